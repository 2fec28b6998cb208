"""The tendon-driven robot (equations/tendon_robot.py; issue 49 item 2; docs/soft-robots.md,
"Tendon-driven robots") against what is independent of its derivation:

* a closed form: with no weight, the total force and moment vanish everywhere, so the strains
  are the same at every s (the minimiser of the density: u2 = tau1 delta / b2, v = (1 -
  tau1 / S) e3 for tendon 1 alone) and the backbone is an arc of a circle;
* a shooting solution written here (not the engine's): the strains (v, u) as states, their
  derivatives from the balances in the body (n_b' = -u x n_b + R^T (0, g, 0), m_b' = -u x m_b
  - v x n_b) through the 6x6 Hessian of the density (the tendons' P_i / |t_i| terms: the
  Rucker-Webster form of the tendon robot), integrated by solve_ivp, the base strains found by
  scipy.optimize.root from the naive guess (straight, unstrained): the tip against the
  engine's with a weight at the tip;
* conservation along computed solutions: n = (0, -P, 0) and m + r x n = r(1) x n(1) at every
  point (no distributed load).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import root

import elastica_auto as ea
from helpers import REPO

ROBOT = REPO / "equations" / "tendon_robot.py"
HELICAL = REPO / "equations" / "tendon_helical.py"


@pytest.fixture(scope="module")
def robot():
    return ea.load_problem(ROBOT)


@pytest.fixture(scope="module")
def helical():
    return ea.load_problem(HELICAL)


def _hat(a):
    return np.array(((0, -a[2], a[1]), (a[2], 0, -a[0]), (-a[1], a[0], 0)))


def _offsets(p, s=0.0):
    """Each tendon's body offset d_i(s) = delta (cos w, sin w, 0), w = a_i + 2 pi k s, with
    its derivatives d_i' = 2 pi k e3 x d_i and d_i'' = -(2 pi k)^2 d_i (parallel routing at
    k = 0)."""
    turn = 2 * math.pi * p.get("k", 0.0)
    out = []
    for i in range(4):
        w = i * math.pi / 2 + turn * s
        d = p["delta"] * np.array((math.cos(w), math.sin(w), 0.0))
        out.append((d, turn * np.array((-d[1], d[0], 0.0)), -turn ** 2 * d))
    return out


def _body(v, u, p, s=0.0):
    """n_b = S diag(1, 1, se) (v - e3) + sum tau_i t_i / |t_i|, m_b = K u + sum tau_i d_i x
    t_i / |t_i|, t_i = v + u x d_i + d_i' (written here from the energy), their Jacobian in
    (v, u) and their derivative in s at (v, u) held (through d_i(s): d/ds t_i = u x d_i' +
    d_i'', the Rucker-Webster terms of a routing that is not parallel)."""
    K = np.diag((1.0, p["b2"], p["c"]))
    Kse = p["S"] * np.diag((1.0, 1.0, p["se"]))
    nb = Kse @ (v - np.array((0, 0, 1.0)))
    mb = K @ u
    J = np.zeros((6, 6))
    J[:3, :3] = Kse
    J[3:, 3:] = K
    ds = np.zeros(6)
    for i, (d, d1, d2) in enumerate(_offsets(p, s)):
        tau = p[f"tau{i + 1}"]
        if tau == 0:
            continue
        t = v + np.cross(u, d) + d1
        length = np.linalg.norm(t)
        unit = t / length
        proj = (np.eye(3) - np.outer(unit, unit)) / length      # d(unit)/dt
        D = _hat(d)                                              # u x d = -D u
        nb += tau * unit
        mb += tau * np.cross(d, unit)
        J[:3, :3] += tau * proj
        J[:3, 3:] -= tau * proj @ D
        J[3:, :3] += tau * D @ proj
        J[3:, 3:] -= tau * D @ proj @ D
        dunit = proj @ (np.cross(u, d1) + d2)
        ds[:3] += tau * dunit
        ds[3:] += tau * (np.cross(d1, unit) + np.cross(d, dunit))
    return nb, mb, J, ds


def _rhs(s, y, p):
    R, v, u = y[3:12].reshape(3, 3), y[12:15], y[15:18]
    nb, mb, J, ds = _body(v, u, p, s)
    dnb = -np.cross(u, nb) + R.T @ np.array((0, p["g"], 0))
    dmb = -np.cross(u, mb) - np.cross(v, nb)
    dvu = np.linalg.solve(J, np.concatenate((dnb, dmb)) - ds)
    return np.concatenate((R @ v, (R @ _hat(u)).ravel(), dvu))


def _shoot(p, base):
    y0 = np.concatenate((np.zeros(3), np.eye(3).ravel(), base))
    return solve_ivp(_rhs, (0, 1), y0, args=(p,), method="DOP853", rtol=1e-11, atol=1e-12)


def _residual(base, p):
    sol = _shoot(p, base)
    if sol.status != 0:
        return np.full(6, 1e6)
    y = sol.y[:, -1]
    R = y[3:12].reshape(3, 3)
    nb, mb, _, _ = _body(y[12:15], y[15:18], p, 1.0)
    return np.concatenate((nb - R.T @ np.array((0, -p["P"], 0)), mb))


def shooting_tip(p):
    """The tip r(1) by shooting from the naive guess (straight, unstrained), or None where
    root does not converge."""
    guess = np.array((0, 0, 1.0, 0, 0, 0))
    found = root(_residual, guess, args=(p,), method="hybr", options={"xtol": 1e-12})
    if not found.success or np.max(np.abs(found.fun)) > 1e-8:
        return None
    return _shoot(p, found.x).y[:3, -1]


def test_without_weight_the_backbone_is_an_arc(robot):
    """Tendon 1 (at d1) alone, g = P = 0: the tip on the arc of curvature u2 = tau1 delta /
    b2 and length v3 = 1 - tau1 / S, x(1) = v3 (1 - cos u2) / u2, z(1) = v3 sin u2 / u2,
    beyond a full turn (u2 = 2 pi at tau1 = 126), with index 0."""
    p = robot.defaults()
    taus = [20.0, 60.0, 130.0, 180.0]
    br = ea.continuation(robot, {"tau1": 0.0}, "tau1", bounds=(0, 200), uz=taus,
                         ds_max=10.0)[0]
    hits = [pt for pt in br.points if pt.type == "UZ"]
    assert [pt.params["tau1"] for pt in hits] == pytest.approx(taus)
    for pt in hits:
        tau = pt.params["tau1"]
        u2, v3 = tau * p["delta"] / p["b2"], 1 - tau / p["S"]
        tip = (v3 * (1 - math.cos(u2)) / u2, 0.0, v3 * math.sin(u2) / u2)
        got = (pt.ordinates["x1"], pt.ordinates["y1"], pt.ordinates["z1"])
        assert got == pytest.approx(tip, abs=1e-7)
        assert pt.index == 0
    assert set(br.columns["index"]) == {0}


@pytest.fixture(scope="module")
def lifting(robot):
    """Tendon 2 (at d2 = e_y) lifting a weight P = 1 at the tip: the weight applied first
    (continued in P), then the tension."""
    weighed = ea.continuation(robot, {"tau2": 0.0}, "P", bounds=(0, 1.0), ds_max=0.5)
    return ea.continuation(robot, weighed.label("EP2"), "tau2", bounds=(0, 60),
                           uz=[2.0, 5.0, 10.0, 20.0, 40.0], ds_max=5.0)[0]


def test_the_tip_is_the_shooting_solution_s(robot, lifting):
    """At tensions where the shooting converges from the naive guess, the engine's tip is
    the shooting's to 1e-6 (the engine's mesh tolerance; the shooting's rtol is 1e-11)."""
    compared = 0
    for pt in lifting.points:
        if pt.type != "UZ":
            continue
        tip = shooting_tip({**robot.defaults(), **pt.params})
        if tip is None:
            continue
        compared += 1
        got = (pt.ordinates["x1"], pt.ordinates["y1"], pt.ordinates["z1"])
        np.testing.assert_allclose(got, tip, atol=1e-6)
    assert compared >= 3


