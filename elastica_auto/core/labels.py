"""The kinds of labelled point, one table: the label each kind writes in a branch's ``type``
column, what it means, and what the engine, the analyses and the plots do with it.

The labels are plain strings (a branch file stores them as such, and files written before
this table read the same); the names below are what the engine compares with, so that a
misspelt kind is a NameError rather than a comparison that is never true. What a kind is
for the code that reads branches (whether the index may change there, whether other
branches start there, whether it is a fold, whether it is a failure) is a property of its
:class:`Kind`, read through the sets below, never a list of label strings written where it
is used: a new kind is a row of :data:`KINDS` and its event's module.
"""

from __future__ import annotations

from dataclasses import dataclass

EP = "EP"
LP = "LP"
BP = "BP"
UZ = "UZ"
MX = "MX"
CP = "CP"
XT = "XT"


@dataclass(frozen=True)
class Kind:
    """One kind of labelled point.

    ``turn``: the branch's linearisation is singular there, so the stability index may
    change at it (a fold, a branch point): the fold rule and the direct count start again
    after it, a diagram's line changes its style there, a stable stretch ending there is
    scanned for snap-back targets, and a start from it without moving is a singular one (its
    tangent is not unique). ``singular``: moving a start from it to other parameter values
    goes round a singular point (a turn, and a fold curve's cusp). ``switch``: other
    branches may start there (``switch``, ``Switch(label)``, branch-point curves).
    ``fold``: the continued parameter turns back there (``stop = ["LPn"]``, a branch's
    folds, fold curves). ``failed``: the branch ended there without reaching its end."""

    label: str
    meaning: str
    turn: bool = False
    singular: bool = False
    switch: bool = False
    fold: bool = False
    failed: bool = False


#: Label -> its kind.
KINDS = {k.label: k for k in (
    Kind(EP, "end point: a bound, a stop, max_points, the start again"),
    Kind(LP, "fold (limit point): the continued parameter turns back",
         turn=True, singular=True, fold=True),
    Kind(BP, "branch point: another branch crosses (the bordered Jacobian is singular)",
         turn=True, singular=True, switch=True),
    Kind(UZ, "user point: the continued parameter, an ordinate or a free parameter takes a "
             "value asked for (uz, events)"),
    Kind(MX, "failed or interrupted: the branch ends at its last accepted point", failed=True),
    Kind(CP, "cusp on a fold curve", singular=True),
    Kind(XT, "extremum of an ordinate along the branch (events = [\"extremum NAME\"])"),
)}

#: Label -> what a point of that kind is.
MEANING = {label: k.meaning for label, k in KINDS.items()}

#: The labels of the kinds with each property (`Kind`), for tests on a ``type`` column.
TURNS = frozenset(label for label, k in KINDS.items() if k.turn)
SINGULAR = frozenset(label for label, k in KINDS.items() if k.singular)
SWITCHES = frozenset(label for label, k in KINDS.items() if k.switch)
FOLDS = frozenset(label for label, k in KINDS.items() if k.fold)
FAILED = frozenset(label for label, k in KINDS.items() if k.failed)


def kind_of(name: str) -> str:
    """The label of a labelled point's name (``"BP3"`` -> ``"BP"``): its letters before the
    number."""
    return name.rstrip("0123456789")


def label_order(label: str) -> tuple:
    """A label's place among labels: by type, then number (``UZ2`` before ``UZ10``)."""
    number = label[2:]
    return (label[:2], int(number) if number.isdigit() else -1, label)


def compact(labels) -> str:
    """Labels compactly, in the order given, runs of consecutive numbers of one type as
    ranges: ``UZ1-UZ3, LP2`` (a message naming the labels of a run of hundreds stays a
    line)."""
    runs: list[list] = []       # [first, last, type, number of the last]
    for label in labels:
        kind, number = label[:2], int(label[2:]) if label[2:].isdigit() else None
        if runs and number is not None and runs[-1][2:] == [kind, number - 1]:
            runs[-1][1], runs[-1][3] = label, number
        else:
            runs.append([label, label, kind, number])
    return ", ".join(first if first == last else f"{first}-{last}" for first, last, *_ in runs)
