"""Stability index: by direct count and by the fold rule (docs/stability.md, "The direct
count" and "The fold rule").

The index of an equilibrium is the number of negative eigenvalues of the second variation of
its energy. An equation module provides it through the optional hook ``second_variation(s, y,
p)``, a `elastica_auto.model.second_variation.SecondVariation`::

    d2E[h] = int_0^1 ( h'.A h' + 2 h'.C h + h.B h ) ds + h(0).E0 h(0) + h(1).E1 h(1)

for h(s) in R^k with essential conditions at the ends and linear constraints (or the scalar
tuple ``(a, b, c[, constraints])``, the case k = 1, h(0) = 0). :func:`count` counts its
negative eigenvalues directly at a point (:func:`count_form`: P2 finite elements, a block
LDL^T by cyclic reduction; the tests check it against conjugate points, a dense Galerkin count
and analytic spectra). With the constraints C (full row rank r) the index is that of the form
on ker C: the bordered matrix M = [[K, C^T], [C, 0]] has n_-(M) = n_-(K on ker C) + r, and
where K is nonsingular In(M) = In(K) + In(-C K^-1 C^T) (Haynsworth), so ::

    index_constrained = n_-(K) - n_-(C K^-1 C^T).

The fold rule (:func:`fold_rule`) propagates a known index along a branch: at a simple fold of
a parameter xi the critical eigenvalue moves with ``dmu/dtau = -xi'' d(dE/dxi)/dtau``, so the
index changes by ``+sign(xi'' dB/dtau)`` in the direction of travel for a parameter entering
the equation or a natural end term (its distinguished ordinate B = dE/dxi; the paper's
eqn:Distinguished_biff_diagram_free_end), and by ``-sign(xi'' dB/dtau)`` for an essential end
value, whose ordinate is the reaction ``-dE/dxi``. At a branch point crossed by a branch, the
index changes by the dimension of the kernel (:func:`kernel_dimension`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core import labels
from ..core.errors import ProblemError
from ..model.second_variation import as_second_variation
from ..core.solution import at_fractions
from ._blocks import condense as blocks_condense, rates as blocks_rates, reduce as blocks_reduce
from ._blocks import window as blocks_window

#: Elements are small enough for the eigenfunctions near zero eigenvalue, which oscillate with
#: wavenumber w = sqrt(|B| / A) (scalar form; :func:`_wavenumber`), when h w <= MAX_PHASE. P2
#: elements are then accurate enough that on the straight rod (eps = 0.25, the first three
#: critical loads, 20 and 50 intervals) the count is right down to 1e-4 (relative) from each
#: critical load; at h w = 0.4 it is not.
MAX_PHASE = 0.2

#: A pivot eigenvalue within this many rounding errors of the largest diagonal block is zero
#: to working precision: its sign, and so the count, would be a guess.
SINGULAR_ULPS = 64.0
_ULPS = SINGULAR_ULPS * np.finfo(float).eps


@dataclass(frozen=True)
class Count:
    """The direct count at one state: ``index`` (-1 if not counted) and, when it was not,
    ``reason`` (no hook, values not finite, a zero eigenvalue, the Legendre condition);
    ``refused`` where the form has no index there (the Legendre condition fails, or the
    module's form is not finite at a finite state); ``parts``
    the index of each of the form's named parts (`SecondVariation.split`; -1 for every part
    where the form does not decouple along them or that part has a zero eigenvalue)."""

    index: int
    reason: str = ""
    refused: bool = False
    parts: dict = field(default_factory=dict)


class LegendreError(ProblemError):
    """A is not positive definite at some point: the form has no index (one line)."""


class _Singular(Exception):
    """A pivot of the elimination is singular to working precision."""


def nodes_and_midpoints(mesh):
    """The nodes and element midpoints of ``mesh``, in order: 2 len(mesh) - 1 points (where
    :func:`count_form` first evaluates the form)."""
    pts = np.empty(2 * len(mesh) - 1)
    pts[0::2] = mesh
    pts[1::2] = 0.5 * (mesh[:-1] + mesh[1:])
    return pts


def form_on_state(problem, state):
    """``evaluate(pts)`` for :func:`count_form`: the module's form at the state, from its
    interpolant (on the state's own mesh the midpoints come from the Hermite cubic of each
    interval, the nodes from the solution itself)."""
    def evaluate(pts):
        if len(pts) == 2 * len(state.s) - 1 and np.array_equal(pts[0::2], state.s):
            y = np.empty((state.y.shape[0], len(pts)))
            y[:, 0::2] = state.y
            y[:, 1::2] = at_fractions(state.s, state.y, state.yp, (0.5,))[:, 0]
        else:
            y = state(pts)
        return as_second_variation(problem.second_variation(pts, y, state.params),
                                   _source(problem))
    return evaluate


def _source(problem) -> str:
    """The module's name for messages ("" if it has none)."""
    return getattr(problem, "source", "")


