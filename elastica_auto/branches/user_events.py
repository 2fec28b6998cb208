"""User events (``events = ["x1 = 0.5", "m0 = 0"]``): a labelled point, UZ (AUTO-07p's UZR
on any ordinate or parameter), wherever an ordinate, a free parameter or the continued
parameter takes a value; the branch goes on past it.

Test function ``q(x) - value``, ``q`` the quantity named (`elastica_auto.branches.kinds.quantity`);
its sign changes are located by the events' one locator (Brent's method on the hyperplanes
across the step, each trial point solved to the corrector's tolerance), so that at the point
``q`` equals ``value`` to the corrector's accuracy. The note says which event it is and
whether ``q`` rose or fell through the value.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..core import labels
from ..core.errors import PlanError
from ..core.expressions import evaluate
from .kinds import CONTINUE, Event, quantity

#: The form of an entry, for the messages that refuse one.
FORM = '"NAME = VALUE" (NAME an ordinate, a free parameter or the continued parameter)'


@dataclass(frozen=True)
class UserEvent(Event):
    """UZ where ``name`` equals ``value`` (``text``: the entry as written)."""

    name: str
    value: float
    text: str

    label = labels.UZ
    action = CONTINUE

    def test(self, walk, sol) -> float:
        return quantity(walk.problem, self.name, sol.state) - self.value

    def note(self, walk, sol, rising: bool) -> str:
        return f"{self.name} = {self.value:.6g} ({'rising' if rising else 'falling'})"

    def describe(self) -> str:
        return f"event {self.text!r}"

    @classmethod
    def parse(cls, problem, parameter: str, text: str) -> UserEvent | None:
        """The event an entry ``"NAME = VALUE"`` asks for; None for an entry of another
        form; PlanError (key ``events``) for a NAME the branch has no value of, or a VALUE
        that does not evaluate (`elastica_auto.core.expressions`)."""
        m = re.fullmatch(r"\s*([^=<>!]+?)\s*=\s*([^=<>!]+?)\s*", text)
        if m is None:
            return None
        name, value = m.groups()
        names = [*problem.ordinate_names, *getattr(problem, "free", ()), parameter]
        if name not in names:
            raise PlanError("events", f"{text!r}: {name!r} is not an ordinate, a free parameter "
                            f"or the continued parameter ({', '.join(names)})")
        try:
            return cls(name, evaluate(value), text)
        except ValueError as exc:
            raise PlanError("events", f"{text!r}: VALUE {exc}") from None


EVENT = UserEvent
