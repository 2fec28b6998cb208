"""Stability maps of a fold-curve run, drawn from its branch file (nothing is recomputed).

One panel per plane (`elastica_auto.analysis.maps`, stored in ``/maps`` by the run): each region
between fold curves shaded and numbered by how many stable equilibria it holds, the fold
curves over it (folded into one period of a periodic first parameter), cusps (CP) marked.
"""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure

from ..analysis.maps import plane_groups
from ..core.labels import CP
from ..core.values import same_value
from ..storage.store import BranchFile
from .diagram import values_tex
from .style import RC, marker_style

#: A region gets its number written in it from this many cells on (smaller ones are only
#: shaded; the colour bar reads them).
LABEL_CELLS = 300


def _wrapped(x, y, x0, period):
    """(x, y) with x folded into [x0, x0 + period), split where the fold jumps."""
    if not period:
        return [(x, y)]
    xm = (x - x0) % period + x0
    jumps = np.flatnonzero(np.abs(np.diff(xm)) > period / 2) + 1
    return [(a, b) for a, b in zip(np.split(xm, jumps), np.split(y, jumps)) if len(a) > 1]


def draw_map(ax, bf: BranchFile, m, cmap, norm):
    """Panel of the map ``m`` of ``bf``: shaded regions, fold curves, cusps, region numbers."""
    shade = np.ma.masked_less(m.stable_cells(), 0)
    ax.imshow(shade, origin="lower", extent=m.extent, aspect="auto", cmap=cmap, norm=norm,
              interpolation="nearest", zorder=1)
    period = bf.periods.get(m.x)
    x0 = m.extent[0]
    members = next(b for fixed, b in plane_groups(bf.branches, bf.parameters, m.x, m.y)
                   if all(same_value(fixed[k], m.fixed[k]) for k in m.fixed))
    for b in members:
        x, y = b.columns[m.x].astype(float), b.columns[m.y].astype(float)
        for xs, ys in _wrapped(x, y, x0, period):
            ax.plot(xs, ys, color="black", lw=0.8, zorder=3)
        cp = b.columns["type"] == CP
        if np.any(cp):
            xc = (x[cp] - x0) % period + x0 if period else x[cp]
            ax.plot(xc, y[cp], zorder=5, **marker_style(CP))
    sizes = np.bincount(m.cells[m.cells >= 0].ravel(), minlength=len(m.stable))
    for k, (px, py, n) in enumerate(zip(m.region_x, m.region_y, m.stable)):
        if sizes[k] >= LABEL_CELLS:
            ax.text(px, py, str(n), ha="center", va="center", fontsize=8, zorder=6,
                    color="white" if n >= (norm.vmax - 1) / 2 else "black")
    ax.set_xlim(m.extent[0], m.extent[1])
    ax.set_ylim(m.extent[2], m.extent[3])
    ax.set_xlabel(bf.tex.get(m.x, m.x))
    ax.set_ylabel(bf.tex.get(m.y, m.y))
    ax.set_title(values_tex(bf, {k: v for k, v in m.fixed.items() if v != 0}) or "",
                 fontsize=9.5)


def map_figure(bf: BranchFile, title: str | None = None) -> Figure:
    """Every stability map of ``bf`` side by side, with one colour bar: the number of stable
    equilibria. ValueError if the file has none (not a fold-curve run, or its module has no
    ``shooting`` hook)."""
    maps = bf.maps
    if not maps:
        raise ValueError(f"{bf.path}: no stability map (a fold-curve run of a module with "
                         "the shooting and second_variation hooks stores them)")
    top = max(int(m.stable.max()) if len(m.stable) else 0 for m in maps)
    colors = matplotlib.colormaps["YlGnBu"](np.linspace(0.08, 0.92, top + 1))
    cmap = ListedColormap(colors)
    norm = BoundaryNorm(np.arange(-0.5, top + 1.5), cmap.N)
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(5.2 * len(maps) + 0.8, 4.6), layout="constrained")
        axes = np.atleast_1d(fig.subplots(1, len(maps)))
        for ax, m in zip(axes, maps):
            draw_map(ax, bf, m, cmap, norm)
        bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=list(axes),
                           ticks=range(top + 1), shrink=0.9, pad=0.01)
        bar.set_label("stable equilibria")
        fig.legend(handles=[matplotlib.lines.Line2D([], [], color="black", lw=0.8,
                                                    label="fold curve"),
                            matplotlib.lines.Line2D([], [], label="cusp (CP)",
                                                    **marker_style(CP))],
                   loc="outside lower center", ncols=2)
        if title:
            fig.suptitle(title, fontsize=10)
    return fig
