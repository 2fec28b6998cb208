"""Bifurcation diagrams: an ordinate against a parameter, every branch of a file.

Line style and colour follow the stability index (0 solid black; 1, 2, ... dashed and dotted
in colour); points whose index is not known yet are drawn solid grey. Folds and the other
labelled points are marked and named (``LP3``).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..store import BranchFile  # noqa: E402

INDEX_STYLE = {0: ("black", "-"), 1: ("tab:red", "--"), 2: ("tab:blue", ":"),
               3: ("tab:green", "-.")}
UNKNOWN_STYLE = ("0.35", "-")
MARKERS = {"LP": ("o", "tab:red"), "BP": ("s", "tab:purple"), "UZ": ("^", "tab:green"),
           "EP": ("D", "0.3"), "MX": ("X", "black")}


def index_runs(x, y, index, period):
    """Split a branch into runs of equal index (joined at the change) and, when x is folded
    into [0, period), break it where x wraps around."""
    if period is not None:
        x = np.mod(x, period)
    wrap = np.abs(np.diff(x)) > period / 2 if period else np.zeros(len(x) - 1, bool)
    change = np.diff(index) != 0
    start = 0
    for i in range(len(x) - 1):
        if wrap[i] or change[i]:
            stop = i + 1 if wrap[i] else i + 2
            yield x[start:stop], y[start:stop], int(index[start])
            start = i + 1
    yield x[start:], y[start:], int(index[start])


def bifurcation_diagram(bf: BranchFile, output: Path, xname: str | None = None,
                        yname: str | None = None, period: float | None = None,
                        label_types=("LP", "BP", "MX")) -> Path:
    """Draw ``yname`` against ``xname`` for every branch of ``bf`` and save to ``output``.

    Defaults: x is the first branch's continued parameter, y its distinguished ordinate.
    ``period`` folds x into [0, period).
    """
    if not bf.branches:
        raise ValueError(f"{bf.path}: the file has no branches")
    b0 = bf.branches[0]
    xname = xname or b0.parameter
    yname = yname or b0.attrs.get("ordinate") or bf.ordinates[0]
    for name in (xname, yname):
        if name not in b0.columns:
            raise ValueError(f"{name!r} is not a column of {bf.path}; columns: "
                             f"{', '.join(bf.parameters + bf.ordinates)}")
    fig, ax = plt.subplots(figsize=(7.0, 4.2), constrained_layout=True)
    seen = set()
    for b in bf.branches:
        x, y, index = b.columns[xname], b.columns[yname], b.columns["index"]
        for xs, ys, k in index_runs(x, y, index, period):
            color, ls = (INDEX_STYLE.get(k, (f"C{k % 10}", (0, (1, 1, 3, 1))))
                         if k >= 0 else UNKNOWN_STYLE)
            label = None
            key = k if k >= 0 else "unknown"
            if key not in seen:
                seen.add(key)
                label = f"index {k}" if k >= 0 else "index not computed"
            ax.plot(xs, ys, color=color, ls=ls, lw=1.3, label=label)
        names = b.label_names()
        for i, t in enumerate(b.columns["type"]):
            if t in label_types:
                marker, color = MARKERS[t]
                xi = np.mod(x[i], period) if period else x[i]
                ax.plot(xi, y[i], marker=marker, color=color, ms=4, ls="none")
                ax.annotate(names[i], (xi, y[i]), textcoords="offset points", xytext=(3, 3),
                            fontsize=7, color=color)
    ax.set_xlabel(bf.tex.get(xname, xname))
    ax.set_ylabel(bf.tex.get(yname, yname))
    if period is not None:
        ax.set_xlim(0, period)
    ax.set_title(f"{bf.run}: {len(bf.branches)} branches", fontsize=10)
    ax.grid(alpha=0.25)
    ax.legend(fontsize=8, loc="best")
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=150)
    plt.close(fig)
    return output
