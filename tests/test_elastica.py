"""The elastica module and the solutions of a rotating-arm run, checked against exact facts:
the trivial solution, the first integral m + r x n, the free-end condition, and an independent
IVP integration."""

from __future__ import annotations

import math

import numpy as np
import pytest

import shooting
from helpers import invariant, invariant_bound

TWO_PI = 2 * math.pi

# ---- 1. the exact start -------------------------------------------------------------------

@pytest.mark.parametrize("P", [math.pi ** 2 / 4, 9 * math.pi ** 2 / 4, 0.3, -5.0])
@pytest.mark.parametrize("eps", [0.25, 0.5, -1.0])
@pytest.mark.parametrize("angle", [0.0, 0.7, -2.0])   # theta0 = alpha = angle
def test_exact_start_solves_the_bvp_exactly(elastica, P, eps, angle):
    s = np.linspace(0.0, 1.0, 41)
    for psi in (0.0, math.pi, TWO_PI, -3 * TWO_PI):
        p = {**elastica.defaults(), "P": P, "eps": eps, "psi": psi, "alpha": angle,
             "theta0": angle}
        y = elastica.exact_start(s, p)
        assert y is not None and y.shape == (4, len(s))
        # The straight rod along the load is linear in s: y' = (0, 0, -sin t, cos t), and the
        # right-hand side returns that to rounding (the derived kappa' = P (sin alpha cos
        # theta - cos alpha sin theta), the load's torque: its two products round apart).
        t = angle
        exact_slope = np.array([0.0, 0.0, -math.sin(t), math.cos(t)])[:, None] * np.ones_like(s)
        np.testing.assert_allclose(elastica.rhs(s, y, p), exact_slope, rtol=0,
                                   atol=1e-15 * (1 + abs(P)))
        # A numerical derivative of a linear function is exact up to rounding.
        np.testing.assert_allclose(np.gradient(y, s, axis=1), exact_slope, rtol=0, atol=1e-13)
        # the rows: theta(0) - theta0, the natural end condition, x(0), y(0) (derived from
        # the energy: each coordinate's ends, then the quadratures' starts)
        bc = elastica.bc(y[:, 0], y[:, -1], p)
        if psi == 0.0:
            np.testing.assert_array_equal(bc, 0.0)
        else:
            # sin(pi), sin(2 pi k) of the rounded multiples of pi are ~1e-16 k, not 0.
            np.testing.assert_array_equal(bc[[0, 2, 3]], 0.0)
            assert abs(bc[1]) <= abs(eps * P) * 1e-14
        # The clamp moment, and with it mA, vanish on the straight rod, and the tip moment
        # m1 = dE/dpsi = -eps F.da/dpsi (derived: the load's moment on the arm) to rounding.
        o = elastica.ordinate_values(s, y, p)
        assert o["m0"] == 0.0 and abs(o["mA"]) <= 1e-14 * (1 + abs(P)) * (1 + abs(eps))
        assert abs(o["m1"]) <= 1e-14 * abs(eps * P)


def test_exact_start_is_refused_where_the_rod_is_not_straight(elastica):
    s = np.linspace(0.0, 1.0, 11)
    base = elastica.defaults()
    assert elastica.exact_start(s, {**base, "alpha": 0.1, "theta0": 0.0}) is None
    assert elastica.exact_start(s, {**base, "psi": 0.3}) is None


# ---- 2. the first integral m + r x n ------------------------------------------------------

def _tol_of(label, options):
    return options.fold_tol if label.startswith("LP") else options.tol


def test_moment_invariant_is_constant_on_every_labelled_solution(rotating_arm):
    """kappa(s) - P (x cos alpha + y sin alpha) is independent of s (docs/design.md, "The
    elastica with a lever arm"), checked on the exact collocation solution of every label, on
    its own mesh."""
    bf, opt = rotating_arm.file, rotating_arm.plan.options
    assert len(bf.labels) > 100
    worst = 0.0
    for name in bf.labels:
        st = bf.label(name).state
        p = st.params
        dev = np.ptp(invariant(st.y, p))
        bound = invariant_bound(_tol_of(name, opt), p["P"], p["alpha"])
        assert dev <= bound, (name, dev, bound)
        worst = max(worst, dev / bound)
    print(f"largest invariant deviation / bound: {worst:.2e}")


def test_moment_invariant_on_every_stored_profile_and_mA_equals_m0(rotating_arm):
    """The same on the 101-point profiles of every point (the cubic Hermite interpolant of a
    solution whose node slopes conserve I keeps I between its node values), and the ordinate
    mA = I(1) equals m0 = kappa(0) = I(0) up to the invariant bound and the clamp's boundary
    residual |P| (|x(0) cos alpha| + |y(0) sin alpha|) <= |P| tol (|cos| + |sin|)."""
    opt = rotating_arm.plan.options
    tol = max(opt.tol, opt.fold_tol)
    for b in rotating_arm.file.branches:
        c = b.columns
        for i in range(len(b)):
            p = {k: c[k][i] for k in ("P", "alpha")}
            bound = invariant_bound(tol, p["P"], p["alpha"])
            assert np.ptp(invariant(b.profiles[i], p)) <= bound
            clamp = abs(p["P"]) * tol * (abs(math.cos(p["alpha"])) + abs(math.sin(p["alpha"])))
            assert abs(c["mA"][i] - c["m0"][i]) <= bound + clamp


# ---- 7. the range of the tip moment -------------------------------------------------------