def test_force_and_moment_are_conserved(robot, lifting):
    """No distributed load: n(s) = (0, -P, 0) and m(s) + r(s) x n(s) = r(1) x n(1) at every
    mesh point of every computed solution."""
    for pt in lifting.points[::3]:
        r, m, n = pt.profile[0:3], pt.profile[7:10], pt.profile[10:13]
        np.testing.assert_allclose(n, np.outer((0, -pt.params["P"], 0), np.ones(n.shape[1])),
                                   atol=1e-8)
        total = m + np.cross(r, n, axis=0)
        np.testing.assert_allclose(total, total[:, -1:] * np.ones(n.shape[1]), atol=1e-7)


def test_where_newton_s_inverse_sticks_the_branch_ends_mx_not_internal(robot):
    """Near tau1 = 238 (1.9 turns, the tendon's length 0.17 per unit) the states between the
    nodes fall where the Legendre inverse's minimiser is the tendon's zero length (the kink of
    |t|), which Newton does not reach: the error estimate is NaN there. The corrector treats
    that as a failed step (shortens it, then ends the branch MX with that reason), never as
    an internal error.
    (The branch's solutions up to there are the closed-form arc's.)"""
    br = ea.continuation(robot, {"tau1": 0.0}, "tau1", bounds=(0, 300),
                         ds_max=10.0)[0]
    last = br.points[-1]
    assert last.type == "MX"
    assert "error estimate is not finite" in br.message
    assert "internal" not in br.message.lower()
    assert 217 < last.params["tau1"] < 285.7


