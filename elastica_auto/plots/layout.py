"""Distinguished bifurcation diagrams with configuration insets, read from branch files.

A :class:`Panel` says what one diagram shows: the branches (ordinate against the continued
parameter, line style by stability index), the numbered equilibria drawn as configurations
along the top, and the snap-back arrows with their before/after configurations at the side.
:func:`draw_panel` lays it out in a matplotlib (sub)figure. The helpers here only select,
interpolate and place what the files hold; nothing is solved.

Configurations are drawn by the ``draw(ax, profile, params)`` hook of the equation module that
the branch file names (its ``equation`` attribute), loaded when a configuration is drawn, if
it is a shipped module (loaded by name from the package); a file that names any other module
(a path to a ``.py`` file) gets diagrams without configurations unless the caller passes the
problem itself: reading a file never executes code the user did not name (docs/trust.md). A
module without the hook gets diagrams without configurations too, and a configuration whose
drawing raises is left blank. Each configuration not drawn is reported as a `NotDrawn`
warning. Nothing here knows the problem.
"""

from __future__ import annotations

import functools
import math
import traceback
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import ConnectionPatch, FancyArrowPatch
from matplotlib.ticker import FuncFormatter, MultipleLocator

from ..core.labels import BP, FOLDS, LP, SWITCHES, TURNS
from ..core.errors import ProblemError
from ..model.interface import ProblemInterface
from ..model.problem import Problem, load_problem, shipped_equations
from ..storage.store import BranchFile, StoredBranch
from .diagram import line_index, same_value, save_figure
from .style import (LABEL_COLOR, SNAP_COLOR, UNLOCATED, index_label, index_style,
                    marker_style)

TWO_PI = 2 * math.pi


# ----------------------------------------------------------------------------------- data
@dataclass
class Configuration:
    """A solution to draw with the ``draw`` hook of ``equation``: a problem, or the name a
    branch file's ``equation`` attribute gives (see `equation_problem`); ``profile`` (states,
    profile grid) at parameter values ``params``; ``extra(ax)`` draws more in its axes (e.g.
    the path some point took to get there)."""

    equation: str | Problem
    profile: np.ndarray
    params: dict
    extra: Callable | None = None


class UntrustedEquation(ProblemError):
    """A branch file names an equation module that is not shipped (a path to a ``.py``
    file): reading the file does not import it."""


class NotDrawn(UserWarning):
    """A configuration that was not drawn, and why: its module is not shipped and was not
    given, or its ``draw`` hook raised (``failed``: the hook's error, on one line)."""

    def __init__(self, message: str, failed: str = ""):
        super().__init__(message)
        self.failed = failed


def equation_problem(equation: str | Problem) -> Problem:
    """The problem that draws configurations of a branch file whose ``equation`` attribute is
    ``equation``: ``equation`` itself if it is a problem (one the caller loaded), else the
    shipped module of that name; UntrustedEquation for any other name. A branch file can
    come from anyone, and the module it names would run as soon as it is imported."""
    if isinstance(equation, ProblemInterface):
        return equation
    return _shipped_problem(equation)


@functools.lru_cache(maxsize=None)
def _shipped_problem(name: str) -> Problem:
    """The shipped equation module ``name``, loaded once (by name, from the package)."""
    if name not in shipped_equations():
        raise UntrustedEquation(f"the file names equation module {name!r}, which is not "
                                "shipped")
    return load_problem(name)


def _trusted(c: Configuration | None) -> Problem | None:
    """``c``'s problem, or None (with a `NotDrawn` warning) if its module is not trusted."""
    if c is None:
        return None
    try:
        return equation_problem(c.equation)
    except UntrustedEquation as exc:
        warnings.warn(NotDrawn(f"configurations not drawn: {exc}"), stacklevel=3)
        return None


def can_draw(c: Configuration | None) -> bool:
    """Whether ``c``'s equation module is trusted and draws configurations (has the
    ``draw`` hook)."""
    problem = _trusted(c)
    return problem is not None and problem.has_draw


def projection(c: Configuration | None) -> str | None:
    """The matplotlib projection of the axes ``c``'s module draws on (its
    ``DRAW_PROJECTION``: None for plain axes, ``"3d"`` for a spatial configuration)."""
    problem = _trusted(c)
    return None if problem is None else problem.draw_projection


def configuration_axes(fig, spec, c: Configuration | None):
    """A subplot of ``fig`` in ``spec`` for drawing ``c``, with its module's projection."""
    return fig.add_subplot(spec, projection=projection(c))


