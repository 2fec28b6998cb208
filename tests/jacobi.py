"""Reference stability counts for the tests, independent of the engine's count: the Jacobi
field integrated by RK4 and piecewise-linear finite elements, both on a fine uniform grid.

For ``delta^2 E[h] = int_0^1 (a h'^2 + b h^2) ds + c h(1)^2``, ``h(0) = 0``, ``a > 0``:

* :func:`index_jacobi` -- the Jacobi field ``(a u')' = b u``, ``u(0) = 0``, ``a u'(0) = 1``.
  By Sturm's comparison (Pruefer angle) the index is the number of zeros of u in (0, 1) plus
  one if ``u(1) (a u'(1) + c u(1)) < 0``; a zero at s = 1 counts as one.
* :func:`index_fem` -- P1 finite elements for the quadratic form; the index is the number of
  negative pivots of its LDL^T factorisation (Sylvester's law of inertia).
"""

from __future__ import annotations

import numpy as np

#: Elements of the finite-element count and steps of the Jacobi-field integration.
N_ELEMENTS = 800


def scalar_form(form):
    """(a, b, c) of a module's scalar form: the tuple of the first protocol, or a
    `SecondVariation` with k = 1, h(0) = 0 and no C, E0 or constraints (a derived module's)."""
    if isinstance(form, tuple):
        return form[:3]
    assert form.k == 1 and not form.constraints and not np.any(form.C) \
        and not np.any(form.E0) and form.fixed0.shape[1] == 1
    a, b = form.A[:, 0, 0], form.B[:, 0, 0]
    return (a[0] if len(a) == 1 else a), (b[0] if len(b) == 1 else b), float(form.E1[0, 0])


def _coefficients(problem, state, n=N_ELEMENTS):
    """a, b on the grid s_j = j / (2 n) (nodes and midpoints of n elements), and c."""
    s = np.linspace(0.0, 1.0, 2 * n + 1)
    a, b, c = scalar_form(problem.second_variation(s, state(s), state.params))
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
    """(Jacobi-field index, finite-element index) of a solution."""
    a, b, c = _coefficients(problem, state)
    return index_jacobi(a, b, c), index_fem(a, b, c)


