"""Extrema of an ordinate along a branch (``events = ["extremum m1"]``): a labelled point, XT,
where the ordinate (or a free parameter) is largest or smallest along the branch locally, the
largest tip load or deflection a design reaches; the branch goes on past it. (MX, AUTO-07p's
label for a failure, is taken: XT, for eXTremum.)

Test function: the derivative of the quantity ``q`` along the branch, ``dq/ds = q'(x) t``,
``t`` the unit tangent at the solution ``x`` oriented along the direction of travel, by a
central difference along the tangent,

    dq/ds ~ (q(x + h t) - q(x - h t)) / (2 h),   h = EXTREMUM_STEP (1 + |lam|),

(its truncation error ``h^2 q''' / 6`` and rounding ``eps |q| / h`` both near 1e-11 of the
quantity's scale). A maximum is where it passes zero downwards (the note says
``maximum``), a minimum upwards. Located as every event is, by Brent's method on the
hyperplanes across the step. A point of the branch where ``q`` is stationary without an
extremum (an inflection with a horizontal tangent) has no sign change and makes no point.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..core import labels
from ..core.errors import PlanError
from ..core.solution import State, difference, norm
from .kinds import CONTINUE, Event, Placement, quantity

#: The form of an entry, for the messages that refuse one.
FORM = '"extremum NAME" (NAME an ordinate or a free parameter)'
#: The central difference's step along the unit tangent, relative to 1 + |lam|.
EXTREMUM_STEP = 1e-5


@dataclass(frozen=True)
class Extremum(Event):
    """XT where ``name`` has a local maximum or minimum along the branch."""

    name: str
    text: str

    label = labels.XT
    action = CONTINUE

    def test(self, walk, sol) -> float:
        x, t = sol.state, sol.tangent.on(sol.state.s)
        h = EXTREMUM_STEP * (1.0 + abs(sol.lam))
        ends = []
        for side in (h, -h):
            moved = State(x.s, x.y + side * t.y, x.yp + side * t.yp,
                          {**x.params, walk.name: x.params[walk.name] + side * t.lam})
            ends.append(quantity(walk.problem, self.name, moved))
        return (ends[0] - ends[1]) / (2.0 * h)

    def note(self, walk, sol, rising: bool) -> str:
        return f"{'minimum' if rising else 'maximum'} of {self.name}"

    def describe(self) -> str:
        return f"event {self.text!r}"

    def place(self, walk, placement: Placement) -> None:
        """The extrema :meth:`find` finds in the step, each a point of its own except where
        it is the same solution as one of the step's turns (a fold, a branch point): that
        turn's note says so instead (the module's docstring)."""
        for hit in self.find(walk, placement.step):
            turn = next((e for e in placement.turns if e.kind in labels.TURNS
                         and norm(difference(hit.state, e.state, walk.name, e.state.s))
                         <= walk.corr.options.fold_tol), None)
            if turn is None:
                placement.points.append(hit)
            else:
                turn.note = "; ".join(filter(None, (turn.note, f"also the {hit.note}")))

    @classmethod
    def parse(cls, problem, parameter: str, text: str) -> Extremum | None:
        """The event an entry ``"extremum NAME"`` asks for; None for an entry of another
        form; PlanError (key ``events``) for a NAME that is not an ordinate or a free
        parameter."""
        m = re.fullmatch(r"\s*extremum\s+(\S+)\s*", text)
        if m is None:
            return None
        name = m.group(1)
        names = [*problem.ordinate_names, *getattr(problem, "free", ())]
        if name not in names:
            raise PlanError("events", f"{text!r}: {name!r} is not an ordinate or a free "
                            f"parameter ({', '.join(names)})")
        return cls(name, text)


EVENT = Extremum
