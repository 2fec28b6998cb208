"""Stability index: by direct count and by the fold rule (DESIGN section 3).

The index of an equilibrium is the number of negative eigenvalues of the second variation.
An equation module provides it in scalar Sturm-Liouville form through the optional hook
``second_variation(s, y, p) -> (a, b, c)``::

    delta^2 E[h] = int_0^1 ( a(s) h'^2 + b(s) h^2 ) ds + c h(1)^2,   h(0) = 0,   a > 0,

whose eigenproblem is ``-(a h')' + b h = mu h`` with the natural end condition
``a h'(1) + c h(1) = 0``. Two independent counts:

* :func:`index_jacobi` -- the Jacobi field ``(a u')' = b u``, ``u(0) = 0``, ``a u'(0) = 1``
  (RK4 on a fine grid). By Sturm's comparison (Pruefer angle) the index is the number of zeros
  of u in (0, 1) plus one if ``u(1) (a u'(1) + c u(1)) < 0``; a zero at s = 1 counts as one.
* :func:`index_fem` -- piecewise-linear finite elements for the quadratic form; the index is the
  number of negative pivots of its LDL^T factorisation (Sylvester's law of inertia).

The fold rule (:func:`fold_rule`) propagates a known index along a branch: at a simple fold of
a parameter xi entering the free end (or the ODE), ``d/dtau delta^2 J = -xi'' dB_xi/dtau``
(the paper's eqn:Distinguished_biff_diagram_free_end) so the index changes by
``+sign(xi'' dB/dtau)`` in the direction of travel; for a fixed-end parameter, whose ordinate
``m0 = -dE/dxi`` has the opposite sign, by ``-sign(xi'' dB/dtau)``.
"""

from __future__ import annotations

import numpy as np

#: Elements of the finite-element count and steps of the Jacobi-field integration.
N_ELEMENTS = 800


def _coefficients(problem, state, n=N_ELEMENTS):
    """a, b on the grid s_j = j / (2 n) (nodes and midpoints of n elements), and c."""
    s = np.linspace(0.0, 1.0, 2 * n + 1)
    a, b, c = problem.second_variation(s, state(s), state.params)
    return (np.broadcast_to(np.asarray(a, dtype=float), s.shape),
            np.broadcast_to(np.asarray(b, dtype=float), s.shape), float(c))


def _jacobi_field(a, b):
    """RK4 for u' = w / a, w' = b u from u(0) = 0, w(0) = 1 on the grid of ``a``, ``b``
    (nodes and midpoints). Returns u(1), w(1) = a u'(1) and the zeros of u in (0, 1)."""
    n = (len(a) - 1) // 2
    h = 1.0 / n
    a, b = np.asarray(a, dtype=float).tolist(), np.asarray(b, dtype=float).tolist()
    u, w = 0.0, 1.0
    zeros = 0
    for j in range(n):
        a0, am, a1 = a[2 * j], a[2 * j + 1], a[2 * j + 2]
        b0, bm, b1 = b[2 * j], b[2 * j + 1], b[2 * j + 2]
        k1u, k1w = w / a0, b0 * u
        k2u, k2w = (w + h / 2 * k1w) / am, bm * (u + h / 2 * k1u)
        k3u, k3w = (w + h / 2 * k2w) / am, bm * (u + h / 2 * k2u)
        k4u, k4w = (w + h * k3w) / a1, b1 * (u + h * k3u)
        u_new = u + h / 6 * (k1u + 2 * k2u + 2 * k3u + k4u)
        w = w + h / 6 * (k1w + 2 * k2w + 2 * k3w + k4w)
        if j > 0 and u != 0.0 and u * u_new <= 0.0 and (u_new != 0.0 or j < n - 1):
            zeros += 1
        u = u_new
    return u, w, zeros


def index_jacobi(a, b, c) -> int:
    """Index from the Jacobi field; ``a``, ``b`` sampled at nodes and midpoints (2n + 1)."""
    u, w, zeros = _jacobi_field(a, b)
    if u == 0.0:
        return zeros + 1
    return zeros + (1 if u * (w + c * u) < 0 else 0)


def singularity_test(problem, state) -> float:
    """``a u'(1) + c u(1)`` of the Jacobi field: zero exactly where the second variation has a
    zero eigenvalue with the natural end condition (a fold or a branch point), and of opposite
    signs on either side of a simple one. Used to locate branch points."""
    a, b, c = _coefficients(problem, state)
    u, w, _ = _jacobi_field(a, b)
    return w + c * u


def index_fem(a, b, c) -> int:
    """Index from P1 finite elements: negative pivots of the tridiagonal stiffness matrix."""
    n = (len(a) - 1) // 2
    h = 1.0 / n
    am, bm = a[1::2], b[1::2]           # element midpoint values
    diag = np.zeros(n + 1)
    diag[:-1] += am / h + bm * h / 3
    diag[1:] += am / h + bm * h / 3
    off = -am / h + bm * h / 6
    diag[-1] += c
    diag, off2 = diag.tolist(), (off ** 2).tolist()
    d, negative = diag[1], 0           # node 0 is clamped (h(0) = 0)
    for i in range(2, n + 2):
        if d == 0.0:
            d = 1e-300
        if d < 0:
            negative += 1
        if i <= n:
            d = diag[i] - off2[i - 1] / d
    return negative


def direct_index(problem, state) -> tuple[int, int]:
    """(Jacobi-field index, finite-element index) of a solution; (-1, -1) without the hook."""
    if not problem.has_second_variation:
        return -1, -1
    a, b, c = _coefficients(problem, state)
    return index_jacobi(a, b, c), index_fem(a, b, c)


def fold_sign(enters: str, lam: np.ndarray, ordinate: np.ndarray, k: int) -> int:
    """Index change across the fold at point ``k`` in the direction of travel, from its
    neighbours: ``+sign(xi'' dB/dtau)`` (free end, ODE) or ``-sign(...)`` (fixed end); 0 if
    the fold is not simple as seen from the neighbouring points."""
    if k == 0 or k == len(lam) - 1:
        return 0
    curvature = np.sign((lam[k - 1] - lam[k]) + (lam[k + 1] - lam[k]))  # sign of xi''
    slope = np.sign(ordinate[k + 1] - ordinate[k - 1])                 # sign of dB/dtau
    change = int(curvature * slope)
    return -change if enters == "fixed" else change


def fold_rule(branch, start_index: int) -> list[int]:
    """Index at every point of ``branch`` from ``start_index`` and the sign rule at each LP.

    The index of a point that is itself an LP is the value on the side it is approached from.
    The sign needs only the neighbouring points, so it also applies at a fold whose extended
    system failed. Where the rule cannot apply (a fold of a parameter without a distinguished
    ordinate, a branch point) it takes the direct count after the special point, if there is
    one, else -1.
    """
    problem, name = branch.problem, branch.parameter
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


def label_stability(branch) -> None:
    """Fill ``index_rule`` and ``index`` on every point of ``branch``.

    The rule starts from the direct count at the first point (the second after a switch). ``index`` is the common value
    where rule and direct count agree; at LP and BP points (critical eigenvalue zero, direct
    count ambiguous) it is the rule's value. Elsewhere a disagreement leaves ``index = -1``
    and says so in the point's note: it is never hidden.
    """
    if not branch.points or not branch.problem.has_second_variation:
        return
    # A branch switched at a branch point starts where the direct count is ambiguous.
    seed = branch.points[1 if branch.singular_start and len(branch.points) > 1 else 0]
    rule = fold_rule(branch, seed.index_direct)
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