def _random_state(rng, p):
    """A smooth random configuration (no equilibrium): the frame q(s) a normalised quadratic,
    r(s) = int_0^s R v with random smooth body strains v; the momenta the Legendre map of the
    energy gives it (n = R n_b(v, u), m = R m_b(v, u), `_body`). Returns (frames and positions
    at any s, the states at any s)."""
    import elastica_auto.equations.kirchhoff_lever_arm as frames
    c = rng.normal(size=(3, 4))
    e = rng.normal(size=(3, 3)) * 0.15
    x, w = np.polynomial.legendre.leggauss(12)

    def unit(s):
        q = c[0][:, None] + c[1][:, None] * s + c[2][:, None] * s ** 2
        return q / np.sqrt(np.sum(q * q, axis=0))

    def body(s):
        return np.vstack((e[0, 0] + e[0, 1] * s, e[1, 0] * np.cos(2 * s) + e[1, 1],
                          1 + e[2, 0] * s + e[2, 1] * s ** 2))

    def rate(s):
        return np.einsum("ijm,jm->im", frames.rotation(unit(s)), body(s))

    def position(s):
        out = np.zeros((3, len(s)))
        for k, sk in enumerate(s):
            out[:, k] = rate(0.5 * sk * (x + 1)) @ (0.5 * sk * w)
        return out

    def configuration(s):
        s = np.asarray(s, dtype=float)
        return frames.rotation(unit(s)).transpose(2, 0, 1), position(s)

    def state(s):
        s = np.asarray(s, dtype=float)
        q = unit(s)
        dq = unit(s + 1e-30j).imag / 1e-30
        u = 2 * frames.qmul(np.vstack((q[0], -q[1:])), dq)[1:]
        rot = frames.rotation(q)
        v = body(s)
        nm = np.array([np.concatenate(_body(v[:, k], u[:, k], p, sk)[:2])
                       for k, sk in enumerate(s)]).T
        n = np.einsum("ijm,jm->im", rot, nm[:3])
        m = np.einsum("ijm,jm->im", rot, nm[3:])
        return np.vstack((position(s), q * (1 + 0.3 * np.sin(2 * s)), m, n))
    return configuration, state