def count(problem, state) -> Count:
    """The stability index at ``state`` by direct count (:func:`count_form` on the state's
    own mesh), or -1 with the reason: no ``second_variation`` hook, a state or coefficient that
    is not finite (NaN compares false with everything, so a count would call it stable), or a
    zero eigenvalue."""
    if not problem.has_second_variation:
        return Count(-1, "no second_variation hook")
    if not (np.all(np.isfinite(state.y)) and np.all(np.isfinite(state.yp))
            and all(math.isfinite(v) for v in state.params.values())):
        return Count(-1, "the state is not finite")
    try:
        return count_form(form_on_state(problem, state), state.s, source=_source(problem))
    except LegendreError as exc:   # at this state only: the branch goes on, the point says so
        return Count(-1, str(exc), refused=True)


def index(problem, state) -> int:
    """The number of negative eigenvalues of the second variation at ``state``, or -1 where it
    is not counted (:func:`count`)."""
    return count(problem, state).index


def min_eig(a):
    """The smallest eigenvalue of each symmetric block (p, k, k). (A lower bound would do for
    the Legendre check, but the refinement's wavenumber divides by it: a bound a factor k - 1
    low refines meshes that need it not.)"""
    k = a.shape[-1]
    if k == 1:
        return a[:, 0, 0]
    if a.strides[0] == 0:   # a constant field (a stiffness), broadcast: one block to solve
        return np.broadcast_to(np.linalg.eigvalsh(a[:1])[:, 0], len(a))
    if k <= 3:
        return _small_min_eig(a)
    return np.linalg.eigvalsh(a)[:, 0]


def _small_min_eig(a):
    """:func:`min_eig` of 2 x 2 and 3 x 3 blocks in closed form (numpy's batched eigensolver
    costs several times as much on them). 2 x 2: (a + b)/2 - |((a - b)/2, d)|. 3 x 3
    (trigonometric; Smith 1961): with q = tr A / 3, A = q I + p B, p^2 = |A - q I|_F^2 / 6,
    the eigenvalues are q + 2 p cos(phi + 2 pi j / 3), 3 phi = arccos(det B / 2), the smallest
    at j = 1: accurate to rounding (relative to |A|) except where the two smallest nearly
    coincide (det B / 2 near 1, where the arccos is steep). Those that have a component
    decoupled (its two off-diagonal entries exactly zero, as a stiffness of its own: the
    shear stiffness S of a Cosserat rod next to the bending stiffnesses, whose two smallest
    eigenvalues are close relative to S) are the smaller of that diagonal entry and the 2 x 2
    formula on the rest, accurate to rounding relative to each; the others go to the
    eigensolver. Where one component is decoupled at every point (the Cosserat rod's parts:
    the hook's literal zeros), that is the answer at every point, without the trigonometric
    form."""
    rows = a.transpose(1, 2, 0).reshape(a.shape[-1] ** 2, -1)   # no copy for a hook's layout
    if a.shape[-1] == 2:
        return 0.5 * (rows[0] + rows[3]) - np.hypot(0.5 * (rows[0] - rows[3]), rows[1])
    # a component decoupled at every point (a Cosserat rod's shear stiffness, a literal zero
    # coupling in the hook): the 2 x 2 formula and that diagonal entry everywhere, a dozen
    # numpy calls fewer than the trigonometric form and its fix-up of near-double points
    coupled = dict(zip(_SYM3[3:].tolist(), rows[_SYM3[3:]].any(axis=1).tolist()))
    for diag, zero0, zero1, lo, hi, off in _DECOUPLED3:
        if not (coupled[zero0] or coupled[zero1]):
            a_lo, a_hi = rows[lo], rows[hi]
            two = 0.5 * (a_lo + a_hi) - np.hypot(0.5 * (a_lo - a_hi), rows[off])
            return np.minimum(rows[diag], two)
    q = rows[_DIAG3].sum(axis=0) / 3
    a0, a1, a2 = rows[_DIAG3] - q
    d, e, f = rows[_SYM3[3:]]
    p2 = (a0 * a0 + a1 * a1 + a2 * a2 + 2 * (d * d + e * e + f * f)) / 6
    det = a0 * (a1 * a2 - f * f) - d * (d * a2 - e * f) + e * (d * f - a1 * e)
    # p = 0 (A = q I): det = 0, so phi = pi / 6 and the result q
    half_det = np.clip(0.5 * det / np.maximum(p2 * np.sqrt(p2), _TINY), -1.0, 1.0)
    out = q + 2 * np.sqrt(p2) * np.cos(np.arccos(half_det) / 3 + 2 * np.pi / 3)
    near = half_det > _NEAR_DOUBLE
    if np.count_nonzero(near):     # the two smallest (nearly) coincide
        for diag, zero0, zero1, lo, hi, off in _DECOUPLED3:
            # a component decoupled (both its off-diagonal entries zero): min(its A, 2 x 2)
            one = near & (rows[zero0] == 0) & (rows[zero1] == 0)
            if np.count_nonzero(one):
                a_lo, a_hi = rows[lo, one], rows[hi, one]
                two = 0.5 * (a_lo + a_hi) - np.hypot(0.5 * (a_lo - a_hi), rows[off, one])
                out[one] = np.minimum(rows[diag, one], two)
                near &= ~one
        if np.count_nonzero(near):     # solve those blocks
            out[near] = np.linalg.eigvalsh(a[near])[:, 0]
    return out


