"""The one look of every diagram: stability-index line styles, point markers, colours, fonts.

`elastica-auto plot` (`diagram`), the panels of `layout` and the paper's figures all draw the
index and the labelled points from these tables.
"""

from __future__ import annotations

from ..core.labels import BP, CP, LP, MX

#: The mark of a turning point of the parameter where no fold could be located (an LP row
#: whose ``fold_residual`` is NaN): drawn apart from a located fold.
UNLOCATED = LP + "?"

#: Stability index -> (colour, dash pattern, line width). Index 0 (stable) solid black.
INDEX_STYLE = {
    0: ("black", "-", 1.7),
    1: ("#c23b22", (0, (5.0, 2.5)), 1.25),
    2: ("#2c6fbb", (0, (1.0, 1.7)), 1.5),
    3: ("#2e8b57", (0, (6.0, 2.0, 1.0, 2.0)), 1.25),
}
#: Index 4 and above: dash-dot-dot in the colour of ``HIGH_INDEX_COLORS[k % 4]``.
HIGH_INDEX_DASH = (0, (6.0, 1.5, 1.0, 1.5, 1.0, 1.5))
HIGH_INDEX_COLORS = ("#8c564b", "#b8860b", "#6a3d9a", "#e377c2")
#: Points whose index is unknown: not computed (no second variation), or the fold rule and the
#: direct count disagree there.
UNKNOWN_STYLE = ("0.62", (0, (3.0, 1.5, 1.0, 1.5)), 1.0)

SNAP_COLOR = "#d7191c"     # snap-back arrows
LANDED_FACE = "#fbe3e3"    # behind the configuration a snap lands on
FOLD_COLOR = "#7b3294"     # fold markers and their index change
BP_COLOR = "#008837"       # branch points
CP_COLOR = "#e66101"       # cusps of fold curves
MX_COLOR = "black"         # failed ends
LABEL_COLOR = "#1f4e79"    # numbered configurations

#: Labelled point type -> (marker, face colour, edge colour, size, edge width) in every
#: diagram, and ``UNLOCATED``'s.
MARKERS = {
    LP: ("o", "white", FOLD_COLOR, 3.4, 0.9),
    UNLOCATED: ("x", "0.4", "0.4", 4.0, 1.0),
    BP: ("s", "white", BP_COLOR, 3.6, 1.0),
    CP: ("D", CP_COLOR, CP_COLOR, 4.2, 0.8),
    MX: ("X", MX_COLOR, MX_COLOR, 5.0, 0.5),
}

RC = {
    # a branch file's TeX labels (its "tex" attribute) are typeset by matplotlib's own parser,
    # never handed to a TeX installation, whatever a user's matplotlibrc says (docs/trust.md)
    "text.usetex": False,
    "font.family": "DejaVu Serif",
    "mathtext.fontset": "dejavuserif",
    "font.size": 9.0,
    "axes.titlesize": 9.5,
    "axes.labelsize": 10.0,
    "axes.linewidth": 0.8,
    "xtick.labelsize": 8.5,
    "ytick.labelsize": 8.5,
    "xtick.direction": "in",
    "ytick.direction": "in",
    "xtick.top": True,
    "ytick.right": True,
    "legend.fontsize": 8.0,
    "legend.frameon": True,
    "legend.framealpha": 0.92,
    "legend.edgecolor": "0.7",
    "savefig.dpi": 200,
    "pdf.fonttype": 42,
}


def index_style(k: int):
    """(colour, dashes, width) of a branch segment of stability index ``k`` (-1: unknown)."""
    if k < 0:
        return UNKNOWN_STYLE
    if k in INDEX_STYLE:
        return INDEX_STYLE[k]
    return HIGH_INDEX_COLORS[k % 4], HIGH_INDEX_DASH, 1.25


def index_label(k: int) -> str:
    """Legend text of stability index ``k`` (-1: unknown)."""
    if k < 0:
        return "index unknown"
    return "index 0 (stable)" if k == 0 else f"index {k}"


def marker_style(kind: str) -> dict:
    """Keywords of ``Axes.plot`` that mark a point of type ``kind`` (a key of `MARKERS`)."""
    marker, face, edge, size, width = MARKERS[kind]
    return dict(marker=marker, mfc=face, mec=edge, ms=size, mew=width, ls="none")
