"""Stability index: by direct count and by the fold rule (docs/design.md, "Stability index").

The index of an equilibrium is the number of negative eigenvalues of the second variation.
An equation module provides it in scalar Sturm-Liouville form through the optional hook
``second_variation(s, y, p) -> (a, b, c)``::

    delta^2 E[h] = int_0^1 ( a(s) h'^2 + b(s) h^2 ) ds + c h(1)^2,   h(0) = 0,   a > 0,

whose eigenproblem is ``-(a h')' + b h = mu h`` with the natural end condition
``a h'(1) + c h(1) = 0``. :func:`index` counts its negative eigenvalues directly at every
point (the tests check it against a Jacobi-field count, a dense Galerkin count and the straight
rod's critical loads).

A constrained problem (an end held by a pin: isoperimetric constraints with Lagrange
multipliers) returns a fourth element, the linearised constraints as a list of pairs
``(g_i(s), d_i)``; the index is then that of the second variation restricted to the variations
with ``int_0^1 g_i h ds + d_i h(1) = 0`` for every i. With K the stiffness matrix and C the
discretised constraints (full row rank r), the bordered matrix M = [[K, C^T], [C, 0]] has
In(M) = In(K) + In(-S), S = C K^{-1} C^T (Haynsworth), and n_-(M) = n_-(K restricted to
ker C) + r; so, S being nonsingular, ::

    index_constrained = n_-(K) - n_-(S).

The fold rule (:func:`fold_rule`) propagates a known index along a branch: at a simple fold of
a parameter xi entering the free end (or the ODE), ``d/dtau delta^2 J = -xi'' dB_xi/dtau``
(the paper's eqn:Distinguished_biff_diagram_free_end) so the index changes by
``+sign(xi'' dB/dtau)`` in the direction of travel; for a fixed-end parameter, whose ordinate
``m0 = -dE/dxi`` has the opposite sign, by ``-sign(xi'' dB/dtau)``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_banded

from .solution import at_fractions

#: Simpson's rule on [0, 1]: the element's nodes, where the solution is known, and midpoint.
#: It is exact for the stiffness of constant coefficients and O(h^4) otherwise, the order of
#: the P2 eigenvalues themselves.
_GAUSS_X = np.array([0.0, 0.5, 1.0])
_GAUSS_W = np.array([1.0, 4.0, 1.0]) / 6.0
#: P2 Lagrange basis (left node, midpoint, right node) and its derivative at those points.
_PHI = np.array([(1 - _GAUSS_X) * (1 - 2 * _GAUSS_X), 4 * _GAUSS_X * (1 - _GAUSS_X),
                 _GAUSS_X * (2 * _GAUSS_X - 1)])
_DPHI = np.array([4 * _GAUSS_X - 3, 4 - 8 * _GAUSS_X, 4 * _GAUSS_X - 1])
#: Products of basis derivatives and of basis functions at each quadrature point, (3, 9).
_STIFF = np.einsum("iq,jq->qij", _DPHI, _DPHI).reshape(3, 9)
_MASS = np.einsum("iq,jq->qij", _PHI, _PHI).reshape(3, 9)


#: Elements are small enough for the eigenfunctions near zero eigenvalue, which oscillate with
#: wavenumber w = sqrt(|b| / a), when h w <= MAX_PHASE. P2 elements are then accurate enough
#: that on the straight rod (eps = 0.25, the first three critical loads, 20 and 50 intervals)
#: the count is right down to 1e-4 (relative) from each critical load; at h w = 0.4 it is not.
MAX_PHASE = 0.2


def _coefficients(problem, state, s):
    """a, b at the nodes and midpoints of each interval of the mesh ``s`` ((m-1, 3) each: left
    node, midpoint, right node), c, and the constraints as a list of (g, d) with g laid out
    like a and b (empty without them), from the state's interpolant (on its own mesh, or a
    refinement of it)."""
    mid = 0.5 * (s[:-1] + s[1:])
    if s is state.s:
        y = np.concatenate((at_fractions(s, state.y, state.yp, (0.5,))[:, 0], state.y), axis=1)
    else:
        y = state(np.concatenate((mid, s)))
    # the hook reads the end term from the last column: the nodes come last, s = 1 at the end
    a, b, c, *rest = problem.second_variation(np.concatenate((mid, s)), y, state.params)
    k = len(mid)

    def layout(v):
        v = np.broadcast_to(np.asarray(v, dtype=float), (2 * k + 1,))
        return np.stack((v[k:-1], v[:k], v[k + 1:]), axis=1)

    constraints = [(layout(g), float(d)) for g, d in (rest[0] if rest else ())]
    return layout(a), layout(b), float(c), constraints


def _constraint_count(k, kmm, diag, off, h, constraints) -> int | None:
    """n_-(S), S = C K^{-1} C^T, of the discretised constraints ``int g h ds + d h(1)``
    (Simpson's rule, like the stiffness: a node or midpoint value times its weight), with K
    condensed like the stiffness: S = C_m K_mm^{-1} C_m^T + C' T^{-1} C'^T, C' = C_n -
    K_nm K_mm^{-1} C_m, T the tridiagonal node matrix (``diag``, ``off``, node 0 clamped).
    None if T is singular."""
    n = len(diag)
    cm, cn = [], []
    for g, d in constraints:
        m = h * _GAUSS_W[1] * g[:, 1]
        nodes = np.zeros(n + 1)
        nodes[:-1] += h * _GAUSS_W[0] * g[:, 0] - k[:, 0, 1] / kmm * m
        nodes[1:] += h * _GAUSS_W[2] * g[:, 2] - k[:, 2, 1] / kmm * m
        nodes[-1] += d
        cm.append(m)
        cn.append(nodes[1:])
    cm, cn = np.array(cm), np.array(cn)
    ab = np.zeros((3, n))
    ab[0, 1:] = off
    ab[1] = diag
    ab[2, :-1] = off
    try:
        x = solve_banded((1, 1), ab, cn.T)
    except (np.linalg.LinAlgError, ValueError):
        return None
    s = (cm / kmm) @ cm.T + cn @ x
    if not np.all(np.isfinite(s)):
        return None
    return int(np.count_nonzero(np.linalg.eigvalsh(0.5 * (s + s.T)) < 0))


def index(problem, state) -> int:
    """The number of negative eigenvalues of the second variation at ``state``, or -1 (unknown)
    if the module has no ``second_variation`` hook or the state or the coefficients are not
    all finite.

    Quadratic (P2) finite elements on the state's own mesh, each interval subdivided where the
    coefficients oscillate faster than the mesh resolves (``MAX_PHASE``); the coefficients at
    each element's nodes and midpoint (Simpson's rule). The element matrices
    ``K_e = int (a phi_i' phi_j' + b phi_i phi_j)``, the end term ``c h(1)^2``, ``h(0) = 0``.
    The index is the inertia of K (Sylvester; the mass matrix is positive definite, so K and
    the generalised eigenproblem have the same number of negative eigenvalues). Each midpoint
    unknown belongs to one element, so it is eliminated element by element: by Haynsworth's
    inertia additivity, In(K) = In(K_mm) + In(K / K_mm), K_mm the (diagonal) midpoint block
    and K / K_mm a tridiagonal matrix on the nodes, whose negative LDL^T pivots are counted.
    The count is exact unless an eigenvalue lies within the discretisation error of zero (at
    a fold or a branch point, where it is zero). With constraints (a fourth element of the
    hook's result) the count of the restricted form, n_-(K) - n_-(C K^{-1} C^T) (module
    docstring), the constraint vectors condensed like K (:func:`_constraint_count`)."""
    if not problem.has_second_variation:
        return -1
    # NaN compares false with everything, so the count below would call such a point stable
    if not (np.all(np.isfinite(state.y)) and np.all(np.isfinite(state.yp))
            and all(np.isfinite(v) for v in state.params.values())):
        return -1
    s = state.s
    a, b, c, cons = _coefficients(problem, state, s)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.isfinite(c)
            and all(np.all(np.isfinite(g)) and np.isfinite(d) for g, d in cons)):
        return -1
    h = np.diff(s)
    parts = np.ceil(h * np.sqrt(np.max(np.abs(b) / a, axis=1)) / MAX_PHASE).astype(int)
    if np.any(parts > 1):
        i = np.repeat(np.arange(len(h)), parts)
        j = np.arange(len(i)) - np.repeat(np.cumsum(parts) - parts, parts)
        s = np.append(s[i] + j * (h / parts)[i], s[-1])
        a, b, c, cons = _coefficients(problem, state, s)
        h = np.diff(s)
    k = (((a * _GAUSS_W) @ _STIFF) / h[:, None]
         + ((b * _GAUSS_W) @ _MASS) * h[:, None]).reshape(-1, 3, 3)
    kmm = k[:, 1, 1]
    kmm = np.where(kmm == 0.0, 1e-300, kmm)
    left = k[:, 0, 0] - k[:, 0, 1] * k[:, 1, 0] / kmm
    right = k[:, 2, 2] - k[:, 2, 1] * k[:, 1, 2] / kmm
    off = k[:, 0, 2] - k[:, 0, 1] * k[:, 1, 2] / kmm
    diag = np.zeros(len(s))
    diag[:-1] += left
    diag[1:] += right
    diag[-1] += c
    negative = int(np.count_nonzero(kmm < 0))
    if cons:
        removed = _constraint_count(k, kmm, diag[1:], off[1:], h, cons)
        if removed is None:
            return -1
        negative -= removed
    diag, off2 = diag[1:].tolist(), (off[1:] ** 2).tolist()    # node 0 is clamped
    d = diag[0]
    for dj, e2 in zip(diag[1:], off2):
        if d < 0:
            negative += 1
        d = dj - e2 / (d or 1e-300)
    return negative + (d < 0)


def index_change(enters: str, curvature: float, slope: float) -> int:
    """Index change across a simple fold in the direction of travel, from the signs of the
    parameter's curvature xi'' and of the ordinate's slope dB/dtau there:
    ``+sign(xi'' dB/dtau)`` for a parameter entering the free end or the ODE, ``-sign(...)``
    for one entering the fixed end; 0 if either vanishes (not a simple fold)."""
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
    one, else -1.
    """
    name = branch.parameter
    ordinate = next((o.name for o in problem.ordinates.values() if o.parameter == name), None)
    enters = problem.parameters[name].enters
    lam = branch.column(name)
    ords = branch.column(ordinate) if ordinate else None
    out, current = [], start_index
    for k, p in enumerate(branch.points):
        out.append(current)
        if p.type == "LP" and current >= 0:
            change = fold_sign(enters, lam, ords, k) if ords is not None else 0
            current = current + change if change else -1
        elif p.type == "BP":
            current = -1
        if current < 0 and k + 1 < len(branch.points):
            current = branch.points[k + 1].index_direct
    return out


def label_stability(branch, problem) -> None:
    """Fill ``index_rule`` and ``index`` on every point of ``branch`` (of ``problem``).

    The rule starts from the direct count at the first point (the second after a switch).
    ``index`` is the common value where rule and direct count agree; at LP and BP points
    (critical eigenvalue zero, direct count ambiguous) it is the rule's value. Elsewhere a
    disagreement leaves ``index = -1`` and says so in the point's note: it is never hidden.
    """
    if not branch.points or not problem.has_second_variation:
        return
    # A branch switched at a branch point starts where the direct count is ambiguous.
    seed = branch.points[1 if branch.singular_start and len(branch.points) > 1 else 0]
    rule = fold_rule(branch, problem, seed.index_direct)
    for k, (p, r) in enumerate(zip(branch.points, rule)):
        p.index_rule = r
        if p.type in ("LP", "BP") or (k == 0 and branch.singular_start):
            p.index = r
        elif r == p.index_direct:
            p.index = r
        else:
            p.index = -1
            msg = f"index disagreement: rule {r}, direct {p.index_direct}"
            p.note = "; ".join(filter(None, (p.note, msg)))