#: For each component of a symmetric 3 x 3 block flattened: its diagonal entry, its two
#: off-diagonal entries, and the other two components' 2 x 2 block (diagonal, diagonal,
#: off-diagonal).
_DECOUPLED3 = ((0, 1, 2, 4, 8, 5), (4, 1, 5, 0, 8, 2), (8, 2, 5, 0, 4, 1))
_TINY = np.finfo(float).tiny
#: det B / 2 above this: the two smallest eigenvalues are so close that the arccos, steep at
#: 1, would lose up to half the digits of the smallest; below it at most a factor 1 /
#: sqrt(1 - 0.99^2) = 7 of a rounding error.
_NEAR_DOUBLE = 0.99


def _norm(a):
    """The Frobenius norm of each (..., k, k) block."""
    if a.shape[-1] == 1:
        return np.abs(a[..., 0, 0])
    return np.sqrt(np.einsum("...ij,...ij->...", a, a))


def _wavenumber(a_min, b, c):
    """A bound on the wavenumber of the form's eigenfunctions near eigenvalue zero, at each
    point: with h' + A^-1 C h = v the form is v.A v + h.(B - C^T A^-1 C) h, so the solutions
    turn at the rate |A^-1 C| and oscillate with sqrt(|B - C^T A^-1 C| / A) (:func:`rates`),
    here bounded by norms (for k = 1 and C = 0, sqrt(|b| / a), exact)."""
    if not np.count_nonzero(c):
        return np.sqrt(_norm(b) / a_min)
    c_norm = _norm(c)
    return np.sqrt((_norm(b) + c_norm * c_norm / a_min) / a_min) + c_norm / a_min


def rates(a, a_min, b, c):
    """The wavenumber of :func:`_wavenumber` from the rates computed, sqrt(|B - C^T A^-1 C| /
    min eig A) + |A^-1 C| (Frobenius norms), never above the bound. The two differ where A
    is stiff in some directions and C couples them to soft ones (a shearable rod: A has the
    bending stiffness 1 and the shear stiffness GA, C and B entries of order GA): the bound
    is of order GA (1000 elements for GA = 1000), the rates of order 1 (the terms of order GA
    cancel in A^-1 C and the Schur complement). A batched solve costs 0.6 ms on 200 points,
    70 times the bound: only where the bound asks for more elements. For k = 2 and 3, A^-1
    is the adjugate over the determinant, point by point (numerics/_blocks.c `rates`, the
    cofactors of its pivots: the numpy form was a dozen calls on the 3 x 3 blocks, 0.05 ms
    on 201 points)."""
    k = a.shape[-1]
    if 2 <= k <= 3:
        out = np.empty(len(a))
        blocks_rates(a, a_min, b, c, out)
        return out
    turn = np.linalg.solve(a, c)
    return np.sqrt(_norm(b - np.swapaxes(c, -1, -2) @ turn) / a_min) + _norm(turn)


def _parts(h, w):
    """The number of elements for each interval of lengths ``h``, from the wavenumber ``w``
    on its nodes and midpoints: h max(w) / MAX_PHASE, rounded up."""
    w = np.maximum(np.maximum(w[0:-1:2], w[1::2]), w[2::2])
    return np.ceil(h * w / MAX_PHASE).astype(int)


def count_form(evaluate, mesh, *, shift: float = 0.0, source: str = "") -> Count:
    """The number of negative eigenvalues of the form ``evaluate(pts)`` (a
    `SecondVariation` with its coefficients on the points ``pts``) less ``shift`` times the
    L2 inner product, on its admissible space; ``mesh`` the nodes of the elements.

    Quadratic (P2) finite elements with k components per node on ``mesh``, each interval
    subdivided where the coefficients oscillate faster than it resolves (``MAX_PHASE``); the
    coefficients at each element's nodes and midpoint (Simpson's rule, which makes the mass
    matrix diagonal). The count is the inertia of the stiffness matrix K (Sylvester: the mass
    matrix is positive definite, so K and the generalised eigenproblem have the same number of
    negative eigenvalues), by a block LDL^T whose pivots are k x k blocks (:func:`_inertia`).
    Essential end conditions restrict the end nodes to the free directions; constraints count
    by the bordered inertia n_-(K) - n_-(C K^-1 C^T) (docs/stability.md, "The direct count").
    A pivot with an eigenvalue zero to working precision (a fold, a branch point, an
    unconstrained symmetry) gives index -1 and says so: its sign would be a guess.
    LegendreError (a ProblemError) where A is not positive definite (the Legendre
    condition), its message starting with ``source`` (the module's name) if given;
    :func:`count` turns it into index -1 with that one-line reason.

    A form with ``parts`` that decouples along them (`SecondVariation.split`) is counted part
    by part, its index their sum (-1 if a part's is), the count of each in ``parts``: the
    same index as the whole form's, from smaller blocks.
    """
    s = np.asarray(mesh, dtype=float)
    first = nodes_and_midpoints(s)
    form = evaluate(first)
    if form.parts:
        split = form.split()
        if split is not None:
            counts = {name: _count(_part_form(evaluate, first, name, part), s, shift, source,
                                   first) for name, part in split.items()}
            if not any(c is None for c in counts.values()):
                parts = {name: c.index for name, c in counts.items()}
                failed = [f"{name}: {c.reason}" for name, c in counts.items() if c.index < 0]
                return Count(-1 if failed else sum(parts.values()), "; ".join(failed),
                             any(c.refused for c in counts.values()), parts=parts)
    whole = _count(lambda pts: form if pts is first else evaluate(pts), s, shift, source,
                   first)
    return Count(whole.index, whole.reason, whole.refused,
                 parts=dict.fromkeys(form.parts, -1))


