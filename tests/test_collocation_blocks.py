"""The cubic collocation's Jacobian blocks (`Discretisation.blocks`, assembled by
`elastica_auto.numerics._blocks`' `cubic_gather`, `cubic_blocks`, `cubic_column`).

Two checks. Bit for bit: on random f_y and f_p fields (with exact zeros of both signs, and
strided as an equation module may return them) on an uneven mesh, the blocks and the
parameter column are the numpy formulas written out below, operation for operation, equal
with np.array_equal: the compiled loops only save numpy's passes, they must not change a bit
of any run. Independently: for shipped modules, the blocks are the derivatives of the
collocation residuals `Discretisation.evaluate` computes, by central differences, in the node
values (d0, d1) and in each parameter (dcol).
"""

import math

import numpy as np
import pytest

from elastica_auto.model.problem import load_problem
from elastica_auto.numerics.collocation import Discretisation, Evaluation


def _numpy_blocks(s, jac_raw, fp_raw):
    """The blocks and the parameter column by the numpy formulas, evaluated left to right:
    d0 = ((-I - h/6 J_i) - (2 h/6) J_mid) - h^2/12 J_mid J_i,
    d1 = ((I - h/6 J_{i+1}) - (2 h/6) J_mid) + h^2/12 J_mid J_{i+1},
    dcol = (-h/6 ((f_p,i + f_p,i+1) + 4 f_p,mid)) + h^2/12 J_mid (f_p,i+1 - f_p,i)."""
    m, n = len(s), jac_raw.shape[0]
    h = np.diff(s)
    h6, h12 = (h / 6)[:, None, None], (h * h / 12)[:, None, None]
    eye = np.eye(n)
    jac_all = np.ascontiguousarray(jac_raw.transpose(2, 0, 1))
    jac, jac_mid = jac_all[:m], jac_all[m:]
    prod = jac_mid @ np.concatenate((jac[:-1], jac[1:]), axis=2)
    prod *= h12
    shared = (2 * h6) * jac_mid
    d0 = np.subtract(-eye, h6 * jac[:-1])
    d0 -= shared
    d0 -= prod[:, :, :n]
    d1 = np.subtract(eye, h6 * jac[1:])
    d1 -= shared
    d1 += prod[:, :, n:]
    fp, fp_mid = fp_raw[:, :m], fp_raw[:, m:]
    dfp = (fp[:, 1:] - fp[:, :-1]).T[:, :, None]
    dcol = (-h6[:, 0, 0] * (fp[:, :-1] + fp[:, 1:] + 4 * fp_mid)
            + (h12 * (jac_mid @ dfp))[:, :, 0].T)
    return d0, d1, dcol


class _Fixed:
    """A stand-in module whose f_y and f_p are given fields, whatever the state."""

    def __init__(self, jac, fp):
        self.n, self.jac, self.fp = jac.shape[0], jac, fp

    def rhs_jac(self, s, y, p):
        return self.jac

    def rhs_dp(self, s, y, p, name):
        return self.fp

    def bc_jac(self, ya, yb, p):
        return np.eye(self.n), -np.eye(self.n)

    def bc_dp(self, ya, yb, p, name):
        return np.zeros(self.n)


def _random_field(rng, shape, points_axis):
    """Normal entries scaled over decades, a tenth of them +0.0 and a tenth -0.0, and at a
    fifth of the points (``points_axis``) only zeros of both signs, so that there the
    products vanish and the signs of -I - h/6 J survive to the blocks (-0.0 - 0.0 is -0.0,
    0.0 - (-0.0) is 0.0)."""
    x = rng.normal(size=shape) * 10.0 ** rng.integers(-3, 4, size=shape)
    pick = rng.uniform(size=shape)
    x[pick < 0.1] = 0.0
    x[(pick >= 0.1) & (pick < 0.2)] = -0.0
    points = np.moveaxis(x, points_axis, 0)           # a view: writes reach x
    zero = rng.uniform(size=len(points)) < 0.2
    points[zero] = np.copysign(0.0, points[zero])
    return x