def data_box(ax) -> np.ndarray:
    """The extent of what is drawn on ``ax``, ``[[x0, x1], [y0, y1]]`` (and ``[z0, z1]`` on
    3D axes)."""
    if ax.name == "3d":
        xy, zz = ax.xy_dataLim, ax.zz_dataLim
        return np.array(((xy.x0, xy.x1), (xy.y0, xy.y1), (zz.x0, zz.x1)))
    b = ax.dataLim
    return np.array(((b.x0, b.x1), (b.y0, b.y1)))


def draw_configurations(axes, configurations, margin=0.08):
    """Draw each configuration in its axes, all at one scale: the limits of each axes are
    centred on its drawing and fit the widest and the tallest one (and on 3D axes the
    deepest), plus ``margin`` of the largest extent on every side; equal aspect, no ticks,
    no frame. A configuration that is not drawn (see `_draw_one`) leaves its axes empty but
    for a line saying why."""
    boxes = []
    for ax, c in zip(axes, configurations):
        why = _draw_one(ax, c)
        if why:
            ax.set_axis_off()
            ax.text(0.5, 0.5, f"no configuration:\n{why}", ha="center", va="center",
                    fontsize=6, wrap=True, transform=ax.transAxes)
            boxes.append(np.full((2, 2), np.nan))
            continue
        if c.extra is not None:
            c.extra(ax)
        boxes.append(data_box(ax))
    finite = [b for b in boxes if np.all(np.isfinite(b))]
    if not finite:
        return
    dims = max(len(b) for b in finite)
    size = np.array([max((b[k, 1] - b[k, 0] for b in finite if len(b) > k), default=0.0)
                     for k in range(dims)])
    pad = margin * max(size.max(), 1e-12)
    for ax, b in zip(axes, boxes):
        if np.all(np.isfinite(b)):
            centre = b.mean(axis=1)
            half = size[:len(b)] / 2 + pad
            if len(b) == 3:          # a cube: the same scale along all three axes
                half[:] = half.max()
                ax.set_zlim(centre[2] - half[2], centre[2] + half[2])
            ax.set_xlim(centre[0] - half[0], centre[0] + half[0])
            ax.set_ylim(centre[1] - half[1], centre[1] + half[1])
        if ax.name == "3d":
            ax.set_box_aspect((1, 1, 1), zoom=1.3)
            ax.set_axis_off()
            continue
        ax.set_aspect("equal", adjustable="box")
        ax.set_xticks([])
        ax.set_yticks([])
        for sp in ax.spines.values():
            sp.set_visible(False)


def hook_error(exc: BaseException, problem: Problem) -> str:
    """``exc``, raised by ``problem``'s hook, on one line with where it was raised: the
    module's own line if it raised there, else the last line of the traceback
    (``KeyError: 'x' at draw.py:12 in draw``)."""
    frames = traceback.extract_tb(exc.__traceback__)
    module_file = getattr(problem.module, "__file__", None)
    at = next((f for f in reversed(frames) if f.filename == module_file),
              frames[-1] if frames else None)
    message = " ".join(str(exc).split())
    text = f"{type(exc).__name__}: {message}" if message else type(exc).__name__
    return text + (f" at {Path(at.filename).name}:{at.lineno} in {at.name}" if at else "")


def _draw_one(ax, c: Configuration) -> str:
    """Draw ``c`` on ``ax`` with its module's ``draw`` hook; why it was not drawn ("" if it
    was): its module is not trusted, has no hook, or the hook raised (a `NotDrawn` warning
    says which)."""
    problem = _trusted(c)
    if problem is None:
        return "module not shipped"
    if not problem.has_draw:
        return "no draw hook"
    try:
        problem.draw(ax, c.profile, c.params)
    except (Exception, SystemExit) as exc:    # the module's code: it fails this drawing only
        for artist in [*ax.lines, *ax.patches, *ax.texts, *ax.collections, *ax.images]:
            artist.remove()        # what it drew before it raised
        error = hook_error(exc, problem)
        warnings.warn(NotDrawn(f"draw hook failed: {error}", failed=error), stacklevel=3)
        return "draw hook failed"
    return ""


@dataclass(frozen=True)
class Pt:
    """One stored point: file, branch, row."""

    bf: BranchFile
    br: StoredBranch
    i: int

    def __getitem__(self, name) -> float:
        return float(self.br.columns[name][self.i])

    @property
    def params(self) -> dict:
        return {q: self[q] for q in self.bf.parameters}

    @property
    def index(self) -> int:
        return int(self.br.columns["index"][self.i])

    @property
    def label(self) -> str:
        return self.br.label_names()[self.i]

    def configuration(self, extra: Callable | None = None,
                      problem: Problem | None = None) -> Configuration:
        """The stored solution of this point, to draw (``extra``: see `Configuration`) by
        ``problem`` (default: the module the file names, if it is shipped)."""
        return Configuration(problem or self.bf.equation, self.br.profiles_at(self.i)[0],
                             self.params, extra)


