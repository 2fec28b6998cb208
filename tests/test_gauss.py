"""Gauss collocation (``ncol`` = 2..7) against independent results.

* the collocation coefficients are those of Gauss-Legendre quadrature (its order conditions);
* the condensed Jacobian is the derivative of the node equations (finite differences, the
  stage equations solved for each perturbed set of node values);
* convergence on Bratu's closed-form solution: node values like h^(2 ncol)
  (superconvergence), stage values (the collocation polynomial inside the intervals) like
  h^(ncol + 1);
* the Bratu fold against its closed form, the rotating-arm folds against the independent
  shooting solve, and the rotating disk against the literature values and scipy's solve_bvp.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import shooting
from elastica_auto.numerics import bordered
from elastica_auto.execution import runfile
from elastica_auto.numerics.gauss import GaussDiscretisation, tableau
from elastica_auto.numerics.newton import Row, newton
from elastica_auto.core.options import ContinuationOptions, OptionsError
from elastica_auto.model.problem import load_problem
from helpers import EXAMPLES, ROTATING_ARM, central_jacobian, run_plan


@pytest.mark.parametrize("k", range(2, 8))
def test_the_coefficients_are_gauss_legendre(k):
    tau, A, b, _, _ = tableau(k)
    x, w = np.polynomial.legendre.leggauss(k)
    np.testing.assert_allclose(tau, (x + 1) / 2, atol=1e-15)
    np.testing.assert_allclose(b, w / 2, atol=1e-13)
    # B(2k): the quadrature is exact for degree 2k - 1; C(k): a_jl integrate degree k - 1
    for q in range(1, 2 * k + 1):
        assert abs(b @ tau ** (q - 1) - 1 / q) < 1e-13
    for q in range(1, k + 1):
        np.testing.assert_allclose(A @ tau ** (q - 1), tau ** q / q, atol=1e-13)


def _elastica_state(problem, m, rng):
    s = np.sort(np.concatenate(([0.0, 1.0], rng.uniform(0, 1, m - 2))))
    y = np.vstack((np.sin(3 * s) + 0.2, 2 * np.cos(2 * s), s * s, -s))
    p = {**problem.defaults(), "P": 7.3, "eps": 0.4, "psi": 0.9, "alpha": 0.3}
    return s, y, p


@pytest.mark.parametrize("k", (2, 4, 7))
def test_the_condensed_jacobian_is_the_derivative_of_the_node_equations(elastica, k):
    rng = np.random.default_rng(k)
    s, y, p = _elastica_state(elastica, 11, rng)
    disc = GaussDiscretisation(elastica, s, k)
    ev = disc.evaluate(y, p)
    assert np.max(np.abs(ev.stage)) < 1e-13          # the stages were solved for y
    blocks = disc.blocks(ev, p, ("P", "psi"))
    v = rng.standard_normal(y.shape)
    h = 1e-6
    plus, minus = disc.evaluate(y + h * v, p), disc.evaluate(y - h * v, p)
    col, bc = blocks.times(v)
    np.testing.assert_allclose(col, (plus.col - minus.col) / (2 * h), rtol=0, atol=1e-8)
    np.testing.assert_allclose(bc, (plus.bc - minus.bc) / (2 * h), rtol=0, atol=1e-8)
    for name in ("P", "psi"):
        up, down = ({**p, name: p[name] + d} for d in (h, -h))
        diff = (disc.evaluate(y, up).col - disc.evaluate(y, down).col) / (2 * h)
        np.testing.assert_allclose(blocks.dcol[name], diff, rtol=0, atol=1e-8)


def _bratu_errors(bratu, k, intervals, z=1.5):
    """Largest errors of the node values and of the stage values of the collocation solution
    at lam = 2 z^2 / cosh(z/2)^2, against u = -2 ln(cosh(z (x - 1/2)) / cosh(z/2))."""
    lam = 2 * z * z / math.cosh(z / 2) ** 2

    def exact(x):
        return np.vstack((-2 * np.log(np.cosh(z * (x - 0.5)) / math.cosh(z / 2)),
                          -2 * z * np.tanh(z * (x - 0.5))))

    p = {"lam": lam}
    ga, gb = bratu.bc_jac(np.zeros(2), np.zeros(2), p)
    split = bordered.split_rows(ga, gb)
    out = []
    for m in intervals:
        s = np.linspace(0.0, 1.0, m + 1)
        disc = GaussDiscretisation(bratu, s, k)
        guess = exact(s) + 0.01 * np.sin(np.pi * s)
        res = newton(disc, "lam", p, guess, lam, Row.value(disc, lam), None, split, tol=1e-14)
        assert res.converged
        node = np.max(np.abs(res.Y - exact(s)))
        stages = np.max(np.abs(res.interior.reshape(2, -1) - exact(disc.s_stage)))
        out.append((node, stages))
    return np.array(out)


@pytest.mark.parametrize("k, intervals", [(2, (8, 16, 32)), (3, (4, 8, 16)), (4, (3, 6, 12))])
def test_node_values_converge_like_h_to_the_2k(k, intervals):
    bratu = load_problem(str(EXAMPLES / "bratu.py"))
    err = _bratu_errors(bratu, k, intervals)[:, 0]
    rates = np.log2(err[:-1] / err[1:])
    assert np.all(np.abs(rates - 2 * k) < 0.3), rates


@pytest.mark.parametrize("k", range(2, 6))
def test_stage_values_converge_like_h_to_the_k_plus_1(k):
    bratu = load_problem(str(EXAMPLES / "bratu.py"))
    err = _bratu_errors(bratu, k, (8, 16, 32))[:, 1]
    rates = np.log2(err[:-1] / err[1:])
    assert np.all(np.abs(rates - (k + 1)) < 0.3), rates


def test_ncol_is_validated():
    for bad in (1, 8, -2, 2.5):
        with pytest.raises(OptionsError, match="ncol"):
            ContinuationOptions(ncol=bad)
    assert ContinuationOptions(ncol=7).ncol == 7


@pytest.mark.parametrize("k", (2, 4, 7))
def test_the_bratu_fold_with_gauss_collocation(tmp_path, k):
    from scipy.optimize import brentq
    z_c = brentq(lambda z: z * math.tanh(z / 2) - 2, 1.0, 4.0, xtol=1e-15)
    plan = runfile.load(EXAMPLES / "bratu.toml")
    plan = dataclasses.replace(plan, options=dataclasses.replace(plan.options, ncol=k))
    (br,) = run_plan(plan, tmp_path).result.branches
    (lp,) = br.folds
    assert abs(lp.params["lam"] - 2 * z_c ** 2 / math.cosh(z_c / 2) ** 2) <= 1e-9


def test_rotating_arm_folds_with_gauss_collocation_match_shooting(tmp_path):
    plan = runfile.load(ROTATING_ARM)
    # the load pi^2/4 (both arm lengths, both directions): 20 folds
    plan.branches = [b for b in plan.branches if abs(b.params["P"] - math.pi ** 2 / 4) < 1e-12]
    plan.user_values = []
    plan = dataclasses.replace(plan, options=dataclasses.replace(plan.options, ncol=4))
    branches = run_plan(plan, tmp_path).result.branches
    assert [len(b.folds) for b in branches] == [5, 5, 5, 5]
    for br in branches:
        for p in br.folds:
            _, psi, _ = shooting.fold(p.params["P"], p.params["eps"], p.ordinates["m0"],
                                      p.params["psi"])
            assert abs(psi - p.params["psi"]) <= 1e-9


# ---- the rotating disk --------------------------------------------------------------------

#: Cochran's values (Rogers and Lance 1960) for the impermeable disk, to their 6 digits.
KARMAN = {"dF0": 0.510233, "dG0": -0.615922, "inflow": 0.884474}


def _karman_bvp(a, z_inf):
    """The disk with suction a on [0, z_inf] by scipy's solve_bvp in z (the inflow an unknown
    parameter), independently of the module: (F'(0), G'(0), inflow)."""
    from scipy.integrate import solve_bvp

    def fun(z, y, q):
        F, dF, G, dG, H = y
        return np.vstack((dF, F * F - G * G + H * dF, dG, 2 * F * G + H * dG, -2 * F))

    def bc(ya, yb, q):
        return np.array((ya[0], ya[2] - 1, ya[4] + a, yb[0], yb[2], yb[4] + q[0]))

    z = np.linspace(0, z_inf, 400)
    e = np.exp(-(1 + a) * z)
    y0 = np.vstack((0.3 * z * e, 0.3 * e, e, -(1 + a) * e, -a - 0.9 * (1 - e)))
    sol = solve_bvp(fun, bc, z, y0, p=[a + 0.9], tol=1e-10, max_nodes=100000)
    assert sol.success, sol.message
    return sol.y[1, 0], sol.y[3, 0], sol.p[0]


@pytest.mark.parametrize("ncol", (0, 4))
def test_the_rotating_disk(tmp_path, ncol):
    plan = runfile.load(EXAMPLES / "karman_disk.toml")
    plan = dataclasses.replace(plan, options=dataclasses.replace(plan.options, ncol=ncol))
    (br,) = run_plan(plan, tmp_path).result.branches
    first = br.points[0]
    assert abs(first.params["a"]) < 1e-12
    got = {"dF0": first.ordinates["dF0"], "dG0": first.ordinates["dG0"],
           "inflow": first.params["inflow"]}
    for key, value in KARMAN.items():
        assert abs(got[key] - value) <= 1e-6, (key, got[key])
    z_inf = first.params["z_inf"]
    for q in (q for q in br.points if q.type == "UZ"):
        dF0, dG0, inflow = _karman_bvp(q.params["a"], z_inf)
        assert abs(q.ordinates["dF0"] - dF0) <= 1e-7
        assert abs(q.ordinates["dG0"] - dG0) <= 1e-7
        assert abs(q.params["inflow"] - inflow) <= 1e-7


@pytest.mark.parametrize("k", (2, 3, 4))
def test_the_error_estimate_is_the_error_between_the_nodes(k):
    """On Bratu's closed-form solution the estimate of each interval is within a factor 2 of
    the actual largest relative error of the collocation polynomial there (evaluated from
    its stage slopes on a fine grid of the interval)."""
    bratu = load_problem(str(EXAMPLES / "bratu.py"))
    z = 1.5
    lam = 2 * z * z / math.cosh(z / 2) ** 2
    p = {"lam": lam}

    def exact(x):
        return np.vstack((-2 * np.log(np.cosh(z * (x - 0.5)) / math.cosh(z / 2)),
                          -2 * z * np.tanh(z * (x - 0.5))))

    s = np.linspace(0.0, 1.0, 17)
    disc = GaussDiscretisation(bratu, s, k)
    ga, gb = bratu.bc_jac(np.zeros(2), np.zeros(2), p)
    res = newton(disc, "lam", p, exact(s), lam, Row.value(disc, lam), None,
                 bordered.split_rows(ga, gb), tol=1e-14)
    ev = disc.evaluate(res.Y, p, res.interior)
    estimate = disc.rms_residuals(res.Y, None, p, ev)
    # u(s_i + t h) = y_i + h sum_l F_l int_0^t l_l, the Lagrange basis l_l on the tau's
    t = np.linspace(0.0, 1.0, 201)
    basis = np.array([np.polynomial.Polynomial.fit(disc.tau, np.eye(k)[j], k - 1).integ()
                      for j in range(k)])
    alpha = np.array([b(t) - b(0.0) for b in basis])                  # (k, len(t))
    h = np.diff(s)
    actual = []
    for i in range(len(h)):
        u = res.Y[:, i, None] + h[i] * ev.F[:, :, i] @ alpha
        ref = exact(s[i] + t * h[i])
        scale = 1 + np.maximum(np.abs(res.Y[:, i]), np.abs(res.Y[:, i + 1]))
        actual.append(np.max(np.sqrt(np.sum(((u - ref) / scale[:, None]) ** 2, axis=0))))
    ratio = estimate / np.array(actual)
    assert np.all((ratio > 0.5) & (ratio < 2)), ratio


def test_ncol_in_a_run_file(tmp_path):
    text = (EXAMPLES / "bratu.toml").read_text()
    (tmp_path / "bratu.py").write_text((EXAMPLES / "bratu.py").read_text())
    good = tmp_path / "good.toml"
    good.write_text(text.replace("[options]\n", "[options]\nncol = 3\n"))
    assert runfile.load(good).options.ncol == 3
    for bad in ("8", "3.0"):
        path = tmp_path / "bad.toml"
        path.write_text(text.replace("[options]\n", f"[options]\nncol = {bad}\n"))
        with pytest.raises(Exception, match="ncol"):
            runfile.load(path)


@pytest.mark.parametrize("k", (2, 3))
def test_the_condensed_newton_correction_solves_the_full_system(elastica, k):
    """Nodes, stages and the parameter: the correction from the condensed banded system (and
    the stage correction recovered from it) against a dense solve of the whole uncondensed
    Newton system, its Jacobian by central differences of the residuals."""
    from elastica_auto.numerics.correctors import Linearizer
    from elastica_auto.numerics.newton import Linearization

    rng = np.random.default_rng(10 + k)
    s, y, p = _elastica_state(elastica, 4, rng)
    disc = GaussDiscretisation(elastica, s, k)
    K = disc.stages(y, p) + 0.01 * rng.standard_normal((4, k, 3))
    lam = p["P"]          # P enters the equation (psi only the end)
    row = Row(rng.standard_normal(y.shape), 0.7, 0.3)
    split = Linearizer(elastica, "P", lambda problem, s: GaussDiscretisation(problem, s, k)).split
    lin = Linearization(disc, "P", p, y, lam, row, split, K)
    dY, dlam, dK = lin.correct(row, disc.evaluate(y, p, K), row.residual(y, lam))

    def residual(x):
        Yx, Kx, lx = x[:y.size].reshape(y.shape), x[y.size:-1].reshape(K.shape), x[-1]
        ev = disc.evaluate(Yx, {**p, "P": lx}, Kx)
        return np.concatenate((ev.col.ravel(), ev.stage.ravel(), ev.bc,
                               [row.residual(Yx, lx)]))

    x0 = np.concatenate((y.ravel(), K.ravel(), [lam]))
    dx = np.linalg.solve(central_jacobian(residual, x0), residual(x0))
    np.testing.assert_allclose(dY, dx[:y.size].reshape(y.shape), rtol=0, atol=1e-7)
    np.testing.assert_allclose(dK, dx[y.size:-1].reshape(K.shape), rtol=0, atol=1e-7)
    assert abs(dlam - dx[-1]) < 1e-7


@pytest.mark.parametrize("k, intervals, order", [(0, (8, 16), 4), (3, (4, 8), 6)])
def test_the_corrector_ncol_makes_solves_on_its_own_discretisation(k, intervals, order):
    """``ncol = k`` makes the Gauss corrector (k > 0) or the cubic collocation one (0), each
    behind the corrector interface: a value solve through it on a fixed mesh has node errors
    against Bratu's closed form that fall like h^4 (the cubic scheme) or h^(2k)."""
    from elastica_auto.core.solution import State
    from elastica_auto.numerics.correctors import Collocation, Gauss, make_corrector

    bratu = load_problem(str(EXAMPLES / "bratu.py"))
    corr = make_corrector(bratu, "lam", ContinuationOptions(ncol=k))
    assert type(corr) is (Gauss if k else Collocation)
    z = 1.5
    lam = 2 * z * z / math.cosh(z / 2) ** 2

    def exact(x):
        return np.vstack((-2 * np.log(np.cosh(z * (x - 0.5)) / math.cosh(z / 2)),
                          -2 * z * np.tanh(z * (x - 0.5))))

    err = []
    for m in intervals:
        s = np.linspace(0.0, 1.0, m + 1)
        guess = State.from_values(bratu, s, exact(s) + 0.01 * np.sin(np.pi * s), {"lam": lam})
        got = corr.at_value(guess, {"lam": lam}, lam)
        assert np.array_equal(got.s, s)
        err.append(np.max(np.abs(got.y - exact(s))))
    assert abs(math.log2(err[0] / err[1]) - order) < 0.3, err


def test_the_cubic_corrector_refuses_gauss_points():
    """`Collocation` is the cubic scheme only: made directly with ``ncol > 0`` it refuses
    (one line naming `make_corrector`) instead of solving on the cubic scheme unasked (the
    benchmark's Gauss rows measured the cubic scheme so, unnoticed)."""
    from elastica_auto.numerics.correctors import Collocation, Gauss

    bratu = load_problem(str(EXAMPLES / "bratu.py"))
    with pytest.raises(ValueError, match="make_corrector"):
        Collocation(bratu, "lam", ContinuationOptions(ncol=4))
    assert Gauss(bratu, "lam", ContinuationOptions(ncol=4)).options.ncol == 4
    Collocation(bratu, "lam", ContinuationOptions())