def _discrete_hessian(p, configuration, n, delta=1e-4):
    """The Hessian in (r_j, w_j), j = 1..n, of the robot discretised on n intervals: frames
    R_j -> exp([w_j]_x) R_j and positions r_j at s_j = j / n (R_0, r_0 clamped), curvatures
    u_j = log(R_j^T R_(j+1)) / h, the midpoint frame M_j = R_j exp(log(R_j^T R_(j+1)) / 2)
    and v_j = M_j^T (r_(j+1) - r_j) / h (the midpoint rule)::

        E_h = sum_j h [ u_j.K u_j/2 + (v_j - e3).Kse (v_j - e3)/2
                        + sum_i tau_i |v_j + u_j x d_i + d_i'| ]

    (Kse = S diag(1, 1, se); d_i and d_i' at the interval's midpoint, exact; the weights g y
    and P y(1) are linear: no Hessian), each interval's 12 x 12 block by central
    differences."""
    from rod_hessian import chain_hessian, expm, logm
    s = np.linspace(0, 1, n + 1)
    frames, r = configuration(s)
    h = 1.0 / n
    kk = np.array((1.0, p["b2"], p["c"]))
    e3 = np.array((0, 0, 1.0))
    se = np.array((1.0, 1.0, p["se"]))
    mids = [_offsets(p, (j + 0.5) * h) for j in range(n)]
    routes = [(np.array([m[i][0] for m in mids]), np.array([m[i][1] for m in mids]))
              for i in range(4)]

    def interval(z):
        ra, wa, rb, wb = z[0:3].T, z[3:6].T, z[6:9].T, z[9:12].T
        fa, fb = expm(wa) @ frames[:-1], expm(wb) @ frames[1:]
        rel = logm(np.swapaxes(fa, -1, -2) @ fb)
        u = rel / h
        mid = fa @ expm(0.5 * rel)
        v = np.einsum("mji,mj->mi", mid, (rb - ra) / h)
        density = 0.5 * np.einsum("mi,i,mi->m", u, kk, u) + 0.5 * p["S"] * np.einsum(
            "mi,i,mi->m", v - e3, se, v - e3)
        for i, (d, d1) in enumerate(routes):
            density = density + p[f"tau{i + 1}"] * np.linalg.norm(v + np.cross(u, d) + d1,
                                                                    axis=1)
        return h * density

    zero = np.zeros((3, n))
    return chain_hessian(interval, np.vstack((r[:, :-1], zero, r[:, 1:], zero)), delta)[6:, 6:]


def test_the_index_is_the_discretised_energy_s_inertia(robot, helical):
    """At random frame and position fields (no equilibria, |q| != 1 in the states) and random
    tensions, offsets, stiffnesses, every other state with helical tendons (tendon_helical,
    random turns k and extension stiffness se), the direct count of the derived second
    variation equals the number of negative eigenvalues of the finite-difference Hessian of
    the robot discretised above on 160 intervals, where its lowest eigenvalues are decided
    (each at least 5 times its change from 80); at least four decided states, two of them
    helical, with at least two different indices."""
    from elastica_auto.numerics.stability import count_form
    rng = np.random.default_rng(4950)
    decided, seen, turned = 0, set(), 0
    for trial in range(6):
        p = {**robot.defaults(), "delta": rng.uniform(0.03, 0.3), "b2": rng.uniform(0.5, 2.5),
             "c": rng.uniform(0.4, 1.5), "S": rng.uniform(50, 200),
             **{f"tau{i}": rng.uniform(0, 20) for i in range(1, 5)}}
        if trial % 2:
            p.update(se=rng.uniform(1, 3), k=rng.uniform(-1.5, 1.5))
        configuration, state = _random_state(rng, p)
        eig = {nn: np.linalg.eigvalsh(_discrete_hessian(p, configuration, nn) * nn)
               for nn in (80, 160)}
        low = eig[160][:8]
        if np.any(np.abs(low) < 5 * np.abs(low - eig[80][:8])):
            continue
        model = helical if trial % 2 else robot
        direct = count_form(lambda pts: model.second_variation(pts, state(pts), p),
                            np.linspace(0, 1, 101)).index
        assert direct == int(np.sum(eig[160] < 0))
        decided += 1
        turned += p.get("k", 0.0) != 0
        seen.add(direct)
    assert decided >= 4 and len(seen) >= 2 and turned >= 2


