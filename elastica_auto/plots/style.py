"""Shared look of the paper figures: index line styles, colours, fonts."""

from __future__ import annotations

#: Stability index -> (colour, dash pattern, line width). Index 0 (stable) solid black.
INDEX_STYLE = {
    0: ("black", "-", 1.7),
    1: ("#c23b22", (0, (5.0, 2.5)), 1.25),
    2: ("#2c6fbb", (0, (1.0, 1.7)), 1.5),
    3: ("#2e8b57", (0, (6.0, 2.0, 1.0, 2.0)), 1.25),
}
#: Points whose index is unknown or where the fold rule and the direct count disagree.
UNKNOWN_STYLE = ("0.62", (0, (3.0, 1.5, 1.0, 1.5)), 1.0)

SNAP_COLOR = "#d7191c"     # snap-back arrows
TRACE_COLOR = "#1a9641"    # tip traces before a snap
LOAD_COLOR = "#e66101"     # load arrows
ARM_COLOR = "#555555"      # lever arms
FOLD_COLOR = "#7b3294"     # fold markers and their index change
BP_COLOR = "#008837"       # branch points
LABEL_COLOR = "#1f4e79"    # numbered equilibria

RC = {
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
    return INDEX_STYLE.get(k, UNKNOWN_STYLE) if k >= 0 else UNKNOWN_STYLE


def index_label(k: int) -> str:
    if k < 0:
        return "index undetermined"
    return "index 0 (stable)" if k == 0 else f"index {k}"
