"""Newton's Legendre inverse (`elastica_auto.energy.runtime.legendre_inverse`; docs/energy.md,
"A density not quadratic in the strains") against what is independent of it:

* a quadratic density's closed form v = A^-1 (m - b), started at 0 and started far out;
* the tendon robot's generated Legendre map at random frames and states: the momenta made
  from random velocities v* by the forward map m = dL/dv (v*), which the inverse must give
  back (phi = L - m.v is strictly convex, so v* is its only minimiser), including velocities
  where a tendon's length |t_i| is 1e-3 (near its kink); and, for momenta that are not made
  from a known v, scipy's minimiser of the same phi, a second method;
* the stopping tests: dL/dv with a rounding floor above RESIDUAL (1 + |m|) converges (it was
  NaN), a minimiser at a kink stays NaN, and a result never depends on the points solved
  alongside (each column alone gives the same bits);
* the tendon robot's state where the pitchfork curve of tendon_lift's BP1 ended MX at
  tau4 = 82.43 (a Newton stall at rounding level, docs/soft-robots.md): now solved, and to
  the scipy minimiser's value.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize, root

import elastica_auto as ea
from elastica_auto.energy import runtime
from elastica_auto.energy.loader import execute


@pytest.fixture(scope="module")
def tendon():
    """The tendon robot's generated module (its ``_derived_legendre`` and velocities)."""
    problem = ea.load_problem("tendon_robot")
    return problem, execute(problem.generated, "tendon_robot")


def _frames(rng, n):
    q = rng.normal(size=(4, n))
    return runtime.frame(q / np.linalg.norm(q, axis=0))


def _params(problem, **kw):
    p = dict(problem.defaults())
    p.update(kw)
    return p


@pytest.mark.parametrize("far", [False, True])
def test_a_quadratic_density_gives_the_closed_form(far):
    rng = np.random.default_rng(1)
    k, n = 3, 40
    a = rng.normal(size=(k, k))
    A = a @ a.T + k * np.eye(k)
    b = rng.normal(size=k)

    def legendre(s, z, v, p):
        L = 0.5 * np.einsum("im,ij,jm->m", v, A, v) + b @ v
        return L, A @ v + b[:, None], np.broadcast_to(A[:, :, None], (k, k, v.shape[1]))

    m = rng.normal(size=(k, n)) * 10
    v = runtime.legendre_inverse(legendre, np.linspace(0, 1, n), np.zeros((1, n)), m, {},
                                 far=far)
    assert np.max(np.abs(v - np.linalg.solve(A, m - b[:, None]))) < 1e-12


def _tendon_case(problem, rng, n, near_kink=0.0):
    """Random frames, states and velocities v* of the tendon robot (tensions up to 150);
    near_kink > 0: tendon 1's length |t_1| set to it."""
    p = _params(problem, tau1=rng.uniform(0, 150), tau2=rng.uniform(0, 150),
                tau3=rng.uniform(0, 150), tau4=rng.uniform(0, 150), g=1.0)
    R = _frames(rng, n)
    z = rng.normal(size=(3, n))
    w = np.vstack((rng.normal(0, 0.2, (2, n)), rng.uniform(0.5, 1.2, (1, n))))   # R^T r'
    u = rng.normal(0, 3, (3, n))
    d1 = p["delta"] * np.array([1.0, 0.0, 0.0])
    if near_kink:          # t_1 = w + u x d_1 = near_kink e3: u2 = (w3 - near_kink) / delta
        u[1] = (w[2] - near_kink) / p["delta"]
        u[2] = -w[1] / p["delta"]
        w[0] = 0.0
        t1 = w + np.cross(u.T, d1).T
        assert np.allclose(np.linalg.norm(t1, axis=0), near_kink)
    v = np.vstack((np.einsum("ijm,jm->im", R, w), u))          # (x', y', z', u)
    return p, R, z, v


