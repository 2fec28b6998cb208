"""Where the kinds of special point are registered: the shipped ones the stepper drives, and
the kinds a run file's or the API's ``events`` entries ask for.

A new kind is one module of this package defining an
:class:`~elastica_auto.branches.kinds.Event` class (its test function, label, note, action)
with a ``parse(problem, parameter, text)`` class method that returns its event for an entry
it reads (else None), the class as ``EVENT`` and the entry's form as ``FORM``; and one line
in :data:`REQUESTED` naming the module. The stepper drives every requested event through
its ``place`` (by default its ``find``: `elastica_auto.branches.stepper`); docs/design.md
("Events") shows the two requested kinds as the example. A shipped kind placed on every
step is an object here and its place in :data:`PLACEMENT`.
"""

from __future__ import annotations

import importlib

from ..core.errors import PlanError
from .kinds import (Bound, BranchPoint, CourseEvents, EvenBranchPoint, Event, Failure, Fold,
                    FoldStop, SymmetricBranchPoint, UserValue)
from .codim2 import FoldCurvePoint
from .loops import Closure, Period

#: The shipped kinds, one object each, which the stepper drives in two stages: the turn
#: kinds (folds and branch points) through :data:`DETECTION`, then the placed kinds through
#: :data:`PLACEMENT`. (A ``stop`` entry on an ordinate is a
#: :class:`~elastica_auto.branches.kinds.Limit` the plan makes, and an ``events`` entry a
#: requested kind's event: the walk's course holds them, :data:`COURSE_EVENTS` places them.)
FOLD = Fold()
BRANCH_POINT = BranchPoint()
SYMMETRIC_BRANCH_POINT = SymmetricBranchPoint()
EVEN_BRANCH_POINT = EvenBranchPoint()
USER_VALUE = UserValue()
BOUND = Bound()
COURSE_EVENTS = CourseEvents()
CLOSURE = Closure()
PERIOD = Period()
FOLD_STOP = FoldStop()
FOLD_CURVE_POINT = FoldCurvePoint()
#: The failure of the walk (MX), which the stepper hands every failure to: no tangent at the
#: start, a step rejected down to ``ds_min``, an exception or an interruption.
FAILURE = Failure()

#: The turn kinds the stepper drives on every step, in the order in which they are located
#: and reconciled (each reads what those before it left in the step's
#: :class:`~elastica_auto.branches.kinds.Scan`): a branch point placed at a symmetric value;
#: else located where the determinant changed sign; the fold where the parameter turns, which
#: makes one BP of a fold and a branch point within SAME_EVENT of each other (or a turn
#: without an index change once the fold system fails), and else probes a fold pair; last,
#: the fold rule's check of the index at the step's end, with the branch point of even
#: multiplicity where the index changed by an even number and nothing was found.
DETECTION = (SYMMETRIC_BRANCH_POINT, BRANCH_POINT, FOLD, EVEN_BRANCH_POINT)

#: The placed kinds the stepper drives on every step after the turns, each through its
#: ``place`` on the step's :class:`~elastica_auto.branches.kinds.Placement`, in this order:
#: the user values (UZ) on the monotone pieces between the folds the turns found, the bound
#: (EP) on the first piece that passes one; the course's own events (the kinds the run asks
#: for, then its limits on ordinates); the start again (a closed loop); the start translated
#: by whole periods (the branch repeats); the n-th fold (``stop = ["LPn"]``), among the
#: points the end found so far leaves; last, on a fold curve, its folds' cusps (CP) and
#: meetings with the exact family (BP), tested against the fold's neighbouring points once
#: the step's points and end are known. The order is that of their solves and warnings; the
#: earliest end offered wins (the first offered of equals), and the points are added in the
#: order of travel. Before each step every kind's ``ahead`` may end the branch (the closure,
#: where the start lies within the next step; the bound, where the start lies on one and
#: leaves it); before the walk's first, every kind's
#: ``begin`` reads its course (the period: whether the branch may repeat).
PLACEMENT = (USER_VALUE, BOUND, COURSE_EVENTS, CLOSURE, PERIOD, FOLD_STOP, FOLD_CURVE_POINT)

#: The modules of the kinds an ``events`` entry asks for, tried in this order.
REQUESTED = (
    "user_events",
    "extrema",
)


def _kinds():
    """The requested kinds' modules (imported on first use: a run that asks for none loads
    none)."""
    return [importlib.import_module(f"{__package__}.{name}") for name in REQUESTED]


def parse_events(problem, parameter: str, entries) -> tuple[Event, ...]:
    """The events the entries of ``events`` ask for, in order (the same entry twice, once).
    PlanError (key ``events``) for an entry no kind reads, or one a kind refuses."""
    from collections.abc import Iterable
    if isinstance(entries, (str, bytes)) or not isinstance(entries, Iterable):
        raise PlanError("events", f"expected a list of entries such as [\"m0 = 0\"], "
                        f"got {entries!r}")
    kinds, out = _kinds(), []
    for text in entries:
        if not isinstance(text, str):
            raise PlanError("events", f"expected {_forms(kinds)}, got {text!r}")
        for kind in kinds:
            event = kind.EVENT.parse(problem, parameter, text)
            if event is not None:
                break
        else:
            raise PlanError("events", f"{text!r}: expected {_forms(kinds)}")
        if event not in out:
            out.append(event)
    return tuple(out)


def _forms(kinds) -> str:
    return " or ".join(kind.FORM for kind in kinds)
