"""The kinds of labelled point, one table: the label each kind writes in a branch's ``type``
column and what it means.

The labels are plain strings (a branch file stores them as such, and files written before
this table read the same); the names below are what the engine compares with, so that a
misspelt kind is a NameError rather than a comparison that is never true.
"""

from __future__ import annotations

EP = "EP"
LP = "LP"
BP = "BP"
UZ = "UZ"
MX = "MX"
CP = "CP"
XT = "XT"

#: Label -> what a point of that kind is.
MEANING = {
    EP: "end point: a bound, a stop, max_points, the start again",
    LP: "fold (limit point): the continued parameter turns back",
    BP: "branch point: another branch crosses (the bordered Jacobian is singular)",
    UZ: "user point: the continued parameter, an ordinate or a free parameter takes a value "
        "asked for (uz, events)",
    MX: "failed or interrupted: the branch ends at its last accepted point",
    CP: "cusp on a fold curve",
    XT: "extremum of an ordinate along the branch (events = [\"extremum NAME\"])",
}