def _part_form(evaluate, first, name, part):
    """``evaluate`` for the part ``name`` of the form: ``part`` on the points ``first``,
    elsewhere split anew (None where the form no longer decouples there)."""
    def on(pts):
        if pts is first:
            return part
        split = evaluate(pts).split()
        return None if split is None else split[name]
    return on


def _count(evaluate, s, shift, source, first) -> Count | None:
    """:func:`count_form` of one form, without its parts, ``first`` the nodes and midpoints
    of ``s``; None where ``evaluate`` gives None (a part that no longer decouples on the
    subdivided mesh)."""
    form, coeffs = _evaluate(evaluate, first, shift, source)
    if form is None:
        return None
    if coeffs is None:
        return _not_finite(form, first, source)
    a, b, c, a_min, _ = coeffs
    h = np.diff(s)
    parts = _parts(h, _wavenumber(a_min, b, c))
    if np.count_nonzero(parts > 1) and np.count_nonzero(c):
        # the bounds ask for more elements: the rates themselves, never above the bounds
        parts = _parts(h, rates(a, a_min, b, c))
    if np.count_nonzero(parts > 1):
        i = np.repeat(np.arange(len(h)), parts)
        j = np.arange(len(i)) - np.repeat(np.cumsum(parts) - parts, parts)
        s = np.append(s[i] + j * (h / parts)[i], s[-1])
        pts = nodes_and_midpoints(s)
        form, coeffs = _evaluate(evaluate, pts, shift, source)
        if form is None:
            return None
        if coeffs is None:
            return _not_finite(form, pts, source)
    try:
        return Count(_inertia(form, s, *coeffs))
    except _Singular as exc:
        return Count(-1, str(exc))


def _not_finite(form, pts, source) -> Count:
    """The count refused where the form's values are not finite at a finite state (the
    module's hook made NaN or inf: a 0/0 of its formulas, say), saying where: a point of the
    first field that is not finite there, or an end term or constraint."""
    a, b, c, g = form.fields(len(pts))
    bad = ~(np.isfinite(a).all(axis=(1, 2)) & np.isfinite(b).all(axis=(1, 2))
            & np.isfinite(c).all(axis=(1, 2)) & np.isfinite(g).all(axis=(0, 2)))
    where = f"at s = {pts[int(np.argmax(bad))]:.6g}" if bad.any() else "in an end term"
    return Count(-1, f"{source + ': ' if source else ''}second_variation is not finite "
                     f"{where}: the stability index is not defined there", refused=True)


def _evaluate(evaluate, pts, shift, source):
    """The form on the points ``pts`` (the nodes and midpoints of a mesh) and its fields (A,
    B, C, min eig A, g); fields None if any value is not finite (both None where ``evaluate``
    gives None). ProblemError where A is not positive definite."""
    form = evaluate(pts)
    if form is None:
        return None, None
    a, b, c, g = form.fields(len(pts))
    ends = (form.E0, form.E1, *(v for con in form.constraints for v in (con.d0, con.d1)))
    # one sum: NaN and inf propagate through it (a finite sum overflows only past 1e300)
    if not math.isfinite(float(a.sum() + b.sum() + c.sum() + g.sum()
                               + sum(v.sum() for v in ends))):
        return form, None
    if shift:
        b = b - shift * np.eye(form.k)
    a_min = min_eig(a)
    if not np.all(a_min > 0):
        j = int(np.argmin(a_min))
        # "module: second_variation: ...", or without a module's name (a module counting a
        # form of its own calls count_form without one)
        raise LegendreError(f"{source + ': ' if source else ''}second_variation: A is not "
                           f"positive definite at s = {pts[j]:.6g} (smallest eigenvalue "
                           f"{a_min[j]:.3g}): the Legendre condition fails there and the "
                           "stability index is not defined")
    return form, (a, b, c, a_min, g)


def _element_blocks(s, a, b, c):
    """The P2 element matrices on the nodes ``s``, from the fields on the nodes and midpoints
    (P, k, k), as blocks (n_el, k, k): (k00, k02, k22) between the element's two nodes and
    (k0m, k2m, kmm) with its midpoint.

    With x in [0, 1] on an element of length h and the Lagrange basis phi_0, phi_m, phi_2 at
    x = 0, 1/2, 1, Simpson's rule (weights 1/6, 4/6, 1/6 at those points, where phi_i =
    delta_iq and phi' = (-3, -1, 1), (4, 0, -4), (-1, 1, 3)) gives ::

        K_ij = sum_q w_q phi_i'(q) phi_j'(q) A_q / h + T_ij + T_ji^T + delta_ij w_i h B_i,
        T_ij = w_j phi_i'(x_j) C_j      (the term h'.C h of phi_i' e_a against phi_j e_b)
    """
    h = np.diff(s).reshape(-1, *(1,) * (a.ndim - 1))
    a0, am, a2 = a[0:-1:2], a[1::2], a[2::2]
    # k00, k22, k02, k0m, k2m as (w0 a0 + wm am + w2 a2) / (6 h), all five at once (the
    # weights of each as written above: -(12 a0 + 4 a2) is -12 a0 + 0 am - 4 a2 exactly)
    w = _P2_A.reshape(3, 5, *(1,) * a.ndim)
    blocks = w[0] * a0
    blocks += w[1] * am
    blocks += w[2] * a2
    blocks /= 6 * h
    k00, k22, k02, k0m, k2m = blocks
    k00 += (h / 6) * b[0:-1:2]
    k22 += (h / 6) * b[2::2]
    kmm = (16 / 6) * (a0 + a2) / h + (4 / 6) * h * b[1::2]
    if np.count_nonzero(c):
        c0, cm, c2 = c[0:-1:2], c[1::2], c[2::2]
        c0t, c2t = (c0, c2) if c.ndim == 1 else (c0.transpose(0, 2, 1), c2.transpose(0, 2, 1))
        k00 -= 0.5 * (c0 + c0t)
        k22 += 0.5 * (c2 + c2t)
        k02 += (c2 - c0t) / 6
        k0m += (4 / 6) * (c0t - cm)
        k2m += (4 / 6) * (cm - c2t)
    return (k00, k02, k22), (k0m, k2m, kmm)


