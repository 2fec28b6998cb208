"""The direct count's compiled block work (`elastica_auto.numerics._blocks`) against dense
linear algebra on the same matrices.

`condense` forms the P2 element matrices of a form's fields and eliminates each element's
midpoint; here the whole P2 stiffness matrix is assembled densely from the basis functions
(Simpson's rule written as a sum over the quadrature points, not the element formulas of
stability.py) and its Schur complement onto the nodes taken by a dense solve: the node blocks
must be that complement, and the midpoint pivots' negative eigenvalues those of the dense
midpoint block. `reduce` eliminates the nodes of a block tridiagonal matrix level by level:
its count must be n_- of the eliminated nodes' dense block (Sylvester), and what it leaves the
dense Schur complement onto the nodes left, its constraint columns and C K^-1 C^T likewise.
Blocks of 1 to 6 components: 2 and 3 take the closed forms (adjugate, Descartes' rule), 4 to
6 the Jacobi eigendecomposition.
"""

import numpy as np
import pytest

from elastica_auto.numerics import _blocks
from elastica_auto.numerics.stability import _ULPS

#: Lagrange P2 basis on [0, 1] at Simpson's points x = 0, 1/2, 1: values delta_iq, and the
#: derivatives d phi_i / dx there (rows: phi_0, phi_m, phi_2).
_DPHI = np.array([[-3.0, -1.0, 1.0], [4.0, 0.0, -4.0], [-1.0, 1.0, 3.0]])
_WEIGHTS = np.array([1.0, 4.0, 1.0]) / 6.0


def _random_fields(rng, n, k, negative_b=0.0):
    """A mesh of n nodes (uneven) and fields A (positive definite), B, C on its 2n - 1 nodes
    and midpoints; B shifted down by ``negative_b`` to make midpoint blocks indefinite."""
    s = np.sort(np.concatenate(([0.0, 1.0], rng.uniform(0.0, 1.0, n - 2))))
    m = rng.normal(size=(2 * n - 1, k, k))
    a = m @ m.transpose(0, 2, 1) + 0.5 * np.eye(k)
    b = rng.normal(size=(2 * n - 1, k, k)) * 5.0
    b = 0.5 * (b + b.transpose(0, 2, 1)) - negative_b * np.eye(k)
    c = rng.normal(size=(2 * n - 1, k, k))
    return s, a, b, c


def _dense_p2(s, a, b, c):
    """The P2 stiffness matrix on the points (node 0, midpoint 0, node 1, ...), k unknowns
    each, and the local blocks (0, 0) and (2, 2) of each element: sum over Simpson's points q
    of w_q h (A phi_i' phi_j' + C phi_i' phi_j + C^T phi_i phi_j' + B phi_i phi_j) with
    phi' = dphi/dx / h, phi_i(q) = delta_iq."""
    k, n_el = a.shape[-1], len(s) - 1
    big = np.zeros(((2 * n_el + 1) * k,) * 2)
    local00, local22 = [], []
    for e in range(n_el):
        h = s[e + 1] - s[e]
        ke = np.zeros((3, k, 3, k))
        for q in range(3):
            pt, wq = 2 * e + q, _WEIGHTS[q] * h
            for i in range(3):
                for j in range(3):
                    di, dj = _DPHI[i, q] / h, _DPHI[j, q] / h
                    ke[i, :, j, :] += wq * (a[pt] * di * dj + c[pt] * di * (j == q)
                                            + c[pt].T * (i == q) * dj
                                            + b[pt] * (i == q) * (j == q))
        local00.append(ke[0, :, 0, :])
        local22.append(ke[2, :, 2, :])
        rows = slice(2 * e * k, (2 * e + 3) * k)
        big[rows, rows] += ke.reshape(3 * k, 3 * k)
    return big, np.array(local00), np.array(local22)