def label_point(bf: BranchFile, name: str) -> Pt:
    """The stored point of label ``name`` (``LP3``)."""
    br, pt = bf.labels[name]
    return Pt(bf, bf.branches[br - 1], pt - 1)


def branches_where(bf: BranchFile, **fixed) -> list[StoredBranch]:
    """Branches of ``bf`` whose first point has the given parameter values (angles modulo
    their period)."""
    out = []
    for b in bf.branches:
        if all(same_value(float(b.columns[q][0]), float(v), bf.periods.get(q))
               for q, v in fixed.items()):
            out.append(b)
    return out


def start_point(bf: BranchFile, b: StoredBranch) -> Pt:
    """The first point of branch ``b``."""
    return Pt(bf, b, 0)


def distinct_starts(bf: BranchFile, branches, key: str, tol=1e-5):
    """The branches' start points, one per distinct equilibrium (the value of the column
    ``key``, which with everything else fixed tells equilibria apart), in branch order; copies
    (the same equilibrium started twice) are dropped."""
    out = []
    for b in branches:
        p = start_point(bf, b)
        if not any(abs(p[key] - q[key]) <= tol * (1 + abs(q[key])) for q in out):
            out.append(p)
    return out


def crossings(bf: BranchFile, branch: StoredBranch, name: str, value: float, period=None):
    """Rows (i, w) where the branch's ``name`` passes ``value`` (mod period) between points i
    and i + 1, at fraction w; stored points exactly at the value give w = 0."""
    lam = branch.columns[name].astype(float)
    if period:
        lam = value + np.remainder(lam - value + period / 2, period) - period / 2
    out = []
    for i in range(len(lam) - 1):
        a, b = lam[i] - value, lam[i + 1] - value
        if a == 0:
            out.append((i, 0.0))
        elif a * b < 0 and abs(lam[i + 1] - lam[i]) < (period or np.inf) / 2:
            out.append((i, a / (a - b)))
    if len(lam) and lam[-1] == value:
        out.append((len(lam) - 1, 0.0))
    return out


def interpolated(bf, br, i, w, name, value):
    """Parameters, ordinate columns and profile between points i and i + 1 (fraction w)."""
    j = min(i + 1, len(br) - 1)
    cols = {k: (1 - w) * float(br.columns[k][i]) + w * float(br.columns[k][j])
            for k in bf.parameters + bf.ordinates}
    cols[name] = value
    here, there = br.profiles_at([i, j])
    prof = (1 - w) * here + w * there
    return cols, prof


def find_equilibrium(sources, name, value, key, target, fixed,
                     tol=0.03) -> Configuration | None:
    """The configuration (interpolated between stored points) at parameter ``name`` =
    ``value`` (mod period) whose ``key`` column is ``target``, among the branches of the files
    ``sources`` in ``name`` with the ``fixed`` parameter values; None if there is none. Used
    for snap-back targets, with a ``key`` that tells equilibria at fixed parameters apart."""
    best = None
    for bf in sources:
        period = bf.periods.get(name)
        fixed_here = {q: v for q, v in fixed.items() if q != name}
        for br in branches_where(bf, **fixed_here):
            if br.parameter != name:
                continue
            for i, w in crossings(bf, br, name, value, period):
                cols, prof = interpolated(bf, br, i, w, name, value)
                err = abs(cols[key] - target)
                if err <= tol * (1 + abs(target)) and (best is None or err < best[0]):
                    best = (err, Configuration(bf.equation, prof,
                                               {q: cols[q] for q in bf.parameters}))
    return None if best is None else best[1]


# --------------------------------------------------------------------------- diagram parts
def _pi_ticks(ax, axis="x", step=None, span=None):
    """Ticks at multiples of pi (or pi/2) labelled as such."""
    if step is None:
        step = math.pi if (span or TWO_PI) > 3 * math.pi else math.pi / 2

    def fmt(v, _):
        k = v / (math.pi / 2)
        n = int(round(k))
        if abs(k - n) > 1e-6:
            return ""
        if n == 0:
            return "0"
        if n % 2 == 0:
            m = n // 2
            return {1: r"$\pi$", -1: r"$-\pi$"}.get(m, rf"${m}\pi$")
        return {1: r"$\pi/2$", -1: r"$-\pi/2$"}.get(n, rf"${n}\pi/2$")

    a = ax.xaxis if axis == "x" else ax.yaxis
    a.set_major_locator(MultipleLocator(step))
    a.set_major_formatter(FuncFormatter(fmt))
    if step >= math.pi:
        a.set_minor_locator(MultipleLocator(math.pi / 2))