#: The weights of a0, am, a2 in k00, k22, k02, k0m, k2m (times 6 h).
_P2_A = np.array([[9, 1, 3, -12, -4], [4, 4, -4, 0, 0], [1, 9, 3, -4, -12]], dtype=float)


def _inertia(form, s, a, b, c, a_min, g) -> int:
    """The index of ``form`` by P2 elements on the nodes ``s`` (:func:`count_form`), its
    fields on the nodes and midpoints. Each midpoint belongs to one element and is eliminated
    there (Haynsworth: In(K) = In(K_mm) + In(K / K_mm)), leaving a block tridiagonal matrix on
    the nodes; all its nodes but the last DENSE_TAIL or fewer are eliminated by odd-even
    (cyclic) reduction, and the matrix left is counted as one dense matrix by its LDL^T
    with Bunch-Kaufman pivoting (for k = 1 without constraints, :func:`_sturm` counts the
    node matrix's pivots instead).

    The element matrices (:func:`_element_blocks`' formulas), the midpoints' elimination and
    the reduction's levels are compiled (numerics/_blocks.c: a few dozen numpy calls each on
    100-200 small blocks cost more than their arithmetic). The reduction is a block LDL^T of
    the node matrix K with the nodes ordered odd ones first, level by level: the odd nodes of
    a level are coupled only to even ones, so their pivots are the diagonal blocks
    themselves; their Schur complement is again block tridiagonal on the even nodes. By
    Haynsworth's additivity the negative eigenvalues of all the pivots, the last matrix's
    included, are n_-(K) (Sylvester); the constraint columns, eliminated alongside,
    accumulate C K^-1 C^T (and, for the scale of its rounding, |C| |K^-1| |C|^T). A pivot of
    2 or 3 components counts its negative eigenvalues by Descartes' rule on its
    characteristic polynomial and is inverted by its adjugate; a larger one by its
    eigendecomposition (Jacobi's method). The first levels' pivots couple neighbours a few
    elements apart, where the stiffness dominates (MAX_PHASE): they are positive definite and
    well conditioned."""
    k, r = form.k, len(form.constraints)
    if k == 1 and not r:
        return _inertia_scalar(form, s, a[:, 0, 0], b[:, 0, 0], c[:, 0, 0])
    h = np.diff(s)
    d, u = np.empty((len(s), k, k)), np.empty((len(h), k, k))
    # kmm_inv: the midpoint blocks' inverses; y = kmm_inv [K_m0, K_m2] (k, 2k) each
    kmm_inv, y = np.empty((len(h), k, k)), np.empty((len(h), k, 2 * k))
    negative, scale = blocks_condense(s, a, b, c, _ULPS, d, u, kmm_inv, y)
    if negative < 0:
        raise _Singular("zero eigenvalue: an element's midpoint block is singular to working "
                        "precision")
    d[0] += form.E0
    d[-1] += form.E1
    gt = g.transpose(1, 2, 0)                                       # (points, k, r)
    cm = ((4 / 6) * h)[:, None, None] * gt[1::2]
    f = _constraint_columns(form, h, gt, y[:, :, :k], y[:, :, k:], cm)
    _restrict(d, u, f, 0, form.free0, form.fixed0)
    _restrict(d, u, f, -1, form.free1, form.fixed1)
    s_mat = [np.zeros((r, r)), np.zeros((r, r))]
    if r:
        _accumulate(cm, kmm_inv, s_mat)
    neg_k, n = blocks_reduce(d, u, f, scale, DENSE_TAIL, *s_mat)     # in place
    if neg_k < 0:
        raise _Singular("zero eigenvalue: a pivot of the node matrix is singular to working "
                        "precision")
    negative += neg_k
    d, u, f = d[:n], u[:n - 1], f[:n]
    # What is left, the block tridiagonal matrix D of the last nodes and, with constraints,
    # the multipliers, [[D, F], [F^T, -C K'^-1 C^T]] (K' the eliminated part), is counted as
    # one dense matrix. Its inertia is In(D) + In(-C K^-1 C^T) where D is nonsingular, but it
    # is counted as a whole: a constraint that removes a zero mode of K (a symmetry) makes D
    # singular and this matrix not. n_-(bordered) = n_-(form on ker C) + r. An eigenvalue
    # within tol of zero is zero to working precision: the matrix shifted by -tol and by
    # +tol has below and above negative eigenvalues (two LDL^T factorisations with
    # Bunch-Kaufman pivoting, numerics/_blocks.c `window`; Sylvester), below - above of
    # them in [-tol, tol); with none there the count is above. (An eigenvalue solve decides
    # the same, at four times the cost: 50 against 13 microseconds on 39 rows.)
    total, size = s_mat
    tol = scale + _ULPS * size.max(initial=0)
    below, above = blocks_window(_dense_tail(d, u, f, -total), tol)
    if below == -2:
        raise _Singular("the last nodes' matrix is not finite (the reduction overflowed)")
    if below != above or above < 0:
        raise _Singular("zero eigenvalue: the last nodes' block is singular to working "
                        "precision (a fold or a branch point)" if not r else
                        "zero eigenvalue: the constrained form is singular to working "
                        "precision (a fold or a branch point), or the constraints are "
                        "dependent")
    return negative + above - r


