"""The Cosserat rods (equations/cosserat_planar.py, equations/cosserat_rod.py; issue 49 item 1;
docs/soft-robots.md, "Cosserat rods") against what is independent of their derivation:

* the inextensible limit: the rotating arm's folds (runs/rotating_arm.toml's four (eps, P)
  pairs) at three shear and extension stiffnesses, extrapolated to infinite stiffness, are the
  shipped elastica's, at the rate 1/stiffness, with the same index on every stretch;
* an exact identity: with equal shear and extension stiffnesses S and no distributed load,
  n = F and r' = d3 + F / S, so the moment balance is the inextensible rod's and every fold in
  psi is the elastica's (the Kirchhoff rod's) to the fold tolerance, gamma = dE/dP less P / S;
* conservation on computed branches with a weight g: n(s) = F - g (1 - s) e_y at every point,
  and the Hamiltonian H = m^2/2 + m u1 + n2^2 / (2 GA) + n3^2 / (2 EA) + n.R v_hat - g y
  (no explicit s) constant along each solution;
* the index two ways at random states (no equilibria): the engine's direct count of the
  derived second variation against the inertia of the finite-difference Hessian of the rod's
  energy discretised here (midpoint rule; nothing of the derivation).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.numerics.stability import count_form
from helpers import REPO
from rod_hessian import chain_hessian

PLANAR = REPO / "equations" / "cosserat_planar.py"
ROD = REPO / "equations" / "cosserat_rod.py"
#: runs/rotating_arm.toml's (eps, P) pairs
ARM = [(e, P) for e in (0.25, 0.5) for P in (math.pi ** 2 / 4, 9 * math.pi ** 2 / 4)]
#: the stiffnesses of the limit: EA = k, GA = k / 3 (the ratio of a solid section, roughly)
STIFF = (1e3, 2e3, 4e3)


@pytest.fixture(scope="module")
def planar():
    return ea.load_problem(PLANAR)


def _folds(problem, params):
    """The folds of psi from the straight rod (one direction; the other is its mirror image):
    their psi, and the index before and after each, in the order met."""
    (branch,) = ea.continuation(problem, {**problem.defaults(), **params}, "psi",
                                bounds=(-6 * math.pi, 6 * math.pi), ds_max=1.0)
    out, before = [], branch.points[0].index
    for pt in branch.points:
        if pt.type == "LP":
            out.append((pt.params["psi"], before, pt.ordinates.get("gamma")))
        if pt.index >= 0 and pt.type not in ("LP", "BP"):
            before = pt.index
    return out, [pt.index for pt in branch.points if pt.type not in ("LP", "BP")]


def test_the_planar_rod_tends_to_the_elastica_at_rate_one_over_stiffness(planar):
    """Every fold of the rotating arm at EA = k, GA = k / 3, k = 1000, 2000, 4000: the gaps to
    the elastica's fold halve as k doubles (the rate log2(d(k) / d(2k)) within 0.05 of 1), and
    Richardson's extrapolation R = 2 psi(2k) - psi(k), whose error is -b / (2 k^2) for psi(k) =
    psi_inf + a / k + b / k^2, meets the elastica's fold within two thirds of |R(1000, 2000) -
    R(2000, 4000)| (= 3 b / 8e6: R(2000, 4000)'s own error is a third of it) plus 1e-8; the
    index before each fold is the elastica's."""
    elastica = ea.load_problem("elastica_lever_arm")
    for eps, P in ARM:
        ref, _ = _folds(elastica, {"eps": eps, "P": P})
        rows = [_folds(planar, {"eps": eps, "P": P, "EA": k, "GA": k / 3})[0] for k in STIFF]
        assert [len(r) for r in rows] == [len(ref)] * 3
        for j, (psi, index, _) in enumerate(ref):
            got = [r[j][0] for r in rows]
            assert [r[j][1] for r in rows] == [index] * 3
            gaps = [g - psi for g in got]
            for a, b in zip(gaps, gaps[1:]):
                assert abs(math.log2(a / b) - 1) < 0.05
            r12, r23 = 2 * got[1] - got[0], 2 * got[2] - got[1]
            assert abs(r23 - psi) <= 2 / 3 * abs(r12 - r23) + 1e-8


def test_equal_stiffnesses_give_the_elastica_s_folds_exactly(planar):
    """GA = EA = S, no weight: r' = d3 + F / S, the moment balance m' = -(d3 x F).e_z is the
    elastica's, so its folds are the elastica's to the fold tolerance (1e-7 in psi) at any S,
    the index on every stretch the same, and gamma = -(F / P).(r(1) + a) less P / S."""
    elastica = ea.load_problem("elastica_lever_arm")
    for eps, P in ARM[:3]:
        ref, ref_index = _folds(elastica, {"eps": eps, "P": P})
        got, got_index = _folds(planar, {"eps": eps, "P": P, "EA": 50.0, "GA": 50.0})
        assert len(got) == len(ref) and got_index[0] == ref_index[0]
        for (psi, index, gamma), (mine, mine_index, my_gamma) in zip(ref, got):
            assert abs(mine - psi) < 1e-7
            assert mine_index == index
            assert abs(my_gamma - (gamma - P / 50.0)) < 1e-6


def _planar_h(p, y):
    """The Hamiltonian m theta' + n.r' - L of the planar rod at the states y (rows theta, m,
    x, y, nx, ny), with the Legendre map's inverse written out: theta' = m + u1, n_b = (n.d2,
    n.d3) = (GA (v2 - v2hat), EA (v3 - v3hat))."""
    theta, m, _, yy, nx, ny = y
    n2 = nx * np.cos(theta) + ny * np.sin(theta)
    n3 = -nx * np.sin(theta) + ny * np.cos(theta)
    return (m * m / 2 + m * p["u1"] + n2 ** 2 / (2 * p["GA"]) + n3 ** 2 / (2 * p["EA"])
            + n2 * p["v2"] + n3 * p["v3"] - p["g"] * yy)


def test_the_heavy_planar_rod_balances_forces_and_keeps_its_hamiltonian(planar):
    """A heavy rod with an intrinsic curvature (g = 3, u1 = 0.4: continued in u1 from the
    straight rod) turned by psi: at
    every point of the branch, n(s) = F - g (1 - s) e_y on the profile (linear in s, which the
    cubic Hermite interpolant holds exactly: to rounding), and H is constant along s to the
    collocation's accuracy (1e-6 relative). Breaking either (the weight's sign in H) fails."""
    p = {**planar.defaults(), "eps": 0.3, "P": 4.0, "g": 3.0, "u1": 0.0, "v2": 0.0,
         "GA": 200.0, "EA": 600.0}
    bent = ea.continuation(planar, p, "u1", bounds=(0, 0.4), ds_max=0.2)
    end = bent[0].labelled[-1]
    assert end.type == "EP" and abs(end.params["u1"] - 0.4) < 1e-9
    (branch,) = ea.continuation(planar, bent.label(end.name), "psi", bounds=(-1.0, 1.0),
                                ds_max=0.3)
    assert len(branch.points) > 5
    grid = np.linspace(0, 1, branch.points[0].profile.shape[1])
    for pt in branch.points:
        q, y = pt.params, pt.profile
        force = q["P"] * np.array((math.sin(q["alpha"]), -math.cos(q["alpha"])))
        assert np.allclose(y[4], force[0], atol=1e-10)
        assert np.allclose(y[5], force[1] - q["g"] * (1 - grid), atol=1e-10)
        h = _planar_h(q, y)
        assert np.ptp(h) < 1e-6 * (1 + np.max(np.abs(h)))
        broken = _planar_h({**q, "g": -q["g"]}, y)
        assert np.ptp(broken) > 1e-3


# ---- the index two ways -----------------------------------------------------------------

def _planar_state(rng, p):
    """A smooth random configuration (theta, r) that is no equilibrium, with the momenta the
    Legendre map gives it (m = theta' - u1, n = GA (v2 - v2hat) d2 + EA (v3 - v3hat) d3), as a
    function of s: its states, and theta, r and their derivatives for the discretisation."""
    ct, cx, cy = rng.normal(size=(3, 4)) * np.array((1.5, 0.3, 0.3))[:, None]

    def fields(s):
        s = np.asarray(s, dtype=float)
        theta = p["theta0"] + ct[0] * s + ct[1] * s ** 2 + ct[2] * np.sin(3 * s)
        dtheta = ct[0] + 2 * ct[1] * s + 3 * ct[2] * np.cos(3 * s)
        # r' = d3 (1 + strain) + d2 shear, a random strain of a tenth
        stretch = 1 + cx[0] * s + cx[1] * np.cos(2 * s)
        shear = cy[0] + cy[1] * s ** 2
        return theta, dtheta, stretch, shear

    def state(s):
        s = np.asarray(s, dtype=float)
        theta, dtheta, stretch, shear = fields(s)
        d2 = np.array((np.cos(theta), np.sin(theta)))
        d3 = np.array((-np.sin(theta), np.cos(theta)))
        n = p["GA"] * (shear - p["v2"]) * d2 + p["EA"] * (stretch - p["v3"]) * d3
        # r itself does not enter the second variation (the weight is linear in it)
        return np.vstack((theta, dtheta - p["u1"], np.zeros_like(s), np.zeros_like(s), n))
    return fields, state


def _planar_hessian(p, fields, n, delta=1e-4):
    """The Hessian in (theta_j, x_j, y_j), j = 1..n, of the rod discretised on n intervals
    (midpoint rule, theta_0 = theta0 and r_0 = 0 clamped), at theta(s_j) and r(s_j) = int_0^s
    r' (Gauss-Legendre, r' = stretch d3 + shear d2), by central differences of each term::

        E_h = sum_j h [ (dtheta/h - u1)^2/2 + GA (d2(tbar).dr/h - v2)^2/2
                        + EA (d3(tbar).dr/h - v3)^2/2 + g ybar ] - F.(r_n + eps a(theta_n)).
    """
    s = np.linspace(0, 1, n + 1)
    x, w = np.polynomial.legendre.leggauss(8)
    theta = fields(s)[0]
    r = np.zeros((2, n + 1))
    for j in range(n):
        t = s[j] + (x + 1) / (2 * n)
        th, _, stretch, shear = fields(t)
        rate = stretch * np.array((-np.sin(th), np.cos(th))) + shear * np.array(
            (np.cos(th), np.sin(th)))
        r[:, j + 1] = r[:, j] + rate @ w / (2 * n)
    h = 1.0 / n
    z = np.vstack((theta, r))                                   # (3, n + 1)

    def interval(a, b):
        tb = 0.5 * (a[0] + b[0])
        dr = (b[1:] - a[1:]) / h
        v2 = np.cos(tb) * dr[0] + np.sin(tb) * dr[1]
        v3 = -np.sin(tb) * dr[0] + np.cos(tb) * dr[1]
        return h * (((b[0] - a[0]) / h - p["u1"]) ** 2 / 2 + p["GA"] * (v2 - p["v2"]) ** 2 / 2
                    + p["EA"] * (v3 - p["v3"]) ** 2 / 2 + p["g"] * 0.5 * (a[2] + b[2]))

    pair = np.vstack((z[:, :-1], z[:, 1:]))                     # (6, n)
    big = chain_hessian(lambda q: interval(q[:3], q[3:]), pair, delta)
    # the arm: -F.eps (sin(psi - theta_n), cos(psi - theta_n)), second derivative in theta_n
    f = p["P"] * np.array((math.sin(p["alpha"]), -math.cos(p["alpha"])))
    t = theta[-1]
    big[-3, -3] += p["eps"] * (f[0] * math.sin(p["psi"] - t) + f[1] * math.cos(p["psi"] - t))
    return big[3:, 3:]


def _discrete_index(p, fields, n):
    """(number of negative eigenvalues, smallest |eigenvalue|) of the discrete Hessian with the
    lumped mass h (the eigenvalues approximate the second variation's)."""
    eig = np.linalg.eigvalsh(_planar_hessian(p, fields, n) * n)
    return int(np.sum(eig < 0)), eig


def test_the_planar_index_is_the_discretised_energy_s_inertia(planar):
    """At random states (random loads, arms, stiffnesses 5..60, intrinsic strains) the derived
    second variation's direct count is the number of negative eigenvalues of the discretised
    energy's Hessian at n = 200, where the lowest eigenvalues are decided: each at least 5
    times its change from n = 100 (second order: the error at 200 is a third of it); at
    least six decided states, with indices from 0 to at least 2."""
    rng = np.random.default_rng(49)
    decided, seen = 0, set()
    for _ in range(14):
        p = {**planar.defaults(), "P": rng.uniform(-30, 30), "eps": rng.uniform(-1, 1),
             "psi": rng.uniform(-3, 3), "alpha": rng.uniform(-3, 3),
             "theta0": rng.uniform(-3, 3), "GA": rng.uniform(5, 60), "EA": rng.uniform(5, 60),
             "g": rng.uniform(-5, 5), "u1": rng.uniform(-1, 1), "v2": rng.uniform(-0.1, 0.1),
             "v3": rng.uniform(0.8, 1.2)}
        fields, state = _planar_state(rng, p)
        fine, coarse = _discrete_index(p, fields, 200), _discrete_index(p, fields, 100)
        low = fine[1][:8]
        change = np.abs(low - coarse[1][:8])
        if np.any(np.abs(low) < 5 * change):
            continue
        direct = count_form(lambda pts: planar.second_variation(pts, state(pts), p),
                            np.linspace(0, 1, 101)).index
        assert direct == fine[0]
        decided += 1
        seen.add(direct)
    assert decided >= 6 and min(seen) == 0 and max(seen) >= 2


# ---- the spatial rod ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def rod():
    return ea.load_problem(ROD)


def test_the_spatial_rod_s_folds_are_the_kirchhoff_rod_s(rod):
    """The identity of the planar rod's test above in space: with S I and no weight, n = F,
    r' = d3 + F / S and m' = -r' x n = -d3 x F, the Kirchhoff rod's balance: at S = 50 every
    fold of rotating_arm_3d's pairs (b2 = 2; the fourth pair's long branch left to the
    docs' command) is the Kirchhoff rod's to 1e-7, with its index and parts, and gamma less
    P / S."""
    kirchhoff = ea.load_problem("kirchhoff_lever_arm")
    for eps, P in ARM[:3]:
        ref, ref_index = _folds(kirchhoff, {"eps": eps, "P": P, "b2": 2.0})
        got, got_index = _folds(rod, {"eps": eps, "P": P, "b2": 2.0, "S": 50.0})
        assert len(got) == len(ref) and got_index[0] == ref_index[0]
        for (psi, index, gamma), (mine, mine_index, my_gamma) in zip(ref, got):
            assert abs(mine - psi) < 1e-7
            assert mine_index == index
            assert abs(my_gamma - (gamma - P / 50.0)) < 1e-6


def _rod_h(p, y):
    """The Hamiltonian m_b.u + n.r' - L of the spatial rod at the states y (rows r, q, m, n),
    the Legendre inverse written out (u = K^-1 m_b + u_hat, r' = n / S + R v_hat)::

        H = m_b.K^-1 m_b / 2 + m_b.u_hat + |n|^2 / (2 S) + n_b.v_hat - g y."""
    from elastica_auto.equations.kirchhoff_lever_arm import rotation
    rot = rotation(y[3:7])
    mb = np.einsum("jim,jm->im", rot, y[7:10])
    nb = np.einsum("jim,jm->im", rot, y[10:13])
    k = np.array((1.0, p["b2"], p["c"]))[:, None]
    uh = np.array((p["u1"], p["u2"], p["u3"]))[:, None]
    vh = np.array((p["v1"], p["v2"], p["v3"]))[:, None]
    return (np.sum(mb * mb / k, axis=0) / 2 + np.sum(mb * uh, axis=0)
            + np.sum(y[10:13] ** 2, axis=0) / (2 * p["S"]) + np.sum(nb * vh, axis=0)
            - p["g"] * y[1])


def test_the_heavy_spatial_rod_balances_forces_and_keeps_its_hamiltonian(rod):
    """A heavy, pre-curved rod (g = 3, u1 = 0.4 continued from the straight rod, S = 300)
    whose load is tilted out of its plane (beta from 0 to 0.6: non-planar states): at every
    point n(s) = F - g (1 - s) e_y to rounding and H constant along s to 1e-6 (relative),
    |q| = 1 to 1e-9; with the weight's sign broken in H, not."""
    from elastica_auto.equations.kirchhoff_lever_arm import load
    p = {**rod.defaults(), "eps": 0.3, "P": 4.0, "g": 3.0, "S": 300.0, "b2": 1.5}
    bent = ea.continuation(rod, p, "u1", bounds=(0, 0.4), ds_max=0.2)
    end = bent[0].labelled[-1]
    assert end.type == "EP" and abs(end.params["u1"] - 0.4) < 1e-9
    (branch,) = ea.continuation(rod, bent.label(end.name), "beta", bounds=(0.0, 0.6),
                                ds_max=0.2)
    assert len(branch.points) > 3 and abs(branch.points[-1].params["beta"] - 0.6) < 1e-9
    assert abs(branch.points[-1].ordinates["z1"]) > 1e-2
    grid = np.linspace(0, 1, branch.points[0].profile.shape[1])
    for pt in branch.points:
        q, y = pt.params, pt.profile
        force = load(q)[:, None] - q["g"] * np.outer((0.0, 1.0, 0.0), 1 - grid)
        assert np.allclose(y[10:13], force, atol=1e-10)
        assert pt.ordinates["qnorm"] < 1e-9
        h = _rod_h(q, y)
        assert np.ptp(h) < 1e-6 * (1 + np.max(np.abs(h)))
        assert np.ptp(_rod_h({**q, "g": -q["g"]}, y)) > 1e-3


@pytest.mark.parametrize("which", ["planar", "rod"])
def test_the_straight_starts_solve_the_derived_equations(which, planar, rod):
    """The straight, compressed (or stretched) heavy rod of each ``exact_start`` along the
    load line (upright and hanging, a weight, a stretch, a load and, in space, a twist):
    y' = rhs(s, y) against central differences of the start (1e-7) and bc(y(0), y(1)) = 0 to
    1e-12; None where the load leaves the line."""
    problem = planar if which == "planar" else rod
    s = np.linspace(0, 1, 41)
    h = 1e-5
    for theta0, P, g in ((0.0, 3.0, 2.0), (math.pi, -2.0, 1.5), (0.0, -4.0, 0.0)):
        p = {**problem.defaults(), "theta0": theta0, "alpha": theta0, "P": P, "g": g,
             "psi": math.pi, "v3": 1.1}
        p.update({"EA": 40.0, "GA": 15.0} if which == "planar" else {"S": 30.0, "u3": 0.7})
        y = problem.exact_start(s, p)
        slope = (problem.exact_start(s + h, p) - problem.exact_start(s - h, p)) / (2 * h)
        assert np.max(np.abs(slope - problem.rhs(s, y, p))) < 1e-7
        assert np.max(np.abs(problem.bc(y[:, 0], y[:, -1], p))) < 1e-12
        assert problem.exact_start(s, {**p, "alpha": theta0 + 0.1}) is None


def _rod_state(rng, rod_module, p):
    """A smooth random configuration of the spatial rod (no equilibrium): the frame q(s) a
    normalised quadratic, r(s) = int_0^s (d3 (1 + e3) + e1 d1 + e2 d2) with random smooth
    strains e; the momenta the Legendre map gives it, m = R K (u - u_hat), n = S (r' -
    R v_hat). Returns (frames and positions at any s, the states at any s)."""
    c = rng.normal(size=(3, 4))
    e = rng.normal(size=(3, 3)) * 0.15
    x, w = np.polynomial.legendre.leggauss(12)

    def unit(s):
        q = c[0][:, None] + c[1][:, None] * s + c[2][:, None] * s ** 2
        return q / np.sqrt(np.sum(q * q, axis=0))

    def rate(s):
        rot = rod_module.rotation(unit(s))
        v = np.vstack((e[0, 0] + e[0, 1] * s, e[1, 0] * np.cos(2 * s) + e[1, 1],
                       1 + e[2, 0] * s + e[2, 1] * s ** 2))
        return np.einsum("ijm,jm->im", rot, v)

    def position(s):
        out = np.zeros((3, len(s)))
        for k, sk in enumerate(s):
            t = 0.5 * sk * (x + 1)
            out[:, k] = rate(t) @ (0.5 * sk * w)
        return out

    def configuration(s):
        s = np.asarray(s, dtype=float)
        return rod_module.rotation(unit(s)).transpose(2, 0, 1), position(s)

    def state(s):
        s = np.asarray(s, dtype=float)
        q = unit(s)
        dq = unit(s + 1e-30j).imag / 1e-30
        u = 2 * rod_module.qmul(np.vstack((q[0], -q[1:])), dq)[1:]
        rot = rod_module.rotation(q)
        k = np.array((1.0, p["b2"], p["c"]))[:, None]
        uh = np.array((p["u1"], p["u2"], p["u3"]))[:, None]
        vh = np.array((p["v1"], p["v2"], p["v3"]))
        m = np.einsum("ijm,jm->im", rot, k * (u - uh))
        n = p["S"] * (rate(s) - np.einsum("ijm,j->im", rot, vh))
        return np.vstack((position(s), q * (1 + 0.3 * np.sin(2 * s)), m, n))
    return configuration, state


def _rod_hessian(rod_module, p, configuration, n, delta=1e-4):
    """The Hessian in (r_j, w_j), j = 1..n, of the spatial rod discretised on n intervals:
    frames R_j -> exp([w_j]_x) R_j and positions r_j at s_j = j / n (R_0, r_0 clamped), with
    curvatures log(R_j^T R_(j+1)) / h and the midpoint frame M_j = R_j exp(log(R_j^T
    R_(j+1)) / 2) (the midpoint rule, second order)::

        E_h = sum_j h [ (u_j - u_hat).K (u_j - u_hat)/2 + S |(r_(j+1) - r_j)/h - M_j v_hat|^2/2
                        + g (y_j + y_(j+1))/2 ] - F.(r_n + eps R_n a_b),

    each interval's 12 x 12 block by central differences (the arm's 3 x 3 likewise)."""
    from rod_hessian import expm, logm
    s = np.linspace(0, 1, n + 1)
    frames, r = configuration(s)
    h = 1.0 / n
    kk = np.array((1.0, p["b2"], p["c"]))
    uh = np.array((p["u1"], p["u2"], p["u3"]))
    vh = np.array((p["v1"], p["v2"], p["v3"]))

    def interval(z):
        ra, wa, rb, wb = z[0:3].T, z[3:6].T, z[6:9].T, z[9:12].T
        fa, fb = expm(wa) @ frames[:-1], expm(wb) @ frames[1:]
        rel = logm(np.swapaxes(fa, -1, -2) @ fb)
        du = rel / h - uh
        mid = fa @ expm(0.5 * rel)
        gap = (rb - ra) / h - mid @ vh
        return h * (0.5 * np.einsum("mi,i,mi->m", du, kk, du)
                    + 0.5 * p["S"] * np.sum(gap * gap, axis=1)
                    + p["g"] * 0.5 * (ra[:, 1] + rb[:, 1]))

    zero = np.zeros((3, n))
    big = chain_hessian(interval, np.vstack((r[:, :-1], zero, r[:, 1:], zero)), delta)
    force, arm = rod_module.load(p), p["eps"] * rod_module.arm_body(p)

    def tip(wv):
        return -force @ (expm(wv) @ frames[-1] @ arm)
    for i in range(3):
        for k in range(3):
            total = 0.0
            for si in (1, -1):
                for sk in (1, -1):
                    wv = np.zeros(3)
                    wv[i] += si * delta
                    wv[k] += sk * delta
                    total += si * sk * tip(wv)
            big[-3 + i, -3 + k] += total / (4 * delta ** 2)
    return big[6:, 6:]


def test_the_spatial_index_is_the_discretised_rod_s_inertia(rod):
    """As the planar test: at random frame and position fields (no equilibria, |q| != 1 in
    the states) and random parameters (loads, arms, angles, b2, c, S 5..40, weights,
    intrinsic strains), the direct count of the derived second variation equals the number of
    negative eigenvalues of the finite-difference Hessian of the rod discretised above on 160
    intervals, where its lowest eigenvalues are decided (each at least 5 times its change from
    80); at least four decided states, with at least three different indices."""
    import elastica_auto.equations.kirchhoff_lever_arm as frames
    rng = np.random.default_rng(4949)
    decided, seen = 0, set()
    for _ in range(6):
        p = {**rod.defaults(), "P": rng.uniform(-25, 25), "eps": rng.uniform(-1, 1),
             "psi": rng.uniform(-3, 3), "alpha": rng.uniform(-3, 3), "beta": rng.uniform(-1, 1),
             "chi": rng.uniform(-3, 3), "theta0": rng.uniform(-3, 3), "phi0": rng.uniform(-3, 3),
             "b2": rng.uniform(0.5, 2.5), "c": rng.uniform(0.4, 1.5), "S": rng.uniform(5, 40),
             "g": rng.uniform(-5, 5), "u1": rng.uniform(-1, 1), "u2": rng.uniform(-1, 1),
             "u3": rng.uniform(-1, 1), "v1": rng.uniform(-0.1, 0.1),
             "v2": rng.uniform(-0.1, 0.1), "v3": rng.uniform(0.8, 1.2)}
        configuration, state = _rod_state(rng, frames, p)
        eig = {nn: np.linalg.eigvalsh(_rod_hessian(frames, p, configuration, nn) * nn)
               for nn in (80, 160)}
        low = eig[160][:8]
        if np.any(np.abs(low) < 5 * np.abs(low - eig[80][:8])):
            continue
        direct = count_form(lambda pts: rod.second_variation(pts, state(pts), p),
                            np.linspace(0, 1, 101)).index
        assert direct == int(np.sum(eig[160] < 0))
        decided += 1
        seen.add(direct)
    assert decided >= 4 and len(seen) >= 3


def _labels(problem, params):
    """(type, psi, index) of every LP and BP of the psi branch from the straight rod, and the
    index at the points between them."""
    (branch,) = ea.continuation(problem, {**problem.defaults(), **params}, "psi",
                                bounds=(-6 * math.pi, 6 * math.pi), ds_max=1.0)
    return ([(pt.type, pt.params["psi"]) for pt in branch.points if pt.type in ("LP", "BP")],
            [pt.index for pt in branch.points if pt.type not in ("LP", "BP")])


def test_the_isotropic_rod_s_symmetric_points_are_the_kirchhoff_rod_s(rod):
    """b2 = 1: at psi = k pi the bent rod with its arm along d3(1) lies on a circle of
    equilibria (the turn about the load line); with the module's symmetry hook its zero mode
    is left out of the count and the branch points are placed there. The labels (folds and
    branch points, their psi to 1e-7) and the index at every other point are the Kirchhoff
    rod's at S = 50 (P = pi^2/4, both arms). Without the hook the labels differ."""
    kirchhoff = ea.load_problem("kirchhoff_lever_arm")
    for eps, P in (ARM[0], ARM[2]):
        ref, ref_index = _labels(kirchhoff, {"eps": eps, "P": P, "b2": 1.0})
        got, got_index = _labels(rod, {"eps": eps, "P": P, "b2": 1.0, "S": 50.0})
        assert [t for t, _ in got] == [t for t, _ in ref] and "BP" in [t for t, _ in ref]
        assert max(abs(a - b) for (_, a), (_, b) in zip(got, ref)) < 1e-7
        assert got_index == ref_index