def _distance_to_segments(P, A, B, chunk=256):
    """Distance of each point of P (n, d) to the nearest of the segments A[j]-B[j]."""
    if len(A) == 0:
        return np.full(len(P), np.inf)
    AB = B - A
    L2 = np.einsum("ij,ij->i", AB, AB) + 1e-300
    out = np.empty(len(P))
    for k in range(0, len(P), chunk):
        Q = P[k:k + chunk, None, :] - A[None]
        t = np.clip(np.einsum("nmj,mj->nm", Q, AB) / L2, 0.0, 1.0)
        D = Q - t[..., None] * AB[None]
        out[k:k + chunk] = np.sqrt(np.einsum("nmj,nmj->nm", D, D).min(axis=1))
    return out


def _fold(x, F, index, period):
    """Fold x into [0, period]: a step across a multiple of the period is cut there, with
    points inserted at both edges (so lines reach them; the rows of F, shape (k, n), are
    interpolated there); returns x, F, index and, per segment, whether it is the jump from
    one edge to the other."""
    k = np.floor(x / period)
    xs, fs, ks, wraps = [x[0] - k[0] * period], [F[:, 0]], [index[0]], []
    for i in range(len(x) - 1):
        if k[i + 1] != k[i] and abs(k[i + 1] - k[i]) == 1:
            up = k[i + 1] > k[i]
            edge = period * max(k[i], k[i + 1])
            w = (edge - x[i]) / (x[i + 1] - x[i])
            fb = F[:, i] + w * (F[:, i + 1] - F[:, i])
            xs += [period if up else 0.0, 0.0 if up else period]
            fs += [fb, fb]
            ks += [index[i], index[i]]
            wraps += [False, True]
            wraps.append(False)
        else:
            wraps.append(bool(k[i + 1] != k[i]))
        xs.append(x[i + 1] - k[i + 1] * period)
        fs.append(F[:, i + 1])
        ks.append(index[i + 1])
    return np.array(xs), np.array(fs).T, np.array(ks), np.array(wraps, bool)


def _smooth(x, y, sx, sy, per_segment=8):
    """Points on the PCHIP curve through (x, y), parameterised by the scaled chord length."""
    # imported here: scipy.interpolate takes half a second to import, and only the paper's
    # figures smooth their curves
    from scipy.interpolate import PchipInterpolator
    if len(x) < 3:
        return x, y
    t = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(x) / sx, np.diff(y) / sy))))
    keep = np.concatenate(([True], np.diff(t) > 0))
    t, x, y = t[keep], x[keep], y[keep]
    if len(t) < 3:
        return x, y
    u = np.concatenate([np.linspace(t[k], t[k + 1], per_segment, endpoint=False)
                        for k in range(len(t) - 1)] + [t[-1:]])
    xs, ys = PchipInterpolator(t, x)(u), PchipInterpolator(t, y)(u)
    # the points themselves, not the interpolant's rounding of them (a fold ends one line
    # and starts the next at the same point: tests/test_plots.py)
    xs[::per_segment], ys[::per_segment] = x, y
    return xs, ys


#: How close (relative to the diagram's extent in each coordinate) a stretch of a branch
#: must follow one drawn before to count as retracing it (`draw_branches`).
RETRACE_TOL = 5e-3