def _dense_tail(d, u, f, corner):
    """The symmetric matrix [[D, F], [F^T, corner]] of the block tridiagonal D (diagonal
    blocks ``d`` (N, k, k), upper ``u`` (N-1, k, k)) and the columns ``f`` (N, k, r)."""
    n, k, r = d.shape[0], d.shape[1], f.shape[2]
    blocks = np.zeros((n, k, n, k))
    i = np.arange(n)
    blocks[i, :, i, :] = d
    blocks[i[:-1], :, i[1:], :] = u
    blocks[i[1:], :, i[:-1], :] = u.transpose(0, 2, 1)
    out = np.empty((n * k + r, n * k + r))
    out[:n * k, :n * k] = blocks.reshape(n * k, n * k)
    out[:n * k, n * k:] = f.reshape(n * k, r)
    out[n * k:, :n * k] = out[:n * k, n * k:].T
    out[n * k:, n * k:] = corner
    return 0.5 * (out + out.T)


def _inertia_scalar(form, s, a, b, c) -> int:
    """:func:`_inertia` for k = 1 without constraints, on (n,) arrays: the node matrix is
    tridiagonal and its pivots are counted in plain floats (:func:`_sturm`); a third of the
    cost of the block form on the planar rod's meshes of 50-200 nodes, where numpy's cost per
    call dominates."""
    (k00, k02, k22), (k0m, k2m, kmm) = _element_blocks(s, a, b, c)
    scale = _ULPS * float((np.abs(k00) + np.abs(k22)).max())
    if np.any(np.abs(kmm) <= scale):
        raise _Singular("zero eigenvalue: an element's midpoint block is singular to working "
                        "precision")
    negative = int(np.count_nonzero(kmm < 0))
    diag = np.zeros(len(s))
    diag[:-1] += k00 - k0m * k0m / kmm
    diag[1:] += k22 - k2m * k2m / kmm
    off = k02 - k0m * k2m / kmm
    diag[0] += form.E0[0, 0]
    diag[-1] += form.E1[0, 0]
    # a fixed end's node is no unknown: its row and column are left out
    lo, hi = (0 if form.free0.shape[1] else 1), (len(diag) - (0 if form.free1.shape[1] else 1))
    return negative + _sturm(diag[lo:hi].tolist(), (off[lo:hi - 1] ** 2).tolist(), scale)


def _accumulate(f, inv, into):
    """Add to ``into`` = [C K^-1 C^T, its size] the terms f^T D^-1 f of the constraint rows
    ``f`` (p, k, r) of eliminated pivots with inverses ``inv`` (p, k, k), and the same sum of
    absolute values (the scale of its rounding errors)."""
    into[0] += np.einsum("pai,pab,pbj->ij", f, inv, f)
    into[1] += np.einsum("pai,pab,pbj->ij", np.abs(f), np.abs(inv), np.abs(f))


def _constraint_columns(form, h, gt, x0, x2, cm):
    """The constraints as columns on the nodes, (n_nodes, k, r): Simpson's rule for int g.h
    (a node or midpoint value times its weight; ``gt`` the values (points, k, r), ``cm`` the
    midpoints' weighted) plus d0, d1 at the ends, the midpoint parts condensed like the
    stiffness: C_n - K_nm K_mm^-1 C_m, with K_nm K_mm^-1 = x^T."""
    r = len(form.constraints)
    f = np.zeros((len(h) + 1, form.k, r))
    if not r:
        return f
    f[:-1] += (h / 6)[:, None, None] * gt[0:-1:2]
    f[1:] += (h / 6)[:, None, None] * gt[2::2]
    f[0] += np.array([con.d0 for con in form.constraints]).T
    f[-1] += np.array([con.d1 for con in form.constraints]).T
    f[:-1] -= x0.transpose(0, 2, 1) @ cm
    f[1:] -= x2.transpose(0, 2, 1) @ cm
    return f