def test_tip_moment_is_bounded_by_eps_P_and_reaches_both_bounds(rotating_arm):
    """The free-end condition kappa(1) = -eps P sin(psi + alpha - theta(1)) makes the tip moment
    m1 = kappa(1) a sine of the arm angle a = psi + alpha - theta(1): |m1| <= |eps P|, with
    m1 = +|eps P| exactly where a = -pi/2 (mod 2 pi) (for eps P > 0), -|eps P| at a = +pi/2.
    Along a psi-branch that turns the arm through full turns, a passes through both values, so
    the continuous branch attains both bounds. The branch is only sampled at its points, so the
    sampled extremes can miss the bounds by eps P (1 - cos(da / 2)), da the step in a across the
    crossing; the boundary condition itself holds to solve_bvp's bc_tol <= tol."""
    tol = rotating_arm.plan.options.tol
    for b in rotating_arm.file.branches:
        c = b.columns
        eP = float(c["eps"][0] * c["P"][0])
        assert eP > 0
        m1 = c["m1"]
        a = c["psi"] + c["alpha"] - b.profiles[:, 0, -1]   # profile grid ends at s = 1
        assert np.all(np.abs(m1) <= eP + tol)
        np.testing.assert_allclose(m1, -eP * np.sin(a), rtol=0, atol=tol)
        for target, sign in ((-math.pi / 2, +1), (math.pi / 2, -1)):
            # crossings of a = target + 2 pi k between consecutive points
            k = np.floor((a - target) / TWO_PI)
            idx = np.nonzero(np.diff(k) != 0)[0]
            assert len(idx) > 0, f"branch {b.number}: the arm angle never reaches {target:+.4f}"
            for i in idx:
                best = max(sign * m1[i], sign * m1[i + 1])
                da = abs(a[i + 1] - a[i])
                assert da < math.pi  # a genuine crossing, not a jump of a whole turn
                assert best >= eP * math.cos(da / 2) - tol
                assert best <= eP + tol


# ---- 8. user points -----------------------------------------------------------------------

def _user_values(plan):
    spec = plan.user_values[0]
    return spec.values, spec.period


def test_user_points_lie_at_the_requested_values_and_solve_the_bvp(rotating_arm, elastica):
    values, period = _user_values(rotating_arm.plan)
    assert period == pytest.approx(TWO_PI, abs=1e-15)
    tol = rotating_arm.plan.options.tol
    bf = rotating_arm.file
    uz = [n for n in bf.labels if n.startswith("UZ")]
    assert len(uz) > 50
    for name in uz:
        st = bf.label(name).state
        p = st.params
        # psi = v + 2 pi k for one of the requested v
        dist = min(abs(p["psi"] - v - TWO_PI * round((p["psi"] - v) / TWO_PI)) for v in values)
        assert dist <= 1e-9, (name, p["psi"])
        # boundary conditions: solve_bvp's success criterion, |bc| <= bc_tol <= tol
        assert np.max(np.abs(elastica.bc(st.y[:, 0], st.y[:, -1], p))) <= tol
        # the ODE: an independent IVP integration from the stored y(0) stays on the stored
        # solution. solve_bvp keeps |y' - f| <= ~tol (1 + |f|), |f| <= 1 + |P|, over a unit
        # interval: an error of order tol (1 + |P|).
        ivp = shooting.profile(p["P"], p["alpha"], st.y[:, 0], st.s)
        assert np.max(np.abs(ivp - st.y)) <= tol * (2 + abs(p["P"])), name


def _crossed(a, b, values, period):
    """Values v + k period in (a, b] (or [b, a)): the user values passed from a to b."""
    lo, hi = min(a, b), max(a, b)
    out = []
    for v in values:
        for k in range(math.floor((lo - v) / period), math.ceil((hi - v) / period) + 1):
            c = v + k * period
            if a < c <= b or b <= c < a:
                out.append(c)
    return sorted(out)


def test_every_user_value_passed_is_labelled(rotating_arm):
    """Between consecutive points that are not UZ (folds included, since psi turns there), each
    user value passed must be labelled once; an EP exactly at a user value stands for it."""
    values, period = _user_values(rotating_arm.plan)
    for b in rotating_arm.file.branches:
        t, psi = b.columns["type"], b.columns["psi"]
        keep = [i for i in range(len(t)) if t[i] != "UZ"]
        for i, j in zip(keep[:-1], keep[1:]):
            expected = _crossed(psi[i], psi[j], values, period)
            if t[j] == "EP":
                expected = [c for c in expected if abs(c - psi[j]) > 1e-12]
            got = sorted(psi[i + 1:j])
            assert len(got) == len(expected), (b.number, i, j, expected, got)
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)


# ---- the accuracy of plain continuation points --------------------------------------------

def test_continuation_points_meet_the_documented_accuracy(rotating_arm):
    """options.py documents tol = 1e-5 as giving points 'good to about 1e-7 (relative)'. The
    free-end condition is exact on a true solution, so its residual on a stored point measures
    that accuracy; allow 10x the documented 1e-7, relative to eps P. (Regression: with
    solve_bvp's default bc_tol = tol the residual reached 8e-6.)"""
    for b in rotating_arm.file.branches:
        c = b.columns
        eP = c["eps"] * c["P"]
        a = c["psi"] + c["alpha"] - b.profiles[:, 0, -1]
        res = np.abs(c["m1"] + eP * np.sin(a))
        assert np.all(res <= 1e-6 * (1 + np.abs(eP))), (b.number, res.max())