def draw_branches(ax, items, xname, yname, period=None, xlim=None) -> set:
    """Every branch of ``items`` [(file, branch)], styled by index; returns the indices drawn.

    With ``period``, x is folded into [0, period) and lines break where it wraps. A stretch
    of a branch that retraces one drawn before (the same equilibria reached from another
    start, or a periodic copy in a folded diagram) is not drawn again: two dashed copies out
    of phase would look like a solid line. The line through the points is a monotone (PCHIP)
    cubic in each coordinate against the chord length, not a polygon: it passes through
    every point and adds no turning point between two."""
    data = _branch_data(items, xname, yname, period)
    if not data:
        return set()
    allx = np.concatenate([d[0] for d in data])
    allF = np.hstack([d[1] for d in data])
    sx = (xlim[1] - xlim[0]) if xlim else (np.ptp(allx) or 1.0)
    sF = np.ptp(allF, axis=1)
    sF[sF == 0] = 1.0
    sy = sF[0]
    dim = 1 + len(sF)
    drawn_a, drawn_b = [np.zeros((0, dim))], [np.zeros((0, dim))]
    seen = set()
    for x, F, index, wrap in data:
        y = F[0]
        n = len(x)
        if n < 2:
            continue
        P = np.column_stack((x / sx, (F / sF[:, None]).T))
        hidden = _retraced(P, wrap, np.vstack(drawn_a), np.vstack(drawn_b), RETRACE_TOL)
        visible = ~hidden & ~wrap
        i = 0
        while i < n - 1:
            if not visible[i]:
                i += 1
                continue
            k = int(index[i])
            j = i
            while j < n - 1 and visible[j] and index[j] == k:
                j += 1
            color, dash, lw = index_style(k)
            xs, ys = _smooth(x[i:j + 1], y[i:j + 1], sx, sy)
            ax.plot(xs, ys, color=color, ls=dash, lw=lw,
                    zorder=2 + (1 if k == 0 else 0) - (1 if k < 0 else 0),
                    solid_capstyle="round", dash_capstyle="butt")
            seen.add(k if k >= 0 else -1)
            i = j
        drawn_a.append(P[:-1][~wrap])
        drawn_b.append(P[1:][~wrap])
    return seen


def _branch_data(items, xname, yname, period):
    """Per branch of ``items``: (x, ordinates F (``yname`` first), index, wrap), with x
    folded into [0, period) and ``wrap`` marking the segments across a wrap."""
    data = []
    for bf, br in items:
        x = br.columns[xname].astype(float)
        # the ordinate first, then every other ordinate: copies of the same equilibria
        # coincide in all of them, distinct equilibria that look alike in one do not
        names = [yname] + [o for o in bf.ordinates if o != yname]
        F = np.array([br.columns[o].astype(float) for o in names])
        index = line_index(br.columns["index"], br.columns["type"])
        if period:
            x, F, index, wrap = _fold(x, F, index, period)
        else:
            wrap = np.zeros(max(len(x) - 1, 0), bool)
        data.append((x, F, index, wrap))
    return data


def _retraced(P, wrap, others_a, others_b, tol):
    """The segments of the scaled points ``P`` to hide: both ends within ``tol`` of a segment
    [others_a, others_b] drawn before or of this branch's own earlier segments, and the short
    visible pieces between two such stretches."""
    n = len(P)
    dup = np.zeros(n, bool)
    # against the branches drawn before, and against this branch's own earlier
    # points (a branch can pass the same equilibria again, a period later)
    own_a, own_b = P[:-1][~wrap], P[1:][~wrap]
    own_i = np.flatnonzero(~wrap)
    for a in range(0, n, 32):
        b = min(a + 32, n)
        keep = own_i < a - 8
        dup[a:b] = _distance_to_segments(
            P[a:b], np.vstack((others_a, own_a[keep])),
            np.vstack((others_b, own_b[keep]))) < tol
    hidden = dup[:-1] & dup[1:]
    if hidden.any():
        # short visible pieces between hidden stretches are the same curve sampled at
        # other points (chords bend away from it by more than tol): hide them too
        edges = np.flatnonzero(np.diff(np.concatenate(([1], hidden.astype(int), [1]))))
        for a, b in zip(edges[::2], edges[1::2]):      # visible runs [a, b)
            if b - a <= 3 and (a == 0 or hidden[a - 1]) and (b == len(hidden)
                                                             or hidden[b]):
                hidden[a:b] = True
    return hidden


def place_labels(ax, insets, step=13.0, min_gap=11.0, taken=()):
    """Shift the numbered markers' offsets (points) so that no two labels overlap, nor a
    label and the data points ``taken`` (e.g. the snap tags)."""
    scale = 72.0 / ax.figure.dpi
    placed = [ax.transData.transform(xy) * scale for xy in taken]
    for ins in insets:
        if ins.xy is None:
            continue
        base = ax.transData.transform(ins.xy) * scale
        ox, oy = ins.offset
        for k in (0, 1, 2, 3, -1, -2, 4, 5, 6):
            pos = base + (ox + k * step * (1 if ox >= 0 else -1), oy)
            if all(np.hypot(*(pos - q)) >= min_gap for q in placed):
                break
        placed.append(pos)
        ins.offset = (float(pos[0] - base[0]), float(pos[1] - base[1]))