def _restrict(d, u, f, end, free, fixed):
    """Impose the essential conditions at node ``end`` (0 or -1): in the basis [free, fixed]
    of its directions, the fixed coordinates are decoupled (rows and columns of the block, the
    coupling and the constraints zeroed) and given a positive pivot, which adds a positive
    eigenvalue per fixed direction and leaves the negative count that of the restriction."""
    if not fixed.shape[1]:
        return
    if not free.shape[1]:   # all fixed: the node's own block, decoupled
        fill = max(float(np.abs(d[end]).max()), 1.0)
        d[end] = fill * np.eye(len(fixed))
        u[0 if end == 0 else -1] = 0.0
        f[end] = 0.0
        return
    q = np.hstack((free, fixed))
    nf = free.shape[1]
    block = q.T @ d[end] @ q
    fill = max(float(np.max(np.abs(block))), 1.0)
    block[nf:, :] = 0.0
    block[:, nf:] = 0.0
    block[nf:, nf:] = fill * np.eye(fixed.shape[1])
    d[end] = block
    if end == 0:
        u[0] = q.T @ u[0]
        u[0][nf:, :] = 0.0
    else:
        u[-1] = u[-1] @ q
        u[-1][:, nf:] = 0.0
    f[end] = q.T @ f[end]
    f[end][nf:, :] = 0.0


#: The diagonal of a 3 x 3 block flattened.
_DIAG3 = np.array([0, 4, 8])
#: A symmetric 3 x 3 block flattened, its entries a, b, c (diagonal), d, e, f (01, 02, 12).
_SYM3 = np.array([0, 4, 8, 1, 2, 5])


def _sturm(diag, off2, scale) -> int:
    """Negative pivots of the LDL^T of a symmetric tridiagonal matrix (diagonal ``diag``,
    squared off-diagonal ``off2``): the k = 1 case of :func:`_reduce` without constraints, in
    plain floats (a tenth of the cost of the array form on a few hundred nodes)."""
    negative, d = 0, diag[0]
    for dj, e2 in zip(diag[1:], off2):
        if -scale <= d <= scale:
            raise _Singular("zero eigenvalue: a pivot of the node matrix is singular to "
                            "working precision")
        if d < 0:
            negative += 1
        d = dj - e2 / d
    if -scale <= d <= scale:
        raise _Singular("zero eigenvalue: the last pivot is zero to working precision "
                        "(a fold or a branch point)")
    return negative + (d < 0)


#: The reduction stops at this many nodes or fewer, whose block tridiagonal matrix is then
#: counted as one dense symmetric matrix (`_inertia`: two pivoted LDL^T of it shifted). The
#: reduction's levels pivot on diagonal blocks without exchanges; past a few levels their
#: rounding can exceed the singularity threshold, and a zero eigenvalue goes unseen: with 8
#: or 4 nodes here, six labels of the shipped fold-curve and tendon files (singular, each
#: refused with 16) got a count. 16 nodes keep them refused.
DENSE_TAIL = 16


def kernel_dimension(problem, state, delta: float | None = None) -> int:
    """The number of eigenvalues of the second variation at ``state`` within ``delta`` of
    zero: n_-(form - delta) - n_-(form + delta) (shifts by the L2 inner product), -1 if
    either count fails. Constraints that remove a symmetry's zero mode (``Constraint.kernel``)
    are left out: that mode is one of the eigenvalues that cross zero there (the index on
    either side of a symmetric point is counted without it), so it belongs to the kernel.
    ``delta`` defaults to 1e-3 times the mean of the smallest eigenvalue of A, far above the
    P2 error of an eigenvalue near zero and far below the spacing of the eigenvalues of the
    examples (of order pi^2 A)."""
    if not problem.has_second_variation:
        return -1
    on_state = form_on_state(problem, state)

    def evaluate(pts):
        return on_state(pts).without_kernel_modes()

    if delta is None:
        a = evaluate(nodes_and_midpoints(state.s)).fields(2 * len(state.s) - 1)[0]
        delta = 1e-3 * float(np.mean(min_eig(a)))
    above = count_form(evaluate, state.s, shift=delta, source=_source(problem)).index
    below = count_form(evaluate, state.s, shift=-delta, source=_source(problem)).index
    return above - below if min(above, below) >= 0 else -1


def index_change(enters: str, curvature: float, slope: float) -> int:
    """Index change across a simple fold in the direction of travel, from the signs of the
    parameter's curvature xi'' and of the ordinate's slope dB/dtau there:
    ``+sign(xi'' dB/dtau)`` for a parameter entering the free end or the ODE, ``-sign(...)``
    for one entering the fixed end; 0 if either vanishes (not a simple fold) or is not
    finite (a module's distinguished ordinate NaN next to the fold: no sign to read)."""
    if not (np.isfinite(curvature) and np.isfinite(slope)):
        return 0
    change = int(np.sign(curvature) * np.sign(slope))
    return -change if enters == "fixed" else change


def fold_sign(enters: str, lam: np.ndarray, ordinate: np.ndarray, k: int) -> int:
    """:func:`index_change` at the fold at point ``k``, the signs read off its neighbours."""
    if k == 0 or k == len(lam) - 1:
        return 0
    return index_change(enters, (lam[k - 1] - lam[k]) + (lam[k + 1] - lam[k]),
                        ordinate[k + 1] - ordinate[k - 1])


