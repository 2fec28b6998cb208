"""The collocation corrector's parts against independent implementations, and the two
correctors against each other.

* the collocation equations against scipy's own (scipy.integrate._bvp.collocation_fun, the
  discretisation both correctors share) and their Jacobian against finite differences;
* the banded form of the bordered systems against a dense assembly and numpy's solver
  (solutions, transposed solutions, log|det|, the sign up to a structural constant, the
  rank-one change of the border row);
* the collocation and the solve_bvp corrector: the same folds on rotating_arm branches and on
  Bratu, to 1e-9 and against the analytic fold.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate._bvp import collocation_fun

import shooting
from elastica_auto.numerics import bordered
from elastica_auto.execution import runfile
from elastica_auto.numerics.collocation import Blocks, Discretisation, equidistributed_mesh
from helpers import EXAMPLES, ROTATING_ARM, central_jacobian, run_plan

# ---- the discretisation ------------------------------------------------------------------


def _state(elastica, m, rng):
    s = np.sort(np.concatenate(([0.0, 1.0], rng.uniform(0, 1, m - 2))))
    y = np.vstack((np.sin(3 * s) + 0.2, 2 * np.cos(2 * s), s * s, -s))
    p = {**elastica.defaults(), "P": 7.3, "eps": 0.4, "psi": 0.9, "alpha": 0.3}
    return s, y, p


def test_collocation_equations_are_scipys(elastica):
    rng = np.random.default_rng(1)
    s, y, p = _state(elastica, 37, rng)
    disc = Discretisation(elastica, s)
    ev = disc.evaluate(y, p)
    col, y_mid, f, f_mid = collocation_fun(lambda x, y, _: elastica.rhs(x, y, p), y, None, s,
                                           np.diff(s))
    np.testing.assert_allclose(ev.col, col, rtol=0, atol=1e-15)
    np.testing.assert_allclose(ev.y_mid, y_mid, rtol=0, atol=1e-15)
    np.testing.assert_allclose(ev.bc, elastica.bc(y[:, 0], y[:, -1], p), rtol=0, atol=0)


def test_collocation_jacobian_is_the_derivative_of_the_equations(elastica):
    rng = np.random.default_rng(2)
    s, y, p = _state(elastica, 13, rng)
    disc = Discretisation(elastica, s)
    blocks = disc.blocks(disc.evaluate(y, p), p, ("psi", "P"))
    v = rng.standard_normal(y.shape)
    h = 1e-6
    plus, minus = disc.evaluate(y + h * v, p), disc.evaluate(y - h * v, p)
    col, bc = blocks.times(v)
    np.testing.assert_allclose(col, (plus.col - minus.col) / (2 * h), rtol=0, atol=1e-8)
    np.testing.assert_allclose(bc, (plus.bc - minus.bc) / (2 * h), rtol=0, atol=1e-8)
    for name in ("psi", "P"):
        up = disc.evaluate(y, {**p, name: p[name] + h})
        down = disc.evaluate(y, {**p, name: p[name] - h})
        np.testing.assert_allclose(blocks.dcol[name], (up.col - down.col) / (2 * h), atol=1e-8)
        np.testing.assert_allclose(blocks.dbc[name], (up.bc - down.bc) / (2 * h), atol=1e-8)
    # the transpose: <w, F_y v> = <F_y^T w, v>
    w_col, w_bc = rng.standard_normal(col.shape), rng.standard_normal(bc.shape)
    lhs = np.sum(w_col * col) + w_bc @ bc
    assert lhs == pytest.approx(np.sum(blocks.transpose_times(w_col, w_bc) * v), rel=1e-12)


@pytest.mark.parametrize("ncol", [0, 4])
def test_the_fold_newton_border_row_is_the_gradient_of_its_test_function(elastica, ncol):
    """`newton.fold_gradient` (the last row of the fold Newton matrix) against central
    differences of the test function g itself (`newton.null_vector`, b and c held fixed) at
    a state that solves nothing: in lam, and along a random direction of the node values;
    for the cubic scheme and for Gauss collocation (whose condensed equations' mixed
    derivatives commute too)."""
    from elastica_auto.numerics.gauss import GaussDiscretisation
    from elastica_auto.numerics.newton import fold_gradient, null_vector
    rng = np.random.default_rng(3)
    s, y, p = _state(elastica, 41, rng)
    disc = GaussDiscretisation(elastica, s, ncol) if ncol else Discretisation(elastica, s)
    name = "psi"
    blocks = disc.blocks(disc.evaluate(y, p), p, (name,))
    split = bordered.split_rows(blocks.ga, blocks.gb)
    c = disc.weights * rng.standard_normal(y.shape)
    b_col, b_bc = blocks.dcol[name], blocks.dbc[name]

    def g_at(Y, lam):
        q = {**p, name: lam}
        bl = disc.blocks(disc.evaluate(Y, q), q)
        fixed = Blocks(bl.d0, bl.d1, bl.ga, bl.gb, {name: b_col}, {name: b_bc}, bl.jac, bl.fp)
        return null_vector(disc, fixed, name, c, split)[1]

    v, _, w_col, w_bc, _ = null_vector(disc, Blocks(blocks.d0, blocks.d1, blocks.ga, blocks.gb,
                                                  {name: b_col}, {name: b_bc}, blocks.jac,
                                                  blocks.fp), name, c, split)
    g_y, g_lam = fold_gradient(disc, name, p, y, blocks, v, w_col, w_bc)
    h, lam = 1e-5, p[name]
    central = (g_at(y, lam + h) - g_at(y, lam - h)) / (2 * h)
    # (the one-sided difference is within ~1e-7 of the derivative; measured 4e-8)
    assert g_lam == pytest.approx(central, rel=1e-6)
    d = rng.standard_normal(y.shape)
    along = (g_at(y + h * d, lam) - g_at(y - h * d, lam)) / (2 * h)
    assert float(np.sum(g_y * d)) == pytest.approx(along, rel=1e-6)


def test_a_fold_newton_step_is_newtons_step_on_the_augmented_system(elastica):
    """One iteration of `newton.fold_newton` from beside the rotating arm's first fold (eps
    = 0.25, P = pi^2/4; its solution and parameter moved by 1e-3) against Newton's step on
    (F, g) with the Jacobian by central differences of the residuals and of g itself (its
    border column F_lam taken at that point, as the iteration's gradient holds it), solved
    densely."""
    import elastica_auto as ea
    from elastica_auto.numerics.newton import null_vector, fold_newton
    arm = ea.continuation(elastica, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                          bounds=(-2 * math.pi, 2 * math.pi))
    near = arm.label("LP1")
    s, p, name = near.state.s, dict(near.state.params), "psi"
    y0 = near.state.y + 1e-3 * np.sin(np.arange(1, 5)[:, None] * s)
    lam0 = p[name] = p[name] + 1e-3
    disc = Discretisation(elastica, s)
    blocks = disc.blocks(disc.evaluate(y0, p), p, (name,))
    split = bordered.split_rows(blocks.ga, blocks.gb)
    c = disc.weights * near.tangent.on(s).y
    b_col, b_bc = blocks.dcol[name], blocks.dbc[name]

    def residual(z):
        Y, lam = z[:-1].reshape(y0.shape), z[-1]
        q = {**p, name: lam}
        ev = disc.evaluate(Y, q)
        bl = disc.blocks(ev, q)
        fixed = Blocks(bl.d0, bl.d1, bl.ga, bl.gb, {name: b_col}, {name: b_bc}, bl.jac, bl.fp)
        return np.concatenate((ev.col.ravel(), ev.bc, [null_vector(disc, fixed, name, c,
                                                                    split)[1]]))

    z0 = np.append(y0.ravel(), lam0)
    dense = np.linalg.solve(central_jacobian(residual, z0), -residual(z0))
    res = fold_newton(disc, name, p, y0, lam0, near.tangent, split, max_iter=1)
    step = np.append((res.Y - y0).ravel(), res.lam - lam0)
    # (measured 1e-8 of the step; a sign error in g or g_lam: O(1))
    assert np.max(np.abs(step - dense)) <= 1e-6 * np.max(np.abs(dense))


def test_equidistributed_mesh_meets_its_target(elastica_reference):
    """A regridded mesh brings the error estimate of a converged solution to about the
    target (within the factor 2 the step's margins allow for). (The hand-written elastica:
    its boundary rows at s = 0 are the first three, as ``split`` says.)"""
    elastica = elastica_reference
    from elastica_auto.numerics.newton import Row, newton
    p = {**elastica.defaults(), "P": 9 * math.pi ** 2 / 4, "eps": 0.5}
    k0 = shooting.solve_at(0.7, p["P"], p["eps"], 6.0)
    s = np.linspace(0.0, 1.0, 41)
    y = shooting.profile(p["P"], 0.0, [0.0, k0, 0.0, 0.0], s)
    p["psi"] = 0.7
    split = ((0, 1, 2), (3,), ())
    for target in (1e-6, 1e-8):
        disc = Discretisation(elastica, s)
        res = newton(disc, "psi", p, y, 0.7, Row.value(disc, 0.7), None, split)
        ev = disc.evaluate(res.Y, p)
        rms = disc.rms_residuals(res.Y, ev.f, p, ev)
        new = Discretisation(elastica, equidistributed_mesh(s, rms, target, 10, 10 ** 4))
        y_new = shooting.profile(p["P"], 0.0, [0.0, k0, 0.0, 0.0], new.s)
        res = newton(new, "psi", p, y_new, 0.7, Row.value(new, 0.7), None, split)
        assert res.converged
        ev = new.evaluate(res.Y, p)
        worst = new.rms_residuals(res.Y, ev.f, p, ev).max()
        assert target / 2 <= worst <= 2 * target, (target, worst)


# ---- the bordered banded systems ---------------------------------------------------------

def _dense(blocks, names, border):
    d0 = blocks.d0
    m, n, k = d0.shape[0] + 1, d0.shape[1], len(names)
    N = n * m + k
    M = np.zeros((N, N))
    for i in range(m - 1):
        M[i * n:(i + 1) * n, i * n:(i + 1) * n] = d0[i]
        M[i * n:(i + 1) * n, (i + 1) * n:(i + 2) * n] = blocks.d1[i]
        for q, nm in enumerate(names):
            M[i * n:(i + 1) * n, n * m + q] = blocks.dcol[nm][:, i]
    r0 = n * (m - 1)
    M[r0:r0 + n, :n] = blocks.ga
    M[r0:r0 + n, (m - 1) * n:m * n] = blocks.gb
    for q, nm in enumerate(names):
        M[r0:r0 + n, n * m + q] = blocks.dbc[nm]
    for q, (c, d) in enumerate(border):
        M[n * m + q, :n * m] = c.T.ravel()
        M[n * m + q, n * m:] = d
    return M


@pytest.mark.parametrize("n, m, names, pattern", [
    (4, 7, ("a",), "LLLR"), (2, 5, (), "LR"), (3, 6, ("a", "b"), "LMR"), (4, 9, ("a",), "MMRL"),
    (2, 6, ("a", "b"), "PM"), (4, 41, ("a",), "LLLR")])
def test_banded_form_solves_the_bordered_system(n, m, names, pattern):
    """Left (L), right (R), both-ends (M) and parameter-only (P) boundary rows; 0-2 borders."""
    rng = np.random.default_rng(m * 10 + n)
    signs = set()
    for _ in range(4):
        d0 = rng.standard_normal((m - 1, n, n)) * 0.3 - np.eye(n)
        d1 = rng.standard_normal((m - 1, n, n)) * 0.3 + np.eye(n)
        ga, gb = rng.standard_normal((n, n)), rng.standard_normal((n, n))
        for r, kind in enumerate(pattern):
            if kind in "RP":
                ga[r] = 0
            if kind in "LP":
                gb[r] = 0
        blocks = Blocks(d0, d1, ga, gb, {nm: rng.standard_normal((n, m - 1)) for nm in names},
                        {nm: rng.standard_normal(n) for nm in names}, None, None)
        k = len(names)
        border = [(rng.standard_normal((n, m)), rng.standard_normal(k)) for _ in range(k)]
        M = _dense(blocks, names, border)
        fact = bordered.factor(blocks, names, border)
        col, bc, g = rng.standard_normal((n, m - 1)), rng.standard_normal(n), rng.standard_normal(k)
        y, p = fact.solve(col, bc, g)
        x = np.linalg.solve(M, np.concatenate([col.T.ravel(), bc, g]))
        scale = np.max(np.abs(x))
        np.testing.assert_allclose(y.T.ravel(), x[:n * m], atol=1e-11 * scale)
        np.testing.assert_allclose(p, x[n * m:], atol=1e-11 * scale)
        ey, ep = rng.standard_normal((n, m)), rng.standard_normal(k)
        w_col, w_bc, w_g = fact.solve_transpose(ey, ep)
        w = np.linalg.solve(M.T, np.concatenate([ey.T.ravel(), ep]))
        scale = np.max(np.abs(w))
        np.testing.assert_allclose(w_col.T.ravel(), w[:n * (m - 1)], atol=1e-11 * scale)
        np.testing.assert_allclose(w_bc, w[n * (m - 1):n * m], atol=1e-11 * scale)
        np.testing.assert_allclose(w_g, w[n * m:], atol=1e-11 * scale)
        sign, logdet = np.linalg.slogdet(M)
        assert fact.logdet == pytest.approx(logdet, abs=1e-8)
        signs.add(fact.sign * int(sign))
        if k:
            c2, d2 = rng.standard_normal((n, m)), rng.standard_normal(k)
            y2, p2 = fact.solve_with_border(c2, d2, col, bc, g)
            M2 = M.copy()
            M2[-1, :n * m], M2[-1, n * m:] = c2.T.ravel(), d2
            x2 = np.linalg.solve(M2, np.concatenate([col.T.ravel(), bc, g]))
            scale = np.max(np.abs(x2))
            np.testing.assert_allclose(y2.T.ravel(), x2[:n * m], atol=1e-10 * scale)
            np.testing.assert_allclose(p2, x2[n * m:], atol=1e-10 * scale)
    # det(banded) = +-det(bordered) with a sign fixed by the structure alone
    assert len(signs) == 1


# ---- the two correctors -------------------------------------------------------------------

def _folds(branches):
    return [sorted(p.params[b.parameter] for p in b.folds) for b in branches]


def test_both_correctors_find_the_same_folds_on_rotating_arm(tmp_path):
    plan = runfile.load(ROTATING_ARM)
    # the load pi^2/4 (both arm lengths, both directions): 20 folds; solve_bvp is slow
    plan.branches = [b for b in plan.branches if abs(b.params["P"] - math.pi ** 2 / 4) < 1e-12]
    plan.user_values = []
    assert len(plan.branches) == 4
    runs = {}
    for corrector in ("collocation", "solve_bvp"):
        p = dataclasses.replace(plan, options=dataclasses.replace(plan.options,
                                                                 corrector=corrector))
        runs[corrector] = run_plan(p, tmp_path / corrector).result.branches
    a, b = _folds(runs["collocation"]), _folds(runs["solve_bvp"])
    assert [len(f) for f in a] == [5, 5, 5, 5] == [len(f) for f in b]
    np.testing.assert_allclose(np.concatenate(a), np.concatenate(b), rtol=0, atol=1e-9)
    for br in runs["collocation"]:
        for p in br.folds:
            eps, P = p.params["eps"], p.params["P"]
            _, psi, _ = shooting.fold(P, eps, p.ordinates["m0"], p.params["psi"])
            assert abs(psi - p.params["psi"]) <= 1e-9


def test_both_correctors_find_the_bratu_fold(tmp_path):
    from test_user_module import lam_of
    from scipy.optimize import brentq
    z_c = brentq(lambda z: z * math.tanh(z / 2) - 2, 1.0, 4.0, xtol=1e-15)
    plan = runfile.load(EXAMPLES / "bratu.toml")
    found = []
    for corrector in ("collocation", "solve_bvp"):
        p = dataclasses.replace(plan, options=dataclasses.replace(plan.options,
                                                                 corrector=corrector))
        (br,) = run_plan(p, tmp_path / corrector).result.branches
        (lp,) = br.folds
        found.append(lp.params["lam"])
    assert abs(found[0] - found[1]) <= 1e-9
    assert abs(found[0] - lam_of(z_c)) <= 1e-9


def test_the_solve_bvp_corrector_steps_by_solve_bvp(tmp_path, monkeypatch):
    """With corrector = "solve_bvp" every accepted step is a solve_bvp solve (it inherited the
    collocation Newton's step, and the cross-check of the two correctors was none: 19
    collocation steps and 1 solve_bvp call on Bratu's branch)."""
    from elastica_auto.numerics import bvp
    real, calls = bvp.solve_arclength, [0]

    def counted(*args, **kwargs):
        calls[0] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(bvp, "solve_arclength", counted)
    plan = runfile.load(EXAMPLES / "bratu.toml")
    p = dataclasses.replace(plan, options=dataclasses.replace(plan.options,
                                                             corrector="solve_bvp"))
    (br,) = run_plan(p, tmp_path / "out").result.branches
    steps = sum(1 for q in br.points if not q.type)
    assert br.end == "EP" and steps >= 10
    assert calls[0] >= steps


def test_a_switch_under_solve_bvp_is_the_collocation_correctors(elastica):
    """The other branch at the straight rod's first branch point (eps = 0.5), by both
    correctors: both ways end at the bound (EP), at the same points (a switch under solve_bvp
    ended both branches MX: its step took no curvature)."""
    import elastica_auto as ea
    straight = ea.continuation(elastica, {"P": 0.5, "eps": 0.5}, "P", bounds=(0.1, 5))
    bp = straight.label("BP1")
    found = []
    for corrector in ("collocation", "solve_bvp"):
        out = ea.continuation(elastica, ea.Switch(bp), "P", bounds=(0.1, 3), uz=[2.5],
                              corrector=corrector)
        assert [b.end for b in out] == ["EP", "EP"], [b.message for b in out]
        found.append(sorted((round(p.ordinates["m1"], 4), p.ordinates["m0"])
                            for b in out for p in b.points if p.type == "UZ"))
    assert len(found[0]) == 2 and [m for m, _ in found[0]] == [m for m, _ in found[1]]
    for (_, a), (_, b) in zip(*found):
        assert abs(a - b) <= 1e-6


# ---- the corrector interface ----------------------------------------------------------------

CONFIGURATIONS = [("collocation", 0), ("collocation", 4), ("solve_bvp", 0)]


@pytest.mark.parametrize("corrector, ncol", CONFIGURATIONS)
def test_every_corrector_has_the_interfaces_operations(elastica, corrector, ncol):
    """Every operation of `numerics.corrector.Corrector` is one of the corrector's own, and the
    solve_bvp corrector inherits nothing from the collocation corrector (it did: its starts
    and tangents were the collocation Newton's)."""
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.numerics.corrector import Corrector
    from elastica_auto.numerics.correctors import Collocation, SolveBVP, make_corrector
    corr = make_corrector(elastica, "P", ContinuationOptions(corrector=corrector, ncol=ncol))
    operations = [n for n, v in vars(Corrector).items() if callable(v) and not n.startswith("_")]
    assert len(operations) == 15
    for name in operations + list(Corrector.__annotations__):
        assert hasattr(corr, name), name
    assert not issubclass(SolveBVP, Collocation)


@pytest.mark.parametrize("corrector, ncol", CONFIGURATIONS)
def test_the_kernel_at_eulers_load_is_the_buckling_mode(elastica, corrector, ncol):
    """The straight rod (eps = 0) at Euler's load P = pi^2/4 of the clamped-free column,
    linearised along the trivial branch's tangent (its parameter alone): the interface's
    kernel is the buckling mode theta = c sin(pi s / 2), kappa = theta', with no parameter
    part (a symmetric pitchfork), its relative residual at rounding or discretisation level;
    at P = 2, a regular point, the "kernel" leaves a residual of order one. On 100 intervals
    the discrete mode is off by the discretisation error: h^4 (pi/2)^4 ~ 6e-8 for the cubic
    scheme (solve_bvp's own, so the same for both of its correctors), h^8 for Gauss at 4."""
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.core.solution import State, Tangent
    from elastica_auto.numerics.correctors import make_corrector
    s = np.linspace(0.0, 1.0, 101)
    t1 = Tangent(s, np.zeros((4, len(s))), np.zeros((4, len(s))), 1.0)
    corr = make_corrector(elastica, "P", ContinuationOptions(corrector=corrector, ncol=ncol))
    bound = 1e-7 if ncol == 0 else 1e-12
    for P in (math.pi ** 2 / 4, 2.0):
        p = {**elastica.defaults(), "P": P, "eps": 0.0, "psi": 0.0, "alpha": 0.0, "theta0": 0.0}
        straight = State.from_values(elastica, s, np.vstack((0 * s, 0 * s, 0 * s, s)), p)
        sol = corr.linearize(straight, t1)
        assert sol.tangent.lam == pytest.approx(1.0) and sol.lam == P
        direction, residual = corr.kernel(sol)
        c = direction.y[0][np.argmax(np.abs(direction.y[0]))]
        mode = np.sin(np.pi * s / 2)
        if P == 2.0:
            assert residual > 1e-2
            continue
        assert residual <= 1e-8
        assert np.max(np.abs(direction.y[0] / c - mode)) <= bound
        assert np.max(np.abs(direction.y[1] / c - np.pi / 2 * np.cos(np.pi * s / 2))) <= 2 * bound
        assert abs(direction.lam) <= bound
        assert corr.kernel_error(sol).max() <= 1e-6


def test_the_solve_bvp_corrector_solves_nothing_by_the_collocation_newton(tmp_path,
                                                                           monkeypatch):
    """Under corrector = "solve_bvp" with the collocation corrector's Newton iterations
    (points, steps, folds) made to fail: a start solved from a guess (Bratu's lower solution
    at z = 1, from 0.8 of it, on 11 nodes) is the closed form's u = -2 ln(cosh(z (x - 1/2)) /
    cosh(z / 2)) to tol = 1e-5 (a start from a guess was the collocation Newton's), and
    Bratu's branch steps and folds by solve_bvp alone, its fold the closed form's (lam at
    z tanh(z / 2) = 2) to 1e-9, the accuracy of a fold located to fold_tol = 1e-7 on the
    residual of a 4th-order scheme (its parameter error ~ fold_tol^(4/3))."""
    from scipy.optimize import brentq
    from test_user_module import lam_of
    import elastica_auto as ea
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.core.solution import State
    from elastica_auto.numerics import correctors

    def refused(*args, **kwargs):
        raise AssertionError("the collocation Newton under corrector = 'solve_bvp'")

    monkeypatch.setattr(correctors, "newton", refused)
    monkeypatch.setattr(correctors, "fold_newton", refused)
    problem = ea.load_problem(str(EXAMPLES / "bratu.py"))
    z, x = 1.0, np.linspace(0.0, 1.0, 11)

    def exact(x):
        u = -2 * np.log(np.cosh(z * (x - 0.5)) / math.cosh(z / 2))
        return np.vstack((u, -2 * z * np.tanh(z * (x - 0.5))))

    corr = correctors.make_corrector(problem, "lam", ContinuationOptions(corrector="solve_bvp"))
    guess = State.from_values(problem, x, 0.8 * exact(x), {"lam": lam_of(z)})
    sol = corr.point(guess)
    assert sol.lam == lam_of(z) and sol.tangent.lam > 0    # oriented along lam = value
    assert np.max(np.abs(sol.state.y - exact(sol.mesh))) <= 1e-5
    plan = runfile.load(EXAMPLES / "bratu.toml")
    p = dataclasses.replace(plan, options=dataclasses.replace(plan.options,
                                                             corrector="solve_bvp"))
    (br,) = run_plan(p, tmp_path / "out").result.branches
    assert br.end == "EP", br.message
    (lp,) = br.folds
    z_c = brentq(lambda z: z * math.tanh(z / 2) - 2, 1.0, 4.0, xtol=1e-15)
    assert abs(lp.params["lam"] - lam_of(z_c)) <= 1e-9