@pytest.mark.parametrize("n", [1, 4, 13])
@pytest.mark.parametrize("layout", ["contiguous", "strided"])
def test_compiled_blocks_are_the_numpy_formulas_bit_for_bit(n, layout):
    rng = np.random.default_rng(n)
    m = 37
    s = np.sort(np.concatenate(([0.0, 1.0], rng.uniform(0.0, 1.0, m - 2)))) ** 2
    big = 2 * m - 1
    if layout == "contiguous":
        jac, fp = _random_field(rng, (n, n, big), 2), _random_field(rng, (n, big), 1)
    else:      # (point, column, row) storage and every other entry of a wider f_p
        jac = _random_field(rng, (big, n, n), 0).transpose(2, 1, 0)
        fp = _random_field(rng, (n, 2 * big), 1)[:, ::2]
    disc = Discretisation(_Fixed(jac, fp), s)
    y = np.zeros((n, m))
    ev = Evaluation(y, y, y[:, 1:], y[:, 1:], y[:, 1:], np.zeros(n))
    got = disc.blocks(ev, {}, ("a", "b"))
    d0, d1, dcol = _numpy_blocks(s, jac, fp)
    assert np.array_equal(got.d0, d0) and np.array_equal(got.d1, d1)
    # the signs of the zeros too (array_equal takes -0.0 == 0.0)
    assert np.array_equal(np.signbit(got.d0), np.signbit(d0))
    assert np.array_equal(np.signbit(got.d1), np.signbit(d1))
    for name in ("a", "b"):
        assert np.array_equal(got.dcol[name], dcol)
        assert np.array_equal(np.signbit(got.dcol[name]), np.signbit(dcol))
        assert np.array_equal(got.fp[name], fp[:, :m])
    assert np.array_equal(got.jac, jac.transpose(2, 0, 1)[:m])


def _state(name, rng):
    """A shipped module, an uneven mesh of 17 nodes, a generic state near its exact start
    (randomly displaced, so that no block is special) and its parameters."""
    problem = load_problem(name)
    params = {**problem.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    s = np.linspace(0.0, 1.0, 17) ** 1.3
    y = problem.exact_start(s, params) + 0.05 * rng.normal(size=(problem.n, len(s)))
    return problem, Discretisation(problem, s), y, params


@pytest.mark.parametrize("name", ["elastica_lever_arm", "cosserat_rod"])
def test_blocks_are_the_derivatives_of_the_residuals(name):
    rng = np.random.default_rng(3)
    problem, disc, y, params = _state(name, rng)
    n, m = problem.n, len(disc.s)
    blocks = disc.blocks(disc.evaluate(y, params), params, tuple(params))
    delta = 1e-6

    def col(yy, pp=params):
        return disc.evaluate(yy, pp).col

    # C_i depends on y_i and y_{i+1} only: moving component a of every other node at once,
    # C_i sees one of them, y_i (d0) if i has the moved parity, y_{i+1} (d1) otherwise
    fd0, fd1 = np.zeros_like(blocks.d0), np.zeros_like(blocks.d1)
    for a in range(n):
        for parity in (0, 1):
            step = np.zeros_like(y)
            step[a, parity::2] = delta
            diff = (col(y + step) - col(y - step)) / (2 * delta)
            for i in range(m - 1):
                (fd0 if i % 2 == parity else fd1)[i, :, a] = diff[:, i]
    eye = np.eye(n)
    # compared without the identity, so that the h-sized terms carry the comparison
    for got, fd in ((blocks.d0 + eye, fd0 + eye), (blocks.d1 - eye, fd1 - eye)):
        assert np.max(np.abs(got - fd)) <= 1e-6 * np.max(np.abs(fd))
    moved = 0
    for key, value in params.items():
        # a step relative to the parameter's size (the shear stiffness S is 1000)
        step = 1e-5 * max(1.0, abs(value))
        up, down = {**params, key: value + step}, {**params, key: value - step}
        fd = (col(y, up) - col(y, down)) / (2 * step)
        assert np.max(np.abs(blocks.dcol[key] - fd)) <= 1e-6 * np.max(np.abs(fd))
        moved += np.max(np.abs(fd)) > 0
    assert moved >= 1


def test_the_compiled_assembly_refuses_arrays_of_the_wrong_shape_or_type():
    from elastica_auto.numerics import _blocks

    n, m = 3, 5
    jac = np.zeros((n, n, 2 * m - 1))
    with pytest.raises(ValueError):         # an even number of points: not 2m - 1
        _blocks.cubic_gather(np.zeros((n, n, 8)), np.empty((8, n, n)), np.empty((3, n, 2 * n)))
    with pytest.raises(ValueError):         # cat one interval short
        _blocks.cubic_gather(jac, np.empty((2 * m - 1, n, n)), np.empty((m - 2, n, 2 * n)))
    with pytest.raises(ValueError):         # a float32 output
        _blocks.cubic_blocks(np.zeros((2 * m - 1, n, n)), np.zeros((m - 1, n, 2 * n)),
                             np.ones(m - 1), np.ones(m - 1),
                             np.empty((m - 1, n, n), dtype=np.float32), np.empty((m - 1, n, n)))
    with pytest.raises(ValueError):         # a non-contiguous output
        _blocks.cubic_column(np.zeros((n, 2 * m - 1)), np.zeros((m - 1, n, 1)), np.ones(m - 1),
                             np.ones(m - 1), np.empty((m - 1, n)).T)