@pytest.mark.parametrize("near_kink", [0.0, 0.1, 1e-3])
def test_the_tendon_inverse_gives_back_the_velocities(tendon, near_kink):
    """Every point's velocities to 1e-11; at |t_1| = 1e-3 (tension up to 150 over a length
    of 1e-3: d2L/dv2 up to 1.5e5) Newton from far out ends at the kink at most points (NaN,
    as at the commit before: a known limit, docs/energy.md), and the others are right."""
    problem, mod = tendon
    rng = np.random.default_rng(0)
    n = 60
    p, R, z, vstar = _tendon_case(problem, rng, n, near_kink)
    s = rng.uniform(0, 1, n)
    _, m, _ = mod._derived_legendre(s, z, vstar, [R], p)
    v = runtime.legendre_inverse(lambda s_, z_, v_, p_: mod._derived_legendre(s_, z_, v_, [R],
                                                                              p_),
                                 s, z, m, p, far=True)
    found = np.all(np.isfinite(v), axis=0)
    assert np.all(found) if near_kink != 1e-3 else np.any(found)
    assert np.max(np.abs(v - vstar)[:, found]) < 1e-11


def _phi_minimiser(mod, s, z, m, R, p, v0):
    """scipy's minimiser of phi(v) = L - m.v at one point: BFGS on phi with its exact
    gradient (a minimiser, not just a stationary point), then Powell's hybrid method on the
    stationarity dL/dv = m (MINPACK's hybrj, with the exact Hessian) to rounding level: the
    second method."""
    def parts(v):
        L, Lv, Lvv = mod._derived_legendre(s, z, v[:, None], [R], p)
        return L[0] - m[:, 0] @ v, Lv[:, 0] - m[:, 0], Lvv[:, :, 0]

    x = minimize(lambda v: parts(v)[0], v0, jac=lambda v: parts(v)[1], method="BFGS",
                 options={"gtol": 1e-9}).x
    out = root(lambda v: parts(v)[1:], x, jac=True, method="hybr", options={"xtol": 1e-15})
    assert np.max(np.abs(out.fun)) < 1e-10 * (1 + np.max(np.abs(m)))
    return out.x


def test_the_tendon_inverse_is_scipy_s_minimiser(tendon):
    problem, mod = tendon
    rng = np.random.default_rng(3)
    n = 6
    p, R, z, vstar = _tendon_case(problem, rng, n)
    s = rng.uniform(0, 1, n)
    _, m, _ = mod._derived_legendre(s, z, vstar, [R], p)
    m = m + rng.normal(0, 0.5, m.shape)                  # momenta of no known velocity
    v = runtime.legendre_inverse(lambda s_, z_, v_, p_: mod._derived_legendre(s_, z_, v_, [R],
                                                                              p_),
                                 s, z, m, p, far=True)
    for j in range(n):
        ref = _phi_minimiser(mod, s[j:j + 1], z[:, j:j + 1], m[:, j:j + 1], R[:, :, j:j + 1], p,
                             vstar[:, j])
        assert np.max(np.abs(v[:, j] - ref)) < 1e-10, j


def test_each_point_is_solved_as_alone(tendon):
    problem, mod = tendon
    rng = np.random.default_rng(11)
    n = 30
    p, R, z, vstar = _tendon_case(problem, rng, n)
    s = rng.uniform(0, 1, n)
    _, m, _ = mod._derived_legendre(s, z, vstar, [R], p)

    def solve(idx):
        Ri = R[:, :, idx]
        return runtime.legendre_inverse(
            lambda s_, z_, v_, p_: mod._derived_legendre(s_, z_, v_, [Ri], p_),
            s[idx], z[:, idx], m[:, idx], p, far=True)

    together = solve(np.arange(n))
    for j in range(n):
        assert np.array_equal(solve(np.array([j]))[:, 0], together[:, j]), j