def fold_rule(branch, problem, start_index: int) -> list[int]:
    """Index at every point of ``branch`` from ``start_index`` and the sign rule at each LP.

    The index of a point that is itself an LP is the value on the side it is approached from.
    The sign needs only the neighbouring points, so it also applies at a fold whose extended
    system failed. Where the rule cannot apply (a fold of a parameter without a distinguished
    ordinate, a branch point) it takes the direct count after the special point, if there is
    one, else -1 (where that point is an LP, the count beyond the LPs less their changes:
    :func:`_count_past`). Points at a branch point itself (the same parameter
    value: a user point placed on it, before or after it) are not past it: the count there
    leaves out the eigenvalues that cross zero (a symmetry's zero mode is constrained away,
    or the count fails), so the rule takes the first point off it, and gives the points on it
    the smaller of the values on either side, the negative eigenvalues that both sides share
    (the kernel's eigenvalues cross zero, each negative on one side only); the BP itself, as
    an LP, the value it is approached with.
    """
    name = branch.parameter
    ordinate = next((o.name for o in problem.ordinates.values() if o.parameter == name), None)
    enters = problem.parameters[name].enters
    lam = branch.column(name)
    ords = branch.column(ordinate) if ordinate else None
    pts = branch.points
    spans = _on_branch_points(pts, lam)
    out, current, k = [], start_index, 0
    while k < len(pts):
        if k in spans:
            last = spans[k]
            after = _count_past(pts, last + 1, enters, lam, ords)
            for j in range(k, last + 1):
                if pts[j].type in labels.SWITCHES:
                    out.append(current)
                elif current >= 0 and after >= 0:
                    out.append(min(current, after))
                else:
                    out.append(pts[j].index_direct)
            current, k = after, last + 1
            continue
        out.append(current)
        if pts[k].type in labels.FOLDS and current >= 0:
            change = fold_sign(enters, lam, ords, k) if ords is not None else 0
            current = current + change if change else -1
        if current < 0 and k + 1 < len(pts):
            current = _count_past(pts, k + 1, enters, lam, ords)
        k += 1
    return out


def _count_past(pts, j, enters, lam, ords) -> int:
    """The index on the branch at point ``j``, where the rule restarts (past a branch point,
    or where it cannot apply): the direct count at ``j``, or, where ``j`` is an LP (its state
    has a zero eigenvalue, so its count is a guess by rounding, or -1), the count at the
    first point past the LPs from ``j`` less their changes by the fold rule. -1 where there
    is no such point or a change is not known (an LP at the branch's end, no distinguished
    ordinate)."""
    change = 0
    while j < len(pts) and pts[j].type in labels.FOLDS:
        sign = fold_sign(enters, lam, ords, j) if ords is not None else 0
        if not sign:
            return -1
        change += sign
        j += 1
    if j >= len(pts) or pts[j].index_direct < 0:
        return -1
    return pts[j].index_direct - change


def _on_branch_points(pts, lam) -> dict[int, int]:
    """{first: last} of each run of consecutive points at a branch point: the BP and its
    neighbours at the same parameter value (user points placed on it)."""
    spans = {}
    for k, p in enumerate(pts):
        if p.type not in labels.SWITCHES:
            continue
        lo = hi = k
        while lo > 0 and abs(lam[lo - 1] - lam[k]) <= 1e-9 * (1.0 + abs(lam[k])):
            lo -= 1
        while hi + 1 < len(pts) and abs(lam[hi + 1] - lam[k]) <= 1e-9 * (1.0 + abs(lam[k])):
            hi += 1
        first = next((f for f, last in spans.items() if f <= lo <= last + 1), None)
        if first is None:
            spans[lo] = hi
        else:
            spans[first] = max(spans[first], hi)
    return spans


def label_stability(branch, problem) -> None:
    """Fill ``index_rule`` and ``index`` on every point of ``branch`` (of ``problem``).

    The rule starts from the direct count at the first point (the second after a switch).
    ``index`` is the common value where rule and direct count agree; at LP and BP points
    (critical eigenvalue zero, direct count ambiguous) it is the rule's value. Elsewhere a
    disagreement leaves ``index = -1`` and says so in the point's note: it is never hidden.

    A branch on which folds or branch points were not looked for (the option ``detect``)
    has no rule to follow, which reads them: its ``index`` is the direct count.
    """
    if not branch.points or not problem.has_second_variation:
        return
    if not all((branch.options or {}).get("detect", {}).values()):
        for p in branch.points:
            p.index_rule, p.index = -1, p.index_direct
        return
    # A branch switched at a branch point starts where the direct count is ambiguous.
    pts = branch.points
    seed = pts[1 if branch.singular_start and len(pts) > 1 else 0]
    rule = fold_rule(branch, problem, seed.index_direct)
    for k, (p, r) in enumerate(zip(pts, rule)):
        p.index_rule = r
        if p.type in labels.TURNS or (k == 0 and branch.singular_start):
            p.index = r
        elif r == p.index_direct:
            p.index = r
        elif p.index_direct < 0:   # not counted there (the note says why, where it can)
            p.index = -1
        else:
            p.index = -1
            msg = f"index disagreement: rule {r}, direct {p.index_direct}"
            p.note = "; ".join(filter(None, (p.note, msg)))
    if branch.closed:   # a closed loop ends at its start's own solution, and so its index
        pts[-1].index = pts[-1].index_rule = pts[0].index