def _blocks_of(matrix, nodes, k):
    """The diagonal and upper blocks of the block tridiagonal ``matrix`` on ``nodes``."""
    d = np.array([matrix[i * k:(i + 1) * k, i * k:(i + 1) * k] for i in range(nodes)])
    u = np.array([matrix[i * k:(i + 1) * k, (i + 1) * k:(i + 2) * k] for i in range(nodes - 1)])
    return d, u


def _condense(s, a, b, c):
    n, k = len(s), a.shape[-1]
    d, u = np.empty((n, k, k)), np.empty((n - 1, k, k))
    inv, y = np.empty((n - 1, k, k)), np.empty((n - 1, k, 2 * k))
    negative, scale = _blocks.condense(s, a, b, c, _ULPS, d, u, inv, y)
    return negative, scale, d, u, inv, y


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5, 6])
@pytest.mark.parametrize("n, negative_b", [(2, 0.0), (7, 0.0), (7, 3000.0), (40, 0.0),
                                           (40, 2e5)])
def test_condensed_node_matrix_is_the_dense_schur_complement(k, n, negative_b):
    rng = np.random.default_rng([k, n, int(negative_b)])
    s, a, b, c = _random_fields(rng, n, k, negative_b)
    negative, scale, d, u, inv, y = _condense(s, a, b, c)
    big, k00, k22 = _dense_p2(s, a, b, c)
    node = np.concatenate([np.arange(2 * i * k, (2 * i + 1) * k) for i in range(n)])
    mid = np.setdiff1d(np.arange(len(big)), node)
    kmm = big[np.ix_(mid, mid)]
    schur = big[np.ix_(node, node)] - big[np.ix_(node, mid)] @ np.linalg.solve(
        kmm, big[np.ix_(mid, node)])
    d_ref, u_ref = _blocks_of(schur, n, k)
    tol = 1e-11 * np.abs(big).max() * max(1.0, np.linalg.cond(kmm) * 1e-3)
    np.testing.assert_allclose(d, d_ref, rtol=0, atol=tol)
    np.testing.assert_allclose(u, u_ref, rtol=0, atol=tol)
    w = np.linalg.eigvalsh(kmm)
    assert negative == np.count_nonzero(w < 0)
    if negative_b:
        assert negative > 0                   # the case is not trivially definite
    inv_ref = np.linalg.inv(kmm.reshape(n - 1, k, n - 1, k)[np.arange(n - 1), :,
                                                             np.arange(n - 1), :])
    np.testing.assert_allclose(inv, inv_ref, rtol=0, atol=1e-10 * np.abs(inv_ref).max())
    assert scale / _ULPS == pytest.approx(np.max(np.abs(k00) + np.abs(k22)), rel=1e-12)


def test_condense_reads_fields_of_any_layout():
    """A field as the hooks give it (a transposed view, a constant broadcast along the
    points) gives the same bits as its contiguous copy."""
    rng = np.random.default_rng(3)
    s, a, b, c = _random_fields(rng, 12, 3)
    a_t = np.ascontiguousarray(a.transpose(1, 2, 0)).transpose(2, 0, 1)   # (k, k, P) storage
    b_const = np.broadcast_to(b[:1], b.shape)
    ref = _condense(s, a, np.ascontiguousarray(b_const), c)
    got = _condense(s, a_t, b_const, c)
    for x, y in zip(ref, got):
        np.testing.assert_array_equal(x, y)


def _block_tridiagonal(rng, n, k, shift):
    """A random symmetric block tridiagonal matrix, its blocks, shifted by -shift I."""
    d = rng.normal(size=(n, k, k))
    d = d + d.transpose(0, 2, 1) + (2.0 * k - shift) * np.eye(k)
    u = rng.normal(size=(n - 1, k, k))
    dense = np.zeros((n * k, n * k))
    for i in range(n):
        dense[i * k:(i + 1) * k, i * k:(i + 1) * k] = d[i]
    for i in range(n - 1):
        dense[i * k:(i + 1) * k, (i + 1) * k:(i + 2) * k] = u[i]
        dense[(i + 1) * k:(i + 2) * k, i * k:(i + 1) * k] = u[i].T
    return d, u, dense


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5, 6])
@pytest.mark.parametrize("n, tail, r, shift", [(1, 16, 0, 0.0), (17, 16, 0, 0.0),
                                               (101, 16, 0, 0.0), (101, 16, 2, 3.0),
                                               (200, 1, 1, 4.0), (64, 3, 0, 5.0)])