def test_a_rounding_floor_above_the_tolerance_converges():
    """dL/dv = a (v - c) + e(v), e = 5e-14 sign(v - c) a floor of the residual's size that
    no v gets under (as rounding's of large terms): Newton's iterates alternate about c,
    c -+ 5e-14, their steps 1e-13 not shrinking (the quadratic-rate stop never fires).
    It converges to within the floor (it was NaN after 50 iterations)."""
    a, c = 1.0, 0.7

    def legendre(s, z, v, p):
        noise = 5e-14 * np.where(v[0] >= c, 1.0, -1.0)
        return 0.5 * a * (v[0] - c) ** 2, (a * (v[0] - c) + noise)[None], \
            np.full((1, 1, v.shape[1]), a)

    v = runtime.legendre_inverse(legendre, np.zeros(1), np.zeros((1, 1)), np.zeros((1, 1)), {})
    assert abs(v[0, 0] - c) < 1e-12


def test_a_minimiser_at_a_kink_is_nan():
    """L = (v - c)^2 / 2 + tau |v| with |c| < tau: the minimiser is the kink v = 0, where
    dL/dv = m has no solution (the residual stays c - tau sign(v)): NaN, not a value."""
    c, tau = 0.3, 1.0

    def legendre(s, z, v, p):
        x = v[0]
        with np.errstate(all="ignore"):
            return (0.5 * (x - c) ** 2 + tau * np.abs(x), (x - c + tau * np.sign(x))[None],
                    (1 + 0 * x)[None, None])

    v = runtime.legendre_inverse(legendre, np.zeros(1), np.zeros((1, 1)), np.zeros((1, 1)), {})
    assert np.isnan(v[0, 0])


def test_a_state_of_the_stall_is_solved(tendon):
    """The first point where BASE's inverse returned NaN along tendon_stability continued to
    tau4 = 100 (a corrector's iterate at tau4 = 51.59, tests/test_legendre_inverse_stall.npz;
    the same stall ended the curve at 82.43): its residual stalled at 6.4e-14 against a
    tolerance of 6.0e-14, the steps at 2.2e-15 against 2.0e-15. Solved, to scipy's
    minimiser."""
    problem, mod = tendon
    data = np.load(__file__.replace(".py", "_stall.npz"))
    p = dict(zip((str(k) for k in data["names"]), (float(x) for x in data["values"])))
    s, z, m, R = data["s"], data["z"], data["m"], data["R"]
    assert math.isclose(p["tau4"], 51.5942, abs_tol=1e-3)
    v = runtime.legendre_inverse(lambda s_, z_, v_, p_: mod._derived_legendre(s_, z_, v_, [R],
                                                                              p_),
                                 s, z, m, p, far=True)
    assert np.all(np.isfinite(v))
    ref = _phi_minimiser(mod, s, z, m, R, p, np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]))
    assert np.max(np.abs(v[:, 0] - ref)) < 1e-9


def test_the_velocity_is_remembered_by_its_arguments_bytes():
    """runtime.remembered: the same (s, y, p) solves once, and its result is read-only; a
    change of any bit of s, y or of a parameter solves again (a pure function: the order
    of the work cannot change a result)."""
    calls = []

    def solve(s, y, p):
        calls.append(1)
        return y * p["a"] + s

    s, y = np.linspace(0, 1, 5), np.arange(10.0).reshape(2, 5)
    first = runtime.remembered(solve, s, y, {"a": 2.0})
    again = runtime.remembered(solve, s.copy(), y.copy(), {"a": 2.0})
    assert len(calls) == 1 and np.array_equal(first, again) and not again.flags.writeable
    y2 = y.copy()
    y2[1, 3] = np.nextafter(y2[1, 3], 10)
    for args in ((s, y2, {"a": 2.0}), (s, y, {"a": np.nextafter(2.0, 3)}),
                 (s + 1e-300, y, {"a": 2.0}), (s, y, {"a": 2.0, "b": 0.0})):
        assert np.array_equal(runtime.remembered(solve, *args), solve(*args))
    assert len(calls) == 1 + 2 * 4