def draw_folds(ax, items, xname, yname, period=None, xlim=None, text=True, fontsize=6.5,
               types=tuple(TURNS)):
    """Mark folds (and branch points) with the index change, read in the direction of
    increasing ordinate (below -> above; at a branch point, along the branch)."""
    placed = []
    for bf, br in items:
        c = br.columns
        x = c[xname].astype(float)
        y = c[yname].astype(float)
        for i in np.flatnonzero(np.isin(c["type"], types)):
            xi = float(np.mod(x[i], period)) if period else float(x[i])
            if xlim is not None and not xlim[0] - 1e-9 <= xi <= xlim[1] + 1e-9:
                continue
            t = c["type"][i]
            tr = str(c["transition"][i]).replace(" ", "")
            a, _, b = tr.partition("->")
            if t in FOLDS and not np.isfinite(c["fold_residual"][i]):
                # the engine saw the parameter turn but could not locate a fold here
                ax.plot(xi, y[i], zorder=6, **marker_style(UNLOCATED))
                continue
            ax.plot(xi, y[i], zorder=6, **marker_style(t))
            if t in FOLDS:
                i0, i1 = max(i - 1, 0), min(i + 1, len(x) - 1)
                if y[i1] < y[i0]:
                    a, b = b, a
                right = x[i] >= max(x[i0], x[i1])
            else:
                right = True
            if not text or not a or not b or a == b:
                continue
            key = ax.transData.transform((xi, float(y[i]))) * 72.0 / ax.figure.dpi
            if any(np.hypot(*(key - q)) < 9.0 for q in placed):
                continue  # a fold at (almost) the same place is labelled already
            placed.append(key)
            ax.annotate(f"{a}\u2192{b}", (xi, y[i]), xytext=(4 if right else -4, 0),
                        textcoords="offset points", ha="left" if right else "right",
                        va="center", fontsize=fontsize, color=marker_style(t)["mec"], zorder=7,
                        bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none"))


def mark_number(ax, x, y, label, offset=(5, 6), fontsize=7.5):
    """A dot at (x, y) with ``label`` in a circle beside it (a configuration drawn above)."""
    ax.plot(x, y, "o", ms=3.2, color=LABEL_COLOR, zorder=8)
    ax.annotate(str(label), (x, y), xytext=offset, textcoords="offset points",
                fontsize=fontsize, color=LABEL_COLOR, weight="bold", ha="center", va="center",
                zorder=9, bbox=dict(boxstyle="circle,pad=0.12", fc="white", ec=LABEL_COLOR,
                                    lw=0.6, alpha=0.95))


def snap_arrow(ax, x, y0, y1, tag=None, lw=1.3, landed=None):
    """The snap-back arrow at parameter ``x`` from ordinate ``y0`` to ``y1``, with ``tag``.
    Where the file says where the rod lands (``landed`` not None), the arrow to that target
    is drawn solid and the others dotted and thin."""
    style = {} if landed is None else (dict(lw=lw * 1.3) if landed
                                       else dict(lw=lw * 0.6, linestyle=":", alpha=0.8))
    ax.add_patch(FancyArrowPatch((x, y0), (x, y1), arrowstyle="-|>", mutation_scale=9,
                                 color=SNAP_COLOR, zorder=7, shrinkA=1.5, shrinkB=1.0,
                                 **{"lw": lw, **style}))
    if tag:
        ax.annotate(tag, (x, y0 + 0.5 * (y1 - y0)), fontsize=7, color=SNAP_COLOR,
                    weight="bold", ha="center", va="center", zorder=10,
                    bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=SNAP_COLOR, lw=0.7))


def legend_handles(indices, folds=True, bps=False, snaps=False, labels=False,
                   unlocated=False, landing=False):
    """Legend entries: the index styles of ``indices`` (-1: unknown), then the markers;
    ``landing``: the snap-back arrows tell where the rod lands from the others."""
    hs = []
    for k in sorted(i for i in indices if i >= 0) + ([-1] if -1 in indices else []):
        color, dash, lw = index_style(k)
        hs.append(Line2D([], [], color=color, ls=dash, lw=lw, label=index_label(k)))
    if folds:
        hs.append(Line2D([], [], label="fold: index below\u2192above", **marker_style(LP)))
    if unlocated:
        hs.append(Line2D([], [], label="turning point not located\n(at a branch point)",
                         **marker_style(UNLOCATED)))
    if bps:
        hs.append(Line2D([], [], label="branch point", **marker_style(BP)))
    if snaps:
        hs.append(Line2D([], [], color=SNAP_COLOR, lw=1.3 * (1.3 if landing else 1),
                         marker=">", ms=4, label="snap-back: lands" if landing else "snap-back"))
    if snaps and landing:
        hs.append(Line2D([], [], color=SNAP_COLOR, lw=0.8, ls=":", marker=">", ms=3,
                         label="snap-back: other stable"))
    if labels:
        hs.append(Line2D([], [], ls="none", marker="o", ms=3.4, color=LABEL_COLOR,
                         label="configuration shown"))
    return hs