def _published():
    """Till's tendon robot statics example (the Rucker-Webster model's demonstration) in SI
    units, nondimensionalised here by the length L and the bending stiffness EI: lengths / L,
    tensions L^2 / EI, weight per length L^3 / EI, GJ / EI, GA L^2 / EI, EA / GA."""
    E, G, rad, rho, grav, L = 200e9, 80e9, 1e-3, 8000.0, 9.81, 0.5
    area, inertia = math.pi * rad ** 2, math.pi * rad ** 4 / 4
    EI = E * inertia
    return {"delta": 0.01506 / L, "b2": 1.0, "c": G * 2 * inertia / EI,
            "S": G * area * L ** 2 / EI, "se": E / G, "g": rho * area * grav * L ** 3 / EI,
            "tension": 15.0 * L ** 2 / EI}


def test_the_published_run_files_hold_the_published_robot():
    """runs/tendon_published_weight.toml's parameters and the published tension 15 N (UZ in
    runs/tendon_published.toml) are the SI values converted above, to the digits written."""
    import tomllib
    pub = _published()
    weight = tomllib.loads((REPO / "runs" / "tendon_published_weight.toml").read_text())
    pulled = tomllib.loads((REPO / "runs" / "tendon_published.toml").read_text())
    params = weight["parameters"]
    for name in ("delta", "c", "S", "se"):
        assert params[name] == pytest.approx(pub[name], rel=1e-4), name
    assert weight["continuation"]["uz"] == [pytest.approx(pub["g"], rel=1e-4)]
    assert pulled["continuation"]["uz"] == [pytest.approx(pub["tension"], rel=1e-4)]


def test_the_published_robot_s_tip_is_the_shooting_solution_s(robot):
    """The published robot (its weight along -e_y, tendon 4 on the -e_y side: the example's
    gravity and tendon 1 along +e_x turned by -90 degrees about e_z, the section being
    round), its weight applied to the straight robot, then tendon 4 pulled: at the published
    15 N and at tensions up to past a half turn the tip is the shooting's from the naive
    guess to 1e-6, in the plane (x = 0), with index 0."""
    pub = _published()
    base = {**robot.defaults(), **{k: pub[k] for k in ("delta", "c", "S", "se")}}
    weighed = ea.continuation(robot, {**base, "g": 0.0}, "g", bounds=(0, 0.25),
                              uz=[pub["g"]], ds_max=0.1)[0]
    taus = [pub["tension"], 60.0, 120.0]
    br = ea.continuation(robot, weighed.label("UZ1"), "tau4", bounds=(0, 130), uz=taus,
                         ds_max=10.0)[0]
    hits = [pt for pt in br.points if pt.type == "UZ"]
    assert [pt.params["tau4"] for pt in hits] == pytest.approx(taus)
    for pt in hits:
        tip = shooting_tip({**base, **pt.params})
        got = (pt.ordinates["x1"], pt.ordinates["y1"], pt.ordinates["z1"])
        np.testing.assert_allclose(got, tip, atol=1e-6)
        assert abs(got[0]) < 1e-9 and pt.index == 0
    assert set(br.columns["index"]) == {0}


def _twisted(p, tau):
    """The straight, uniformly twisted robot under four equal tensions tau on helical
    tendons (docs/soft-robots.md, "Helical routing"): u = u3 e3, v = v3 e3, each tendon's
    t_i = v3 e3 + (u3 + 2 pi k) e3 x d_i of length l = (v3^2 + delta^2 (u3 + 2 pi k)^2)^(1/2);
    the in-section parts of the four pulls cancel, and the axial force and torque
    S se (v3 - 1) + 4 tau v3 / l = 0 and c u3 + 4 tau delta^2 (u3 + 2 pi k) / l = 0 remain:
    (v3, u3) by scipy's fsolve from the untwisted (1, 0)."""
    from scipy.optimize import fsolve
    turn = 2 * math.pi * p.get("k", 0.0)

    def balance(z):
        v3, u3 = z
        length = math.hypot(v3, p["delta"] * (u3 + turn))
        return (p["S"] * p["se"] * (v3 - 1) + 4 * tau * v3 / length,
                p["c"] * u3 + 4 * tau * p["delta"] ** 2 * (u3 + turn) / length)
    return fsolve(balance, (1.0, 0.0), xtol=1e-13)


