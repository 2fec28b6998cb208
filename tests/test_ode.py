"""The vectorised DOP853 integrator of the shooting scans (elastica_auto.numerics.ode).

Independent references: the matrix exponential for y' = M y; the energy of the pendulum,
conserved; the step counts an 8th-order method takes; scipy's solve_ivp (DOP853 at
rtol = atol = 1e-12, one column at a time: tests/shooting.py) on the elastica's shooting.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

import shooting
from elastica_auto.numerics.ode import IntegrationError, dop853


def test_linear_system_matches_the_matrix_exponential():
    """y' = M y: y(s) = expm(M s) y0, for a rotation with growth and decay (eigenvalues
    -1 +- 6i, 0.5 +- 2i) and 50 initial values at once, at s = 1 and between steps."""
    rot = lambda w, g: np.array([[g, -w], [w, g]])  # noqa: E731
    m = np.zeros((4, 4))
    m[:2, :2], m[2:, 2:], m[0, 2] = rot(6.0, -1.0), rot(2.0, 0.5), 1.0
    y0 = np.random.default_rng(1).normal(size=(4, 50))
    s = np.linspace(0.0, 1.0, 11)
    got = dop853(lambda t, y: m @ y, y0, rtol=1e-11, atol=1e-11, s_eval=s)
    for j, t in enumerate(s):
        want = expm(m * t) @ y0
        assert np.max(np.abs(got[:, :, j] - want)) < 2e-10 * (1 + np.max(np.abs(want)))


@pytest.mark.parametrize("columns", [31, 3001])
def test_pendulum_conserves_its_energy(columns):
    """theta'' = -sin theta over 10 time units, from rest at amplitudes up to 3.1 (next to
    the separatrix, period about 17): E = omega^2 / 2 - cos theta stays within 1e-10. With
    3001 columns (6002 numbers a stage) the stages' sums are made in blocks of columns
    (`numerics.ode.SINGLE_THREAD_GEMV`), every block's columns checked."""
    amp = np.linspace(0.1, 3.1, columns)
    y0 = np.vstack((amp, np.zeros_like(amp)))
    f = lambda t, y: np.vstack((y[1], -np.sin(y[0])))  # noqa: E731
    y1 = dop853(f, y0, 0.0, 10.0, rtol=1e-12, atol=1e-12)
    energy = lambda y: y[1] ** 2 / 2 - np.cos(y[0])  # noqa: E731
    assert np.max(np.abs(energy(y1) - energy(y0))) < 1e-10


def test_elastica_shooting_matches_solve_ivp():
    """The elastica's shooting from k = theta'(0) across P = 9 pi^2/4's first-integral bound,
    all columns together, against solve_ivp on each column alone."""
    P, alpha = 9 * math.pi ** 2 / 4, 0.3
    ks = np.linspace(-16.0, 16.0, 9)
    y0 = np.vstack((np.full_like(ks, 0.2), ks, np.zeros_like(ks), np.zeros_like(ks)))
    got = dop853(lambda t, y: np.vstack((y[1], -P * np.sin(y[0] - alpha), -np.sin(y[0]),
                                         np.cos(y[0]))), y0, rtol=1e-11, atol=1e-11)
    for j in range(len(ks)):
        want = shooting.profile(P, alpha, y0[:, j], np.array([0.0, 1.0]))[:, -1]
        assert np.max(np.abs(got[:, j] - want)) < 1e-9 * (1 + np.max(np.abs(want)))
    # alone from k next to zero (a grid's k = 0 after rounding): the straight rod; the first
    # step once was of the order of rounding, and refused
    f = lambda t, y: np.vstack((y[1], -P * np.sin(y[0]), -np.sin(y[0]), np.cos(y[0])))  # noqa: E731
    got = dop853(f, np.array([[0.0], [1.8e-15], [0.0], [0.0]]), rtol=1e-11, atol=1e-11)
    assert np.max(np.abs(got[:, 0] - [0.0, 0.0, 0.0, 1.0])) < 1e-10


def test_a_blow_up_is_refused():
    """y' = y^2 from y(0) = 1 is 1 / (1 - s): no solution reaches s = 2."""
    with pytest.raises(IntegrationError):
        dop853(lambda t, y: y * y, np.ones((1, 3)), 0.0, 2.0)
    # up to s = 0.9 it is 10, to the tolerance
    y = dop853(lambda t, y: y * y, np.ones((1, 3)), 0.0, 0.9, rtol=1e-10, atol=1e-10)
    assert np.max(np.abs(y - 10.0)) < 1e-8


def test_steps_shrink_as_an_eighth_order_method_does():
    """The local error of order 8 is h^9: a tolerance a million times smaller takes about
    10^(6/9) to 10^(6/8) = 4.6 to 5.6 times as many steps (calls of f), not the 16 or more
    of a method of order 4 or less (a wrong coefficient; its error estimate then keeps the
    answer right, at that cost)."""
    amp = np.linspace(0.1, 3.0, 30)
    y0 = np.vstack((amp, np.zeros_like(amp)))
    calls = []

    def f(t, y):
        calls.append(1)
        return np.vstack((y[1], -np.sin(y[0])))

    counts = []
    for tol in (1e-6, 1e-12):
        calls.clear()
        dop853(f, y0, 0.0, 10.0, rtol=tol, atol=tol)
        counts.append(len(calls))
    assert 3.5 < counts[1] / counts[0] < 7.0


def test_the_stage_sums_in_blocks_are_the_whole_product():
    """`combine` (the stages' weighted sums, in blocks of columns BLAS multiplies on one
    thread) against numpy's product of the whole, over sizes below, at and across the
    block's width, the last block short."""
    from elastica_auto.numerics.ode import SINGLE_THREAD_GEMV, combine
    rng = np.random.default_rng(7)
    for j in (1, 5, 11, 12):
        cols = SINGLE_THREAD_GEMV // j
        for n in (1, cols, cols + 1, 3 * cols - 7):
            w, flat = rng.standard_normal(j), rng.standard_normal((j, n))
            want = w @ flat
            assert np.max(np.abs(combine(w, flat) - want)) <= 1e-14 * np.max(np.abs(flat))
