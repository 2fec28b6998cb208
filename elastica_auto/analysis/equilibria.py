"""The equilibria at given parameters, searched for on a grid, and the folds that end a stable
stretch of a branch.

What the snap-back targets (`snaps`), the snap's landing (`landing`), the stability maps
(`maps`) and the snaps along a path (`elastica_auto.path`) share. The equilibria are found by
a bounded shooting scan (docs/design.md, "Searching for the equilibria"), through the optional
equation-module hook

``shooting(p) -> (k_lo, k_hi, initial, residual)``
    equilibria at parameters ``p`` are the roots ``k`` in ``[k_lo, k_hi]`` of
    ``residual(y(0), y(1))`` with ``y(0) = initial(k)`` and y integrated by the module's ``rhs``
    (both vectorised over columns). For the elastica k = theta'(0), the residual is the
    free-end moment balance and the first integral bounds |k|.

    ``k_lo`` and ``k_hi`` may also be sequences of d >= 2 numbers: the unknown is then
    k in R^d, in the box between them, ``initial(k)`` takes k of shape (d, m) and
    ``residual`` returns (d, m) (for the spatial rod, d = 2: the clamp moment across the
    load; its component along the load is conserved and zero). A fifth item, where not None,
    is a reflection of the box: signs S with the roots in pairs k, S k at ``p`` (the spatial
    rod's z -> -z at planar parameters), and the scan searches half the box.

The scan integrates all grid values of k at once (`elastica_auto.numerics.ode.dop853`, at a
loose tolerance, the values near zero again at the tight one), brackets every sign change,
refines all brackets together (Illinois regula falsi at the loose tolerance, then narrower
brackets checked at the tight one: `_scan_line`), and computes each root's index by the
direct count. It is a search with the grid's resolution, not a proof of completeness: a grid
cell whose residual has one sign at both ends holds an even number of roots, and none of
them is found (two equilibria within one cell of each other, as near a fold of the
equilibria in the parameters, where they merge).

With d >= 2 unknowns (`scan_box`): the residual on a grid of the box, a Newton
solve (difference Jacobian, all candidates at once) from every grid cell whose
neighbourhood holds both signs of every residual component or where |r| has a local minimum,
and the distinct converged roots;
a root that no such cell catches (a residual the grid does not resolve) is missed, so this is
a search, not a proof of completeness.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import labels
from ..core.solution import State
from ..numerics.ode import dop853
from ..numerics.stability import index

#: The grid of the 1D scan: SCAN_POINTS values of k spanning [k_lo, k_hi], cells of
#: (k_hi - k_lo) / 1200 (0.024 for the rotating arm at P = 9 pi^2/4, eps = 0.5). Two roots
#: within one cell, with no grid value between them, are not found (tests/
#: test_equilibria_scan.py); the grid costs one vectorised integration of its columns.
SCAN_POINTS = 1201
#: Grid points of the box scan (d >= 2 unknowns), about: BOX_POINTS ** (1/d) per axis.
BOX_POINTS = 10201
IVP_TOL = 1e-11
#: The grid's integration tolerance, and the thresholds that keep its signs and roots those
#: of IVP_TOL (`_scan_line`).
SCAN_TOL, NEAR, DELTA, EPS = 1e-8, 1e-5, 1e-6, 1e-10
PROFILE_NODES = 201


@dataclass
class Equilibrium:
    """One equilibrium found by the scan: shooting value (a float, or a tuple of d >= 2),
    solution, index, ordinates."""

    k: float | tuple
    state: State
    index: int
    ordinates: dict


def integrate(problem, params, y0, s_eval=None, tol: float = IVP_TOL):
    """Integrate y' = rhs(s, y, p) from the columns of y0 (n, m) together (`dop853`, relative
    and absolute tolerance ``tol`` in every column); y at s = 1 (or at ``s_eval``), shape
    (n, m) (or (n, m, len(s_eval)))."""
    return dop853(lambda s, y: problem.rhs(s, y, params), y0, rtol=tol, atol=tol,
                  s_eval=s_eval)


def refine_brackets(r, a, b, fa, fb, max_iter: int = 60, xtol: float = 1e-13) -> np.ndarray:
    """The root in each bracket [a, b] of ``r`` (vectorised; ``fa fb < 0``), all refined
    together by Illinois regula falsi.

    A bracket is done once it is shorter than ``xtol`` (relative) or ``r`` is exactly 0 at its
    newest end, which is then the root; only the others are evaluated again. (Iterating a done
    bracket would meet ``fa = fb = 0`` after an exact zero, and 0 / 0 would make its root NaN.)
    """
    a, b, fa, fb = (np.array(v, dtype=float) for v in (a, b, fa, fb))
    for _ in range(max_iter):
        # fa and fb have opposite signs in a live bracket (fa is only ever halved or set to
        # a nonzero fb), so fb - fa cannot vanish
        live = np.flatnonzero((np.abs(b - a) >= xtol * (1 + np.abs(a))) & (fb != 0.0))
        if len(live) == 0:
            break
        c = b[live] - fb[live] * (b[live] - a[live]) / (fb[live] - fa[live])
        fc = r(c)
        same = fc * fb[live] > 0
        a[live] = np.where(same, a[live], b[live])
        fa[live] = np.where(same, fa[live] / 2, fb[live])
        b[live], fb[live] = c, fc
    return b


def enumerate_equilibria(problem, params) -> list[Equilibrium]:
    """The equilibria at ``params`` that the scan finds (roots of the shooting residual in the
    module's bounds, to the grid's resolution: SCAN_POINTS), sorted by k (lexicographically
    for d >= 2 unknowns, found by `scan_box`). Requires the module hooks ``shooting`` and
    (for the index) ``second_variation``."""
    lo, hi, initial, residual = problem.shooting(params)

    def r(k, tol=IVP_TOL):
        k = np.asarray(k, dtype=float)
        y0 = initial(k)
        return residual(y0, integrate(problem, params, y0, tol=tol))

    if np.ndim(lo) == 0:
        roots = _scan_line(r, lo, hi)
        keys = [float(k) for k in roots]
    else:
        roots = scan_box(r, np.asarray(lo, dtype=float), np.asarray(hi, dtype=float),
                         coarse=lambda k: r(k, SCAN_TOL),
                         reflection=problem.shooting_reflection(params))
        keys = [tuple(float(v) for v in k) for k in roots.T]
    if len(keys) == 0:
        return []
    s = np.linspace(0.0, 1.0, PROFILE_NODES)
    ys = integrate(problem, params, initial(roots), s)
    out = []
    for j, k in enumerate(keys):
        state = State.from_values(problem, s, ys[:, j, :], params)
        out.append(Equilibrium(k, state, index(problem, state),
                               problem.ordinate_values(s, state.y, params)))
    return out


def _scan_line(r, lo: float, hi: float) -> np.ndarray:
    """The sorted roots in [lo, hi] of ``r(k, tol)`` (vectorised over k; ``tol`` the
    integration's): a grid integrated at ``SCAN_TOL`` whose signs are made those of
    ``IVP_TOL``; each bracket refined at ``SCAN_TOL``, then narrowed at ``IVP_TOL``.

    On the shipped runs' grids the loose integration differs from the tight one by less
    than 2e-8 (1 + max |r|), and its roots by 7e-9 (1 + |k|) (docs/benchmarks.md). Grid values
    below ``NEAR`` (1 + max |r|) are integrated again at ``IVP_TOL``, so that every sign,
    hence every bracket, is the tight integration's. Around the loose root g, the bracket
    g -+ ``DELTA`` (1 + |g|) (cut to its grid cell) and, around that bracket's secant root x,
    x -+ ``EPS`` (1 + |x|) are each kept if their tight values differ in sign; the root is the
    secant root of the last (its width bounds the error, and the secant's is of the order of
    the width squared). A bracket that fails either check (roots closer than its width, as
    at a fold) is refined from the last one kept by Illinois at ``IVP_TOL`` (`refine_brackets`).
    """
    ks = np.linspace(lo, hi, SCAN_POINTS)
    rs = r(ks, SCAN_TOL)
    near = np.flatnonzero(np.abs(rs) < NEAR * (1 + np.max(np.abs(rs))))
    if len(near):
        rs[near] = r(ks[near])
    exact = ks[rs == 0.0]
    idx = np.flatnonzero(rs[:-1] * rs[1:] < 0)
    # a, b bracket each root with values of the tight integration's signs
    a, b, fa, fb = ks[idx], ks[idx + 1], rs[idx], rs[idx + 1]
    x = refine_brackets(lambda k: r(k, SCAN_TOL), a, b, fa, fb, xtol=1e-7)
    ok = np.ones(len(idx), bool)
    for width in (DELTA, EPS):
        sub = np.flatnonzero(ok)
        half = width * (1 + np.abs(x[sub]))
        left, right = np.maximum(a[sub], x[sub] - half), np.minimum(b[sub], x[sub] + half)
        f = r(np.concatenate((left, right))) if len(sub) else np.zeros(0)
        fl, fr = f[:len(sub)], f[len(sub):]
        kept = (fl * fr <= 0) & (fl != fr)
        ok[sub[~kept]] = False
        sub, left, right, fl, fr = sub[kept], left[kept], right[kept], fl[kept], fr[kept]
        a[sub], b[sub], fa[sub], fb[sub] = left, right, fl, fr
        x[sub] = left - fl * (right - left) / (fr - fl)
    x[~ok] = refine_brackets(r, a[~ok], b[~ok], fa[~ok], fb[~ok])
    return np.sort(np.concatenate((exact, x)))


#: A box-scan candidate whose max |r_j| has not fallen below STALL_FACTOR of its smallest
#: value STALL_STEPS Newton steps ago, and is not yet a root's, is given up: it circles a
#: local minimum of |r| that is no root (about a third of the spatial rod's candidates,
#: which otherwise took every one of the 40 steps). A candidate on its way to a root, even
#: by steps cut to a cell, lowers |r| on every few steps.
STALL_STEPS, STALL_FACTOR = 6, 0.9
#: A root of r: max |r_j| below ROOT_SIZE of r's scale on the grid, the last Newton step
#: below ROOT_STEP of the box. With ``coarse`` (the loose integration, whose residual is
#: within about 2e-8 of r's scale of the tight one's: docs/benchmarks.md), Newton runs on it
#: until max |r_j| is below COARSE_ROOT of the scale, and on r from there.
ROOT_SIZE, ROOT_STEP, COARSE_ROOT = 1e-9, 1e-12, 1e-6
#: A candidate whose max |r_j| stayed below the root's size for SETTLE_STEPS steps is a root,
#: however long its steps.
SETTLE_STEPS = 3
#: A candidate not done after STRAGGLE_STEPS steps within MERGE_SPAN of a root found is given
#: up: a degenerate root's candidates circle it for 20-30 steps (1-8 of them, at a branch
#: point's parameters), each step an integration of the few still live.
STRAGGLE_STEPS = 10
#: A double root (the fold's own equilibrium, in a scan at a fold) takes Newton steps that
#: halve: where two successive steps are parallel (cosine above AITKEN_COS) and the second
#: is a fraction q in AITKEN_Q of the first, the step is taken as s / (1 - q), the limit of
#: that geometric sequence (Aitken's extrapolation). Without it such a root took all
#: 40 steps (each integrating 3 columns a candidate).
AITKEN_COS, AITKEN_Q = 0.99, (0.3, 0.7)


def scan_box(r, lo, hi, points: int = BOX_POINTS, max_iter: int = 40,
             coarse=None, reflection=None) -> np.ndarray:
    """The roots (d, n) of ``r: (d, m) -> (d, m)`` in the box ``[lo, hi]`` of R^d, sorted
    lexicographically.

    ``r`` on a grid of about ``points`` points; a candidate at the centre of every block of
    3^d grid points that holds both signs of every component of r, or where max |r_j| is
    smallest among the block's points; Newton from all candidates together (`box_newton`); the
    converged ones (ROOT_SIZE, ROOT_STEP) within half a cell of the box are kept, and roots
    closer than 1e-6 of the box merged. ``coarse``, if given, is ``r`` computed more cheaply
    (a looser integration): the grid is computed with it, and Newton runs on it until
    COARSE_ROOT, the candidates not given up merged, then on ``r``. (Each Newton step
    integrates d + 1 columns a candidate; most are those of candidates still on their way,
    and at the loose tolerance they take about half the time.)

    ``reflection``: signs S (d,) of +-1 such that the roots come in pairs k, S k (the box
    symmetric in each component S flips). Only the half of the grid where S k >= k, from one
    row of cells below each mirror plane (a root on the plane then lies inside its cells'
    blocks), is computed and searched from, and each root found is given with its image."""
    d = len(lo)
    n = max(int(round(points ** (1.0 / d))), 3)
    box = Box(lo, hi, np.maximum(hi - lo, 1e-300), (hi - lo) / (n - 1))
    flip = np.zeros(d, bool) if reflection is None else np.asarray(reflection) < 0
    # each axis from its first grid point (index first[i]) on: one below the mirror plane
    first = np.where(flip, n // 2 - 1, 0)
    axes = [np.linspace(lo[i], hi[i], n)[first[i]:] for i in range(d)]
    shape = np.array([len(a) for a in axes])
    grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(d, -1)
    rs = (coarse or r)(grid).reshape((d, *shape))
    scale = max(float(np.max(np.abs(rs))), 1e-300)

    def shifted(o):
        return tuple(slice(o[i], o[i] + shape[i] - 2) for i in range(d))

    ok = np.ones(shape - 2, bool)
    for comp in rs:
        blocks = [comp[shifted(o)] for o in np.ndindex(*(3,) * d)]
        ok &= (np.min(blocks, axis=0) <= 0) & (np.max(blocks, axis=0) >= 0)
    # and every grid point where |r| is smallest among its 3^d neighbours (a root between
    # grid points where a component's zero set does not separate the block's points)
    size = np.max(np.abs(rs), axis=0)
    inner = size[shifted((1,) * d)]
    least = np.ones_like(inner, bool)
    for o in np.ndindex(*(3,) * d):
        least &= inner <= size[shifted(o)]
    corners = np.array(np.nonzero(ok | least))                # the block's lowest corner
    k = lo[:, None] + (first[:, None] + corners + 1.0) * box.cell[:, None]     # its centre
    if coarse is not None:
        k = _distinct(box_newton(coarse, k, box, COARSE_ROOT * scale, np.inf, max_iter),
                      box.width)
    k = box_newton(r, k, box, ROOT_SIZE * scale, ROOT_STEP, max_iter)
    final = np.max(np.abs(r(k)), axis=0) if k.shape[1] else np.zeros(0)
    if flip.any():     # the image of a root is one, as accurate
        k, final = np.hstack((k, np.where(flip[:, None], -k, k))), np.tile(final, 2)
    inside = np.all((k >= lo[:, None] - box.cell[:, None] / 2)
                    & (k <= hi[:, None] + box.cell[:, None] / 2), axis=0)
    kept = inside & (final < ROOT_SIZE * scale)
    return _distinct(merged_roots(r, k[:, kept], final[kept], box.width, ROOT_SIZE * scale),
                     box.width)


@dataclass
class Box:
    """The box scan's box [lo, hi], its widths and the grid's cell."""

    lo: np.ndarray
    hi: np.ndarray
    width: np.ndarray
    cell: np.ndarray


def box_newton(r, k, box: Box, size_tol: float, step_tol: float, max_iter: int) -> np.ndarray:
    """Newton on ``r`` from every column of ``k`` (d, m) together: the Jacobian by forward
    differences (d + 1 columns of r a candidate), its pseudo-inverse (a singular Jacobian, a
    double root, takes the least step), each step cut to a grid cell. A candidate is done
    once max |r_j| < ``size_tol`` and its step < ``step_tol`` of the box; given up once it
    leaves the box by a cell or stalls (STALL_STEPS). Returns the candidates not given up,
    done or not."""
    d = k.shape[0]
    k = k.copy()
    done = np.zeros(k.shape[1], bool)
    lost = np.zeros(k.shape[1], bool)
    # each candidate's max |r_j| at every step so far (for the stall test)
    history = np.full((max_iter, k.shape[1]), np.inf)
    previous = np.zeros_like(k)         # each candidate's last step (0: none to compare)
    for it in range(max_iter):
        live = np.flatnonzero(~done)
        if len(live) == 0:
            break
        x = k[:, live]
        h = 1e-7 * (1 + np.abs(x))
        shifted = [x + np.where(np.arange(d)[:, None] == j, h, 0.0) for j in range(d)]
        f = r(np.hstack([x] + shifted)).reshape(d, d + 1, len(live))
        jac = ((f[:, 1:] - f[:, :1]) / h[None, :, :]).transpose(2, 0, 1)   # (m, d, d)
        step = -(np.linalg.pinv(jac) @ f[:, 0].T[:, :, None])[:, :, 0].T
        step = np.where(np.isfinite(step), step, 0.0)
        step, previous[:, live] = _aitken(step, previous[:, live])
        big = np.max(np.abs(step) / box.cell[:, None], axis=0)
        step *= np.minimum(1.0, 1.0 / np.maximum(big, 1e-300))
        k[:, live] = x + step
        small = np.max(np.abs(step) / box.width[:, None], axis=0) < step_tol
        size_now = np.max(np.abs(f[:, 0]), axis=0)
        converged = small & (size_now < size_tol)
        outside = np.any((k[:, live] < box.lo[:, None] - box.cell[:, None])
                         | (k[:, live] > box.hi[:, None] + box.cell[:, None]), axis=0)
        history[it, live] = size_now
        stalled = np.zeros(len(live), bool)
        if it >= STALL_STEPS:
            before = np.min(history[: it - STALL_STEPS + 1, live], axis=0)
            stalled = (size_now >= size_tol) \
                & (np.min(history[it - STALL_STEPS + 1: it + 1, live], axis=0)
                   > STALL_FACTOR * before)
        # a root whose place the residual does not fix better (a degenerate one: along a
        # direction where r grows like a cube, at a branch point's own equilibrium, the step
        # does not shrink while |r| stays below size_tol)
        settled = np.zeros(len(live), bool)
        if it >= SETTLE_STEPS - 1:
            settled = np.max(history[it - SETTLE_STEPS + 1: it + 1, live], axis=0) < size_tol
        # a candidate still on its way after STRAGGLE_STEPS next to a root found (`merged_roots`
        # would make them one): the tail of a degenerate root's, whose steps circle it
        straggling = np.zeros(len(live), bool)
        found = k[:, done & ~lost] if it >= STRAGGLE_STEPS - 1 else k[:, :0]
        if found.shape[1]:
            gap = np.abs(k[:, live][:, :, None] - found[:, None, :]) / box.width[:, None, None]
            straggling = ~(converged | settled) & np.any(
                np.all(gap < MERGE_SPAN, axis=0), axis=1)
        done[live[converged | outside | stalled | settled | straggling]] = True
        lost[live[outside | stalled | straggling]] = True
    return k[:, ~lost]


def _aitken(step, previous):
    """``step`` (d, m) with each column that halves (AITKEN_COS, AITKEN_Q) its ``previous``
    one extrapolated to the limit, and the steps to compare the next ones with (0 after an
    extrapolation: the next two steps are compared afresh)."""
    a, b = np.linalg.norm(previous, axis=0), np.linalg.norm(step, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = b / a
        cos = np.sum(step * previous, axis=0) / (a * b)
    geometric = (a > 0) & (b > 0) & (cos > AITKEN_COS) & (q > AITKEN_Q[0]) & (q < AITKEN_Q[1])
    factor = np.where(geometric, 1.0 / (1.0 - np.where(geometric, q, 0.0)), 1.0)
    return step * factor, np.where(geometric, 0.0, step)


#: Roots closer than MERGE_SPAN of the box (in every component) between which |r| stays below
#: the root's size are one root; closer than DISTINCT, one root whatever r.
MERGE_SPAN, DISTINCT = 1e-3, 1e-6


def merged_roots(r, k, size, width, size_tol) -> np.ndarray:
    """The roots ``k`` (d, m), each set of them that are one degenerate root taken as its
    member of least max |r_j| (``size``). Where r grows like a cube across a root (a branch
    point's own equilibrium, r ~ c x^3 along its kernel), every point within about
    (size_tol / c)^(1/3) of it is a root to size_tol, and Newton's candidates settle all
    over that span (13 roots within 1.6e-4 at one of the spatial rod's branch points). Two
    roots closer than MERGE_SPAN of the box are one where |r| at their midpoint is below
    ``size_tol`` too: between two simple roots d apart it is about |r'| d / 2, far above."""
    m = k.shape[1]
    if m < 2:
        return k
    apart = np.max(np.abs(k[:, :, None] - k[:, None, :]) / width[:, None, None], axis=0)
    i, j = np.nonzero(np.triu(apart < MERGE_SPAN, 1))
    # pairs closer than `_distinct`'s 1e-6 are one without asking (a root and its image)
    ask = apart[i, j] >= DISTINCT
    if not ask.any():
        return k
    one = ~ask
    one[ask] = np.max(np.abs(r(0.5 * (k[:, i[ask]] + k[:, j[ask]]))), axis=0) < size_tol
    group = np.arange(m)
    for a, b in zip(i[one], j[one]):      # union of the pairs, each set by its first member
        ga, gb = group[a], group[b]
        group[group == max(ga, gb)] = min(ga, gb)
    best = [members[np.argmin(size[members])]
            for members in (np.flatnonzero(group == g) for g in np.unique(group))]
    return k[:, np.sort(best)]


def _distinct(k, width) -> np.ndarray:
    """The columns of ``k`` sorted lexicographically, each one closer than DISTINCT of the
    box (``width``) to one kept before it left out."""
    roots: list[np.ndarray] = []
    for x in k.T[np.lexsort(k[::-1])]:
        if not any(np.max(np.abs(x - y) / width) < DISTINCT for y in roots):
            roots.append(x)
    return np.array(roots).T if roots else np.zeros((k.shape[0], 0))


def stable_side(before: int, after: int) -> str | None:
    """'before' or 'after': the side of a point with index 0, where the other side's index
    is positive (the point ends a stable segment); None otherwise."""
    return "before" if before == 0 < after else "after" if after == 0 < before else None


def snap_lps(branch):
    """LPs of ``branch`` that bound an index-0 segment: (point, stable side 'before'/'after')."""
    out = []
    for k, p in enumerate(branch.points):
        if p.type not in labels.FOLDS or k == 0 or k + 1 >= len(branch.points):
            continue
        side = stable_side(p.index, branch.points[k + 1].index)
        if side is not None:
            out.append((p, side))
    return out


def beyond_fold(branch, point, side: str) -> int:
    """The direction (+1 or -1) in which ``branch``'s parameter moves past the fold
    ``point`` from its stable side (``side``, as `snap_lps` gives it): where the stable
    equilibrium no longer exists."""
    k = branch.points.index(point)
    other = branch.points[k - 1 if side == "before" else k + 1]
    return int(np.sign(point.params[branch.parameter] - other.params[branch.parameter]))