def test_equal_tensions_on_helical_tendons_twist_the_straight_robot(helical):
    """Four equal tensions tau = 20, continued in the turns k from the parallel robot (k = 0,
    straight: exact): the robot stays straight and twists uniformly against the helix, the
    tip at (0, 0, v3) and its frame turned by u3 about e3, (v3, u3) the two scalar balances
    above, to 1e-8; index 0."""
    tau = 20.0
    p = {**helical.defaults(), **{f"tau{i}": tau for i in range(1, 5)}, "delta": 0.1}
    ks = [0.25, 0.5, 1.0]
    br = ea.continuation(helical, p, "k", bounds=(0, 1.2), uz=ks, ds_max=0.2)[0]
    hits = [pt for pt in br.points if pt.type == "UZ"]
    assert [pt.params["k"] for pt in hits] == pytest.approx(ks)
    for pt in hits:
        v3, u3 = _twisted({**p, **pt.params}, tau)
        got = (pt.ordinates["x1"], pt.ordinates["y1"], pt.ordinates["z1"])
        np.testing.assert_allclose(got, (0, 0, v3), atol=1e-8)
        q = pt.profile[3:7, -1] / np.linalg.norm(pt.profile[3:7, -1])
        np.testing.assert_allclose(q, (math.cos(u3 / 2), 0, 0, math.sin(u3 / 2)), atol=1e-8)
        assert u3 < -0.01 * pt.params["k"] and pt.index == 0
    assert set(br.columns["index"]) == {0}


def test_a_helical_tendon_s_tip_is_the_shooting_solution_s_out_of_the_plane(helical):
    """Tendon 1 alone on half a turn (k = 1/2: from +e_x at the base to -e_x at the tip),
    no weight: the tip is the shooting's (its right side has the helical path's terms d_i'
    and d_i'') from the naive guess to 1e-6 at a few tensions, and out of the plane the
    parallel tendon keeps it in (y(1) = 0 at k = 0)."""
    p = {**helical.defaults(), "k": 0.5}
    taus = [5.0, 10.0, 20.0]
    br = ea.continuation(helical, p, "tau1", bounds=(0, 25), uz=taus, ds_max=5.0)[0]
    hits = [pt for pt in br.points if pt.type == "UZ"]
    assert [pt.params["tau1"] for pt in hits] == pytest.approx(taus)
    for pt in hits:
        tip = shooting_tip({**p, **pt.params})
        got = (pt.ordinates["x1"], pt.ordinates["y1"], pt.ordinates["z1"])
        np.testing.assert_allclose(got, tip, atol=1e-6)
        assert abs(got[1]) > 0.01


def test_at_no_turn_the_helical_robot_is_the_parallel_one(robot, helical):
    """tendon_helical at k = 0 against tendon_robot, two derivations of one energy (the
    helical one through cos and sin of a_i + 2 pi k s and d_i' = 2 pi k e3 x d_i, the
    parallel one with exact offsets): the right side, its Jacobian in the states and the
    second variation's direct count agree at random states with tensions, to Newton's
    tolerance."""
    from elastica_auto.numerics.stability import count_form
    rng = np.random.default_rng(4951)
    s = np.linspace(0, 1, 41)
    for _ in range(3):
        p = {**robot.defaults(), "delta": rng.uniform(0.03, 0.3), "se": rng.uniform(1, 3),
             **{f"tau{i}": rng.uniform(0, 20) for i in range(1, 5)}}
        ph = {**p, "k": 0.0}
        _, state = _random_state(rng, p)
        y = state(s)
        np.testing.assert_allclose(helical.rhs(s, y, ph), robot.rhs(s, y, p),
                                   rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(helical.rhs_jac(s, y, ph), robot.rhs_jac(s, y, p),
                                   rtol=1e-7, atol=1e-7)
        mesh = np.linspace(0, 1, 101)
        assert (count_form(lambda pts: helical.second_variation(pts, state(pts), ph),
                           mesh).index
                == count_form(lambda pts: robot.second_variation(pts, state(pts), p),
                              mesh).index)