def test_reduction_counts_and_leaves_the_dense_schur_complement(k, n, tail, r, shift):
    rng = np.random.default_rng([k, n, tail, r])
    d, u, dense = _block_tridiagonal(rng, n, k, shift)
    f = rng.normal(size=(n, k, r))
    fd = f.reshape(n * k, r).copy()                     # reduce works in place
    total, size = np.zeros((r, r)), np.zeros((r, r))
    negative, left = _blocks.reduce(d, u, f, 1e-12, tail, total, size)
    stride, m = 1, n                        # the nodes left: multiples of 2^levels
    while m > tail:
        m, stride = m - m // 2, 2 * stride
    assert left == m
    kept = np.arange(0, n, stride)
    t = np.concatenate([np.arange(i * k, (i + 1) * k) for i in kept])
    e = np.setdiff1d(np.arange(n * k), t)
    if not len(e):                          # nothing to eliminate: left as it was
        assert negative == 0 and left == n
        return
    k_ee = dense[np.ix_(e, e)]
    w = np.linalg.eigvalsh(k_ee)
    assert negative == np.count_nonzero(w < 0)
    if shift:
        assert negative > 0
    sol = np.linalg.solve(k_ee, np.hstack((dense[np.ix_(e, t)], fd[e])))
    schur = dense[np.ix_(t, t)] - dense[np.ix_(t, e)] @ sol[:, :len(t)]
    d_ref, u_ref = _blocks_of(schur, left, k)
    scale = np.abs(dense).max() * np.abs(w).max() / np.abs(w).min()    # |K| cond(K_ee)
    np.testing.assert_allclose(d[:left], d_ref, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(u[:left - 1], u_ref.reshape(left - 1, k, k), rtol=0,
                               atol=1e-13 * scale)
    if r:
        f_ref = fd[t] - dense[np.ix_(t, e)] @ sol[:, len(t):]
        np.testing.assert_allclose(f[:left].reshape(-1, r), f_ref, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(total, fd[e].T @ sol[:, len(t):], rtol=0,
                                   atol=1e-13 * scale)
        assert np.all(size >= np.abs(total))


@pytest.mark.parametrize("k", [1, 2, 3, 4, 6])
def test_a_singular_pivot_is_refused(k):
    """A pivot with an eigenvalue exactly zero (k >= 2: a rank-deficient block) gives -1."""
    rng = np.random.default_rng(k)
    d, u, _ = _block_tridiagonal(rng, 40, k, 0.0)
    v = rng.normal(size=(k, max(k - 1, 1)))
    d[5] = v @ v.T if k > 1 else 0.0                      # node 5: an odd node, first level
    negative, _ = _blocks.reduce(d, u, np.zeros((40, k, 0)), 1e-12, 16, np.zeros((0, 0)),
                                 np.zeros((0, 0)))
    assert negative == -1


def test_the_kernel_refuses_arrays_of_the_wrong_kind():
    d, u = np.zeros((5, 2, 2)), np.zeros((4, 2, 2))
    none = np.zeros((0, 0))
    with pytest.raises(ValueError, match="u"):
        _blocks.reduce(d, np.zeros((5, 2, 2)), np.zeros((5, 2, 0)), 0.0, 16, none, none)
    with pytest.raises(ValueError, match="tail"):
        _blocks.reduce(d, u, np.zeros((5, 2, 0)), 0.0, 0, none, none)
    with pytest.raises(ValueError, match="d"):
        _blocks.reduce(d.astype(np.float32), u, np.zeros((5, 2, 0)), 0.0, 16, none, none)
    s = np.linspace(0, 1, 3)
    a = np.zeros((5, 2, 2))
    with pytest.raises(ValueError, match="b"):
        _blocks.condense(s, a, np.zeros((4, 2, 2)), a, 1e-14, np.empty((3, 2, 2)),
                         np.empty((2, 2, 2)), np.empty((2, 2, 2)), np.empty((2, 2, 4)))


def _tail_like(rng, kind, n):
    """A symmetric test matrix: random; with a zero diagonal (every pivot 2 x 2 at first);
    a planted spectrum over nine decades of both signs; block tridiagonal of 3 x 3 blocks
    scaled over four decades (the shape `_inertia` hands over)."""
    if kind == "random":
        m = rng.standard_normal((n, n))
        return m + m.T
    if kind == "zero diagonal":
        m = rng.standard_normal((n, n))
        m = m + m.T
        np.fill_diagonal(m, 0.0)
        return m
    if kind == "spectrum":
        q, _ = np.linalg.qr(rng.standard_normal((n, n)))
        w = rng.choice([-1.0, 1.0], n) * 10.0 ** rng.uniform(-6, 3, n)
        m = (q * w) @ q.T
        return 0.5 * (m + m.T)
    k, nodes = 3, max(1, n // 3)
    m = np.zeros((k * nodes, k * nodes))
    for i in range(nodes):
        for j in (i, i + 1):
            if j < nodes:
                b = rng.standard_normal((k, k)) * 10.0 ** rng.uniform(-2, 2)
                m[i * k:(i + 1) * k, j * k:(j + 1) * k] = b
                m[j * k:(j + 1) * k, i * k:(i + 1) * k] = b.T
    return 0.5 * (m + m.T)


@pytest.mark.parametrize("kind", ["random", "zero diagonal", "spectrum", "block tridiagonal"])
def test_window_counts_the_eigenvalues_below_and_above_the_threshold(kind):
    # `window`'s two pivoted LDL^T against numpy's eigenvalues: the numbers below tol and
    # below -tol, on 300 matrices of 1 to 60 rows, tol from 1e-8 to 1e-1 of the largest
    # eigenvalue (those with an eigenvalue within 1e-10 of +-tol, too close to call, skipped)
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(300):
        m = _tail_like(rng, kind, int(rng.integers(1, 61)))
        w = np.linalg.eigvalsh(m)
        top = np.abs(w).max()
        tol = 10.0 ** rng.uniform(-8, -1) * top
        if not top or np.min(np.abs(np.abs(w) - tol)) < 1e-10 * top:     # [[0]]: no scale
            continue
        checked += 1
        assert _blocks.window(m, tol) == (np.count_nonzero(w < tol),
                                          np.count_nonzero(w < -tol))
    assert checked > 250


def test_window_sees_a_zero_eigenvalue_and_reads_any_strides():
    # a projector (eigenvalues 0 and 1): one eigenvalue in [-tol, tol); exactly singular
    # with tol = 0 (a zero pivot: -1); a transposed (strided) view reads as the matrix
    rng = np.random.default_rng(5)
    v = rng.standard_normal(10)
    p = np.eye(10) - np.outer(v, v) / (v @ v)
    assert _blocks.window(p, 1e-12) == (1, 0)
    assert _blocks.window(np.zeros((4, 4)), 0.0) == (-1, -1)
    assert _blocks.window(np.diag([1.0, -2.0, 3.0]), 0.1) == (1, 1)
    m = _tail_like(rng, "random", 20)
    assert _blocks.window(np.asfortranarray(m), 1e-9) == _blocks.window(m, 1e-9)
    with pytest.raises(ValueError, match="square"):
        _blocks.window(np.zeros((3, 4)), 0.1)
    for bad in (np.nan, np.inf, -np.inf):       # no pivot decided by a comparison with NaN
        m = np.eye(5)
        m[2, 3] = m[3, 2] = bad
        assert _blocks.window(m, 1e-9) == (-2, -2)
