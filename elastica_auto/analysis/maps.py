"""Stability maps: the regions of a parameter plane cut out by fold curves, and how many
stable equilibria each region holds.

Across a fold curve two equilibria appear or vanish; inside a region bounded by fold curves
the set of equilibria, and so the number of stable ones, stays the same. A map therefore
needs one complete enumeration per region, not one per point of the plane:

1. the fold curves of one plane (branches of a fold-curve run at the same values of the other
   parameters) are drawn on a grid of ``nx`` x ``ny`` cells over the plane's window (one
   period of a periodic first parameter, the bounds of the second), thickened by one cell;
2. the free cells fall into connected regions (`scipy.ndimage.label`; joined across the
   period's edges);
3. each region of at least ``MIN_CELLS`` cells gets one enumeration of all equilibria
   (`elastica_auto.analysis.equilibria.enumerate_equilibria`, the module's ``shooting`` and
   ``second_variation`` hooks) at its deepest cell, the one farthest from any curve and from
   the window's edges.

Regions thinner than a cell (the tip of a cusp's wedge) are left out: their cells are -1,
like the curves'. The map is computed by the run, stored in the branch file (``/maps``) and
drawn from there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.values import same_value

#: Cells across the plane (first parameter) and up it (second).
NX, NY = 360, 240
#: The smallest region that gets an enumeration (cells).
MIN_CELLS = 12


@dataclass
class StabilityMap:
    """One plane's map: the window ``extent = (x0, x1, y0, y1)`` of parameters ``x``
    (solved for on the fold curves) and ``y`` (continued), the other parameters ``fixed``,
    ``cells`` (ny, nx) holding each cell's region (-1: on a curve or in a region too small),
    and per region its deepest point and the counts found there."""

    x: str
    y: str
    fixed: dict[str, float]
    extent: tuple[float, float, float, float]
    cells: np.ndarray
    region_x: np.ndarray = field(default_factory=lambda: np.zeros(0))
    region_y: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stable: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    equilibria: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    def stable_cells(self) -> np.ndarray:
        """(ny, nx) number of stable equilibria in each cell's region; -1 where none."""
        out = np.full(self.cells.shape, -1)
        inside = self.cells >= 0
        out[inside] = self.stable[self.cells[inside]]
        return out


def _window(values, period, bounds) -> tuple[float, float]:
    if period:
        return -period / 2, period / 2
    lo, hi = bounds
    if math.isfinite(lo) and math.isfinite(hi):
        return lo, hi
    return float(np.min(values)), float(np.max(values))


def _raster(curves, extent, period, nx, ny) -> np.ndarray:
    """Cells (ny, nx) crossed by the polylines ``curves`` [(x, y), ...], x folded into the
    window if ``period``; segments sampled at a quarter cell."""
    x0, x1, y0, y1 = extent
    hx, hy = (x1 - x0) / nx, (y1 - y0) / ny
    hit = np.zeros((ny, nx), dtype=bool)
    for xs, ys in curves:
        xs, ys = np.asarray(xs, float), np.asarray(ys, float)
        if len(xs) < 2:
            continue
        dx, dy = np.diff(xs) / hx, np.diff(ys) / hy
        steps = np.maximum(1, np.ceil(4 * np.hypot(dx, dy))).astype(int)
        t = np.concatenate([np.arange(k) / k for k in steps])
        seg = np.repeat(np.arange(len(steps)), steps)
        px = np.append(xs[seg] + t * np.diff(xs)[seg], xs[-1])
        py = np.append(ys[seg] + t * np.diff(ys)[seg], ys[-1])
        if period:
            px = (px - x0) % period + x0
        i = np.floor((px - x0) / hx).astype(int)
        j = np.floor((py - y0) / hy).astype(int)
        ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        hit[j[ok], i[ok]] = True
    return hit