# ------------------------------------------------------------------------------------ panel
@dataclass
class Inset:
    """A numbered configuration along the top; ``xy`` is its place in the diagram."""

    label: str
    config: Configuration
    xy: tuple[float, float] | None = None
    offset: tuple[float, float] = (5, 6)


@dataclass
class Snap:
    """A snap-back arrow at parameter ``x`` from ordinate ``y0`` (the fold) to ``y1``; with
    ``before``/``after`` configurations it is also drawn at the side under ``tag``.
    ``landed``: whether the rod's dynamics end at this target (None: not known)."""

    x: float
    y0: float
    y1: float
    tag: str | None = None
    before: Configuration | None = None
    after: Configuration | None = None
    landed: bool | None = None


@dataclass
class Panel:
    """What one diagram shows (see the module docstring)."""

    items: list                      # [(BranchFile, StoredBranch)]
    xname: str
    yname: str
    xlabel: str
    ylabel: str
    title: str = ""
    period: float | None = None      # fold x into [0, period)
    xlim: tuple | None = None
    ylim: tuple | None = None
    xpi: bool = False                # ticks at multiples of pi
    insets: list[Inset] = field(default_factory=list)
    snaps: list[Snap] = field(default_factory=list)
    legend_loc: str = "best"
    fold_text: bool = True
    extra: Callable | None = None    # extra(ax) draws more on the diagram
    legend_cols: int = 1
    zoom: dict | None = None         # {"xlim", "ylim", "bounds" (axes fraction), "text"}


def _inset_row(fig, spec, insets: list[Inset]):
    """The numbered configurations side by side, at one scale."""
    gs = spec.subgridspec(1, max(len(insets), 1), wspace=0.03)
    axes = [configuration_axes(fig, gs[0, j], ins.config) for j, ins in enumerate(insets)]
    draw_configurations(axes, [ins.config for ins in insets])
    for ax, ins in zip(axes, insets):
        ax.set_title(ins.label, fontsize=8, color=LABEL_COLOR, weight="bold", pad=1.0)


def _snap_column(fig, spec, snaps: list[Snap]):
    """Before (top) and after (bottom) configurations of each tagged snap, side by side."""
    shown = [s for s in snaps if s.before is not None]
    gs = spec.subgridspec(2, len(shown), wspace=0.12, hspace=0.3)
    for c, s in enumerate(shown):
        a0 = configuration_axes(fig, gs[0, c], s.before)
        a0.set_title(f"{s.tag}: before", fontsize=7.5, color=SNAP_COLOR, pad=1.0)
        a1 = configuration_axes(fig, gs[1, c], s.after)
        if s.after is not None:
            draw_configurations([a0, a1], [s.before, s.after], margin=0.04)
            a1.set_title(f"{s.tag}: after", fontsize=7.5, color=SNAP_COLOR, pad=1.0)
        else:
            draw_configurations([a0], [s.before], margin=0.04)
            a1.axis("off")
            a1.text(0.5, 0.5, "target not on a\ncomputed branch", ha="center", va="center",
                    fontsize=6.5, transform=a1.transAxes, color=SNAP_COLOR)
        fig.add_artist(ConnectionPatch((0.5, -0.02), (0.5, 1.16), "axes fraction",
                                       "axes fraction", axesA=a0, axesB=a1, arrowstyle="-|>",
                                       color=SNAP_COLOR, lw=1.3, mutation_scale=10))