def regions(curves, extent, period=None, nx=NX, ny=NY):
    """The regions between ``curves`` in ``extent``: (cells (ny, nx) with region numbers, -1
    on the thickened curves and in regions under ``MIN_CELLS``; per region its deepest cell
    (j, i))."""
    from scipy import ndimage
    wall = ndimage.binary_dilation(_raster(curves, extent, period, nx, ny))
    labels, count = ndimage.label(~wall)
    if period and count:                      # a region crossing the window's edge is one
        parent = np.arange(count + 1)

        def find(a):
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a
        for a, b in zip(labels[:, 0], labels[:, -1]):
            if a and b:
                parent[find(a)] = find(b)
        roots = np.array([find(a) for a in range(count + 1)])
        labels = roots[labels]
    cells = np.full((ny, nx), -1)
    deepest = []
    ids = [k for k in np.unique(labels) if k]
    sizes = ndimage.sum_labels(np.ones_like(labels), labels, ids) if ids else []
    # distance to the nearest curve or edge of the window: the deepest cell is well inside
    depth = ndimage.distance_transform_edt(np.pad(labels > 0, 1))[1:-1, 1:-1]
    for k, size in zip(ids, sizes):
        if size < MIN_CELLS:
            continue
        mask = labels == k
        cells[mask] = len(deepest)
        flat = np.argmax(np.where(mask, depth, -1))
        deepest.append(np.unravel_index(flat, mask.shape))
    return cells, deepest


def plane_groups(branches, names, x: str, y: str) -> list[tuple[dict, list]]:
    """The branches (in memory or stored) grouped by the values of the parameters ``names``
    other than ``x`` and ``y`` (at their first point, the same by `core.values.same_value`,
    as the diagram's panels), in order of first appearance."""
    groups: list[tuple[dict, list]] = []
    for b in branches:
        fixed = {k: float(b.columns[k][0]) for k in names if k not in (x, y)}
        for known, members in groups:
            if all(same_value(known[k], fixed[k]) for k in fixed):
                members.append(b)
                break
        else:
            groups.append((fixed, [b]))
    return groups


def stability_maps(problem, branches, x: str, y: str, bounds, nx=NX, ny=NY,
                   progress=None, mapper=None) -> list[StabilityMap]:
    """The map of each plane of a fold-curve run (``branches`` of ``problem``, the module's
    own problem, with curves in ``x`` solved for and ``y`` continued within ``bounds``).
    The enumerations, one per region of every plane, are independent tasks
    (`region_counts`): ``mapper(function, args_list, on_done)`` computes them (a default
    run's workers, `execution.run._analyse`; default here, one after the other), and
    ``progress(done, total)`` follows them."""
    from .landing import one_by_one
    period = problem.parameters[x].period
    out, tasks = [], []
    for fixed, members in plane_groups(branches, problem.parameter_names, x, y):
        curves = [(b.columns[x], b.columns[y]) for b in members]
        xs = np.concatenate([c[0] for c in curves])
        ys = np.concatenate([c[1] for c in curves])
        extent = (*_window(xs, period, (-math.inf, math.inf)), *_window(ys, None, bounds))
        cells, deepest = regions(curves, extent, period, nx, ny)
        x0, x1, y0, y1 = extent
        m = StabilityMap(x, y, dict(fixed), extent, cells)
        m.region_x = np.array([x0 + (i + 0.5) * (x1 - x0) / nx for _, i in deepest])
        m.region_y = np.array([y0 + (j + 0.5) * (y1 - y0) / ny for j, _ in deepest])
        tasks += [(problem, {**fixed, x: px, y: py}) for px, py in zip(m.region_x, m.region_y)]
        out.append(m)

    finished = []

    def done(i, counts):
        finished.append(i)
        if progress is not None:
            progress(len(finished), len(tasks))

    counts = iter((mapper or one_by_one)(region_counts, tasks, done))
    for m in out:
        stable, total = zip(*[next(counts) for _ in m.region_x]) if len(m.region_x) else ((), ())
        m.stable, m.equilibria = np.array(stable, dtype=int), np.array(total, dtype=int)
    return out


def region_counts(problem, params) -> tuple[int, int]:
    """(stable, all) equilibria at ``params``: one region's enumeration, a task of
    `stability_maps`."""
    from .equilibria import enumerate_equilibria
    eqs = enumerate_equilibria(problem, params)
    return sum(e.index == 0 for e in eqs), len(eqs)