def draw_panel(fig, panel: Panel, spec=None, inset_height=1.15, main_height=2.9,
               side_width=0.27):
    """Lay ``panel`` out in ``fig`` (a Figure or SubFigure), or in ``spec`` of it: the
    configuration insets along the top, the diagram below; with snap-backs, a column at the
    right holding the legend and the before/after configurations. Configurations whose module
    has no ``draw`` hook are left out (the insets, their numbers, the snap-back column), the
    diagram is drawn all the same."""
    panel = replace(panel, insets=[i for i in panel.insets if can_draw(i.config)],
                    snaps=[s if can_draw(s.before) else replace(s, before=None, after=None)
                           for s in panel.snaps])
    has_side = any(s.before is not None for s in panel.snaps)
    rows = [inset_height, main_height] if panel.insets else [main_height]
    kw = dict(width_ratios=[1 - side_width, side_width], wspace=0.04) if has_side else {}
    outer = (spec.subgridspec if spec is not None else fig.add_gridspec)(
        len(rows), 2 if has_side else 1, height_ratios=rows, hspace=0.06, **kw)
    if panel.insets:
        _inset_row(fig, outer[0, 0], panel.insets)
    ax = fig.add_subplot(outer[-1, 0])
    xlim = panel.xlim or ((0, panel.period) if panel.period else None)
    seen = draw_branches(ax, panel.items, panel.xname, panel.yname, panel.period, xlim=xlim)
    if xlim:
        ax.set_xlim(*xlim)
    if panel.ylim:
        ax.set_ylim(*panel.ylim)
    ax.autoscale_view()
    draw_folds(ax, panel.items, panel.xname, panel.yname, panel.period, xlim,
               text=panel.fold_text)
    for s in panel.snaps:
        snap_arrow(ax, s.x, s.y0, s.y1, s.tag if s.before is not None else None,
                   landed=s.landed)
    place_labels(ax, panel.insets, taken=[(t.x, t.y0 + 0.5 * (t.y1 - t.y0))
                                          for t in panel.snaps if t.tag and t.before])
    for ins in panel.insets:
        if ins.xy is not None:
            mark_number(ax, *ins.xy, ins.label, offset=ins.offset)
    if panel.extra is not None:
        panel.extra(ax)
    if panel.xpi:
        lo, hi = ax.get_xlim()
        _pi_ticks(ax, "x", span=hi - lo)
    ax.set_xlabel(panel.xlabel, labelpad=1)
    ax.set_ylabel(panel.ylabel, labelpad=2)
    has_bp = any(np.any(np.isin(br.columns["type"], list(SWITCHES))) for _, br in panel.items)
    lps = [np.isfinite(br.columns["fold_residual"][np.isin(br.columns["type"], list(FOLDS))])
           for _, br in panel.items]
    has_lp = any(np.any(f) for f in lps)
    has_unlocated = any(np.any(~f) for f in lps)
    handles = legend_handles(seen, folds=has_lp, bps=has_bp, snaps=bool(panel.snaps),
                             labels=bool(panel.insets), unlocated=has_unlocated,
                             landing=any(s.landed is not None for s in panel.snaps))
    if has_side:
        lax = fig.add_subplot(outer[0, 1]) if panel.insets else ax.inset_axes((1.02, 0, .3, 1))
        lax.axis("off")
        lax.legend(handles=handles, loc="center", handlelength=2.6, borderaxespad=0.2)
        _snap_column(fig, outer[-1, 1], panel.snaps)
    else:
        ax.legend(handles=handles, loc=panel.legend_loc, handlelength=2.6, borderaxespad=0.4,
                  ncol=panel.legend_cols, columnspacing=1.0)
    if panel.zoom:
        _zoom(ax, panel)
    if panel.title:
        ax.set_title(panel.title, loc="left", fontsize=9.5, pad=3)
    return ax


def _zoom(ax, panel: Panel):
    z = panel.zoom
    sub = ax.inset_axes(z["bounds"])
    draw_branches(sub, panel.items, panel.xname, panel.yname, panel.period, xlim=z["xlim"])
    draw_folds(sub, panel.items, panel.xname, panel.yname, panel.period, z["xlim"],
               text=z.get("text", True), fontsize=6)
    for s in panel.snaps:
        snap_arrow(sub, s.x, s.y0, s.y1, landed=s.landed)
    sub.set_xlim(*z["xlim"])
    sub.set_ylim(*z["ylim"])
    sub.tick_params(labelsize=6.5)
    ax.indicate_inset_zoom(sub, edgecolor="0.4", lw=0.7)


def save(fig, out_dir, name) -> list:
    """Write ``name``.png and ``name``.pdf into ``out_dir``; return the paths.

    The PDF keeps the PNG's layout: the constrained layout of a figure with dozens of
    configuration insets is about a third of its drawing time, and solving it again for the
    second file would only move the axes by rounding."""
    out_dir = Path(out_dir)
    paths = [out_dir / f"{name}.png", out_dir / f"{name}.pdf"]
    # each through a temporary file (`diagram.save_figure`): a figure cut short by a full
    # disk would otherwise be newer than its runs, and make would keep it
    save_figure(fig, paths[0], dpi=200)
    fig.set_layout_engine("none")
    save_figure(fig, paths[1])
    return paths
