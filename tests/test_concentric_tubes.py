"""Concentric-tube robots (issue 49 item 3; equations/concentric_tubes.py,
examples/three_tubes.py, docs/soft-robots.md).

Each derived module is checked against something derived here, independently of it:

* two tubes: the relative rotation alpha = psi2 - psi1 obeys alpha'' = lambda^2 sin(alpha) on
  the curved section (arclength scaled to [0, 1]), alpha'(1) = 0 at the free tip and beta =
  alpha(0) - tau alpha'(0) at the base (tau = Lt / L, the transmission's torsion spring). A
  shooting from the tip in alpha(1) gives beta as an explicit function of the tip's rotation;
  its folds are the zeros of dbeta/dalpha(1), found by a scan and a root bracket. The
  continuation's folds in beta are these;
* the fold curve in (beta, L): where it turns in L is the snap-free bound in closed form,
  sqrt(c) Lt tan(lambda) = 1 (the linearisation about the opposed tubes alpha = pi at beta =
  pi, derived in docs/soft-robots.md), for two designs; beta moves like the cube of the
  distance along the curve there (beta - pi ~ (L - L_c)^(3/2): a cusp, not a plain turn); and
  below the bound a turn of the base through 2 pi has no fold;
* three tubes, where no closed form is known: the folds in beta3 against a shooting of the
  three coupled angles from the tip (the equilibrium curve at beta2 = 0 followed in the tip's
  rotations, its folds where the Jacobian of the base rotations in the tip's vanishes);
* exact conservation along every solution: the total torque sum_i T_i vanishes (the density
  depends on the relative rotations only, and the tip is free), and the Hamiltonian
  sum_i L T_i^2 / (2 GJ_i) - L W(psi) does not depend on s;
* the index two ways (the direct count and the fold rule) at every point off the folds,
  and against the negative eigenvalues of the Hessian of the energy discretised here
  (midpoint rule on the stored profile), for two tubes and three.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import elastica_auto as ea
from elastica_auto.energy import cache as energy_cache
from elastica_auto.equations import concentric_tubes as ct
from elastica_auto.execution import runfile
from helpers import EXAMPLES, REPO, run_plan

TWO_PI = 2 * math.pi
DEFAULTS = dict(kappa1=1.0, kappa2=1.0, EI1=1.0, EI2=1.0, GJ1=1 / 1.3, GJ2=1 / 1.3, L=1.0,
                Lt=1.0)
#: A second design: unequal tubes and a short transmission (the bound nearer pi/2).
OTHER = dict(kappa1=0.8, kappa2=1.6, EI1=1.0, EI2=0.45, GJ1=0.7, GJ2=0.3, L=1.0, Lt=0.3)
ODE = dict(method="DOP853", rtol=1e-12, atol=1e-13)


@pytest.fixture(autouse=True, scope="module")
def own_cache(tmp_path_factory):
    """The generated code in a folder of this module's own, not the user's cache."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
        mp.delenv(energy_cache.ENV, raising=False)
        yield


@pytest.fixture(scope="module")
def tubes():
    return ea.load_problem("concentric_tubes")


def c_of(p):
    """c = EI1 EI2 kappa1 kappa2 / (EI1 + EI2) (1/GJ1 + 1/GJ2), written here again."""
    return (p["EI1"] * p["EI2"] / (p["EI1"] + p["EI2"]) * p["kappa1"] * p["kappa2"]
            * (1 / p["GJ1"] + 1 / p["GJ2"]))


def base_rotation(a, lam, tau):
    """beta and dbeta/da for the tip rotation alpha(1) = a: alpha'' = lam^2 sin(alpha) and its
    variation w'' = lam^2 cos(alpha) w (w = dalpha/da) integrated from the tip (alpha'(1) = 0,
    w(1) = 1, w'(1) = 0) to the base, beta = alpha(0) - tau alpha'(0)."""
    def f(s, y):
        return [y[1], lam ** 2 * math.sin(y[0]), y[3], lam ** 2 * math.cos(y[0]) * y[2]]
    y0 = solve_ivp(f, (1.0, 0.0), [a, 0.0, 1.0, 0.0], **ODE).y[:, -1]
    return y0[0] - tau * y0[1], y0[2] - tau * y0[3]


def shooting_folds(p):
    """The folds of the two-tube robot by shooting: the tip rotations a in (0, pi) where
    dbeta/da changes sign (a scan of 200 values, then a root bracket), and beta there."""
    lam, tau = p["L"] * math.sqrt(c_of(p)), p["Lt"] / p["L"]
    grid = np.linspace(0.01, math.pi - 0.01, 200)
    slope = [base_rotation(a, lam, tau)[1] for a in grid]
    folds = []
    for a0, a1, d0, d1 in zip(grid, grid[1:], slope, slope[1:]):
        if d0 * d1 < 0:
            a = brentq(lambda a: base_rotation(a, lam, tau)[1], a0, a1, xtol=1e-14)
            folds.append((a, base_rotation(a, lam, tau)[0]))
    return folds


def turn_base(problem, params, **kw):
    (br,) = ea.continuation(problem, {**params, "beta": 0.0}, "beta",
                            bounds=(-0.1, TWO_PI + 0.1), directions="+", **kw)
    return br


def assert_index_two_ways(br):
    for pt in br.points:
        if pt.type not in ("LP", "BP"):
            assert pt.index_direct == pt.index_rule == pt.index >= 0, pt


def test_two_tubes_fold_pair_against_shooting(tubes):
    """At the defaults (lambda = 1.14 beyond the bound 0.72) turning the base through 2 pi
    meets one fold pair, symmetric about beta = pi (alpha -> 2 pi - alpha is an exact
    symmetry); the stable branch loses its stability at the first (0 -> 1) and the second
    gives it back (1 -> 0). Both folds, and the tip's rotation there, are the shooting's."""
    br = turn_base(tubes, DEFAULTS)
    lps = [p for p in br.points if p.type == "LP"]
    assert len(lps) == 2
    ((a, beta),) = shooting_folds(DEFAULTS)
    assert beta > math.pi
    assert lps[0].params["beta"] == pytest.approx(beta, abs=1e-8)
    assert lps[0].ordinates["tip"] == pytest.approx(a, abs=1e-6)
    assert lps[1].params["beta"] == pytest.approx(TWO_PI - beta, abs=1e-8)
    assert lps[1].ordinates["tip"] == pytest.approx(TWO_PI - a, abs=1e-6)
    assert [br.transition(p) for p in lps] == ["0 -> 1", "1 -> 0"]
    assert_index_two_ways(br)
    # the tip lags the base before the snap: the tip's rotation is behind beta all the way
    tip, b = np.array(br.columns["tip"]), np.array(br.columns["beta"])
    first = list(br.columns["type"]).index("LP")
    assert np.all(tip[1:first + 1] < b[1:first + 1])


def test_torque_and_hamiltonian_are_conserved(tubes):
    """On every solution of the turn, T1 + T2 = 0 (the total torque: the density depends on
    psi2 - psi1 only, and the tip carries none) and H = L (T1^2/GJ1 + T2^2/GJ2) / 2 - L W is
    the same along s (the density has no explicit s), on the stored profiles (101 points):
    H to 1e-7, the scale h^4 of the collocation's error on meshes of 50 intervals."""
    p = DEFAULTS
    br = turn_base(tubes, p)
    w = p["EI1"] * p["EI2"] / (2 * (p["EI1"] + p["EI2"]))
    for pt in br.points:
        psi1, psi2, T1, T2 = pt.profile[:4]
        assert np.max(np.abs(T1 + T2)) < 1e-12
        bend = w * (p["kappa1"] ** 2 + p["kappa2"] ** 2
                    - 2 * p["kappa1"] * p["kappa2"] * np.cos(psi2 - psi1))
        H = p["L"] * (T1 ** 2 / p["GJ1"] + T2 ** 2 / p["GJ2"]) / 2 - p["L"] * bend
        assert np.ptp(H) < 1e-7 * (1 + np.max(np.abs(H)))


@pytest.mark.parametrize("design", [DEFAULTS, OTHER], ids=["defaults", "unequal"])
def test_fold_curve_cusp_is_the_snap_free_bound(tubes, design):
    """The fold pair followed in (beta, L): the curve turns in L at beta = pi where lambda =
    L sqrt(c) meets the closed form arctan(1 / (sqrt(c) Lt)), to 1e-8; beta - pi grows like
    (L - L_c)^(3/2) on both sides (a cusp: two folds meet and the hysteresis vanishes)."""
    br = turn_base(tubes, design)
    curves = ea.continuation(tubes, br.label("LP1"), ["beta", "L"], bounds=(0.2, 2.0),
                             directions="both", tol=1e-7)
    turns = [p for c in curves for p in c.points if p.type in ("CP", "BP")]
    assert len(turns) == 1
    (cusp,) = turns
    sq = math.sqrt(c_of(design))
    lam_c = math.atan(1 / (sq * design["Lt"]))
    assert cusp.ordinates["lam"] == pytest.approx(lam_c, abs=1e-8)
    assert cusp.params["L"] == pytest.approx(lam_c / sq, abs=1e-8)
    assert cusp.params["beta"] == pytest.approx(math.pi, abs=1e-8)
    assert ct.snap_free_bound(design) == pytest.approx(lam_c, rel=1e-14)
    L_c = lam_c / sq
    near = []
    for c in curves:
        for b, L in zip(c.columns["beta"], c.columns["L"]):
            if 1e-3 < L - L_c < 0.05:
                near.append(abs(b - math.pi) / (L - L_c) ** 1.5)
    assert len(near) >= 2
    assert max(near) / min(near) < 1.05


def test_no_fold_below_the_snap_free_bound(tubes):
    """At lambda 2% below the bound the turn through 2 pi has no fold, and the tip's rotation
    increases with beta (no snap); 2% above it has the fold pair."""
    sq = math.sqrt(c_of(DEFAULTS))
    L_c = math.atan(1 / (sq * DEFAULTS["Lt"])) / sq
    below = turn_base(tubes, {**DEFAULTS, "L": 0.98 * L_c})
    assert not [p for p in below.points if p.type == "LP"]
    assert np.all(np.diff(below.columns["tip"]) > 0)
    assert all(p.index == 0 for p in below.points)
    above = turn_base(tubes, {**DEFAULTS, "L": 1.02 * L_c})
    assert len([p for p in above.points if p.type == "LP"]) == 2


# ---- three tubes: no closed form; a shooting of the three angles -------------------------

def three_tube_params(problem):
    return {name: par.default for name, par in problem.parameters.items()}


def three_tube_base(p, a2, a3):
    """Shooting from the tip (psi = (0, a2, a3), psi' = 0) to the base, the Euler-Lagrange
    equations of the energy written here: (GJ_i psi_i' / L)' = L dW/dpsi_i with W = 1/(2K)
    sum_{i<j} EI_i EI_j |kappa_i e_i - kappa_j e_j|^2, so psi_i'' = L^2 / GJ_i sum_j EI_i EI_j
    kappa_i kappa_j / K sin(psi_i - psi_j). Returns the base rotations relative to tube 1's,
    (beta2 - beta1, beta3 - beta1) with beta_i = psi_i(0) - Lt / L psi_i'(0), and their
    Jacobian in (a2, a3) from the variational equations."""
    EI = np.array([p["EI1"], p["EI2"], p["EI3"]])
    kap = np.array([p["kappa1"], p["kappa2"], p["kappa3"]])
    GJ = np.array([p["GJ1"], p["GJ2"], p["GJ3"]])
    L, tau = p["L"], p["Lt"] / p["L"]
    k = np.outer(EI * kap, EI * kap) / EI.sum()
    np.fill_diagonal(k, 0.0)

    def f(s, y):
        psi, dpsi = y[:3], y[3:6]
        V = y[6:].reshape(2, 6)           # the two variations (psi, psi')
        d = psi[:, None] - psi[None, :]
        acc = L ** 2 / GJ * np.sum(k * np.sin(d), axis=1)
        H = -L ** 2 / GJ[:, None] * k * np.cos(d)          # d acc_i / d psi_j, i != j
        H[np.diag_indices(3)] = -np.sum(H, axis=1)
        dV = [np.r_[v[3:], H @ v[:3]] for v in V]
        return np.r_[dpsi, acc, np.ravel(dV)]

    y1 = np.r_[0.0, a2, a3, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0]
    y0 = solve_ivp(f, (1.0, 0.0), y1, **ODE).y[:, -1]
    beta = y0[:3] - tau * y0[3:6]
    V = y0[6:].reshape(2, 6)
    dbeta = np.array([v[:3] - tau * v[3:] for v in V]).T     # rows beta_i, columns a2, a3
    rel = beta[1:] - beta[0]
    J = dbeta[1:] - dbeta[0]
    return rel, J


def test_three_tubes_folds_against_shooting():
    """Three tubes at the defaults, the innermost turned (beta3) with beta2 = 0: one fold pair,
    0 -> 1 -> 0. The equilibria at beta2 = 0 are a curve in the tip's rotations (a2, a3),
    followed here in a3 (a2 by Newton on beta2 = 0); its folds in beta3 are where the
    Jacobian of (beta2, beta3) in (a2, a3) is singular, located by a root bracket. The
    continuation's folds and tip rotations are these."""
    problem = ea.load_problem(EXAMPLES / "three_tubes.py")
    p = three_tube_params(problem)
    (br,) = ea.continuation(problem, {"beta3": 0.0}, "beta3", bounds=(-0.1, TWO_PI + 0.1),
                            directions="+")
    lps = [q for q in br.points if q.type == "LP"]
    assert len(lps) == 2
    assert [br.transition(q) for q in lps] == ["0 -> 1", "1 -> 0"]
    assert_index_two_ways(br)

    def on_curve(a3, a2):
        """The equilibrium at beta2 = 0 with the tip rotation a3, by Newton in a2."""
        for _ in range(20):
            rel, J = three_tube_base(p, a2, a3)
            if abs(rel[0]) < 1e-12:
                return a2, rel, J
            a2 -= rel[0] / J[0, 0]
        raise AssertionError(f"shooting: no equilibrium at a3 = {a3}")

    a2, grid, found = 0.0, np.linspace(0.0, TWO_PI, 61), []
    prev = None
    for a3 in grid:
        a2, rel, J = on_curve(a3, a2)
        det = np.linalg.det(J)
        if prev is not None and prev[2] * det < 0:
            start = prev[1]
            root = brentq(lambda t: np.linalg.det(on_curve(t, start)[2]), prev[0], a3,
                          xtol=1e-13)
            a2r, rel_r, _ = on_curve(root, start)
            found.append((root - 0.0, rel_r[1]))
        prev = (a3, a2, det)
    assert len(found) == 2
    for lp, (a3, beta3) in zip(lps, found):
        assert lp.params["beta3"] == pytest.approx(beta3, abs=1e-8)
        assert lp.ordinates["tip3"] == pytest.approx(a3, abs=1e-6)
    # the total torque vanishes on every solution
    for q in br.points:
        assert np.max(np.abs(np.sum(q.profile[3:6], axis=0))) < 1e-12


# ---- the index against the Hessian of the energy discretised here -------------------------

def discrete_hessian(p, n_tubes):
    """E_h(psi) = sum_j h [ sum_i GJ_i ((psi_i,j+1 - psi_i,j) / h)^2 / (2 L) + L W(psi_mid) ]
    + sum_i GJ_i (psi_i,0 - beta_i)^2 / (2 Lt) on the profile grid (the midpoint rule, written
    here from the model, not from the derived code), as a function returning its Hessian at
    the nodes' values psi (n_tubes, N + 1): the twist and the springs are quadratic, and W's
    second derivatives in psi_i - psi_j are EI_i EI_j kappa_i kappa_j cos(psi_j - psi_i) / K
    at the midpoints, shared by the two nodes of each interval."""
    EI = np.array([p[f"EI{i}"] for i in range(1, n_tubes + 1)])
    kap = np.array([p[f"kappa{i}"] for i in range(1, n_tubes + 1)])
    GJ = np.array([p[f"GJ{i}"] for i in range(1, n_tubes + 1)])
    L, Lt = p["L"], p["Lt"]
    k = np.outer(EI * kap, EI * kap) / EI.sum()

    def hessian(psi):
        m = psi.shape[1]
        h = 1.0 / (m - 1)
        H = np.zeros((n_tubes * m, n_tubes * m))
        ix = np.arange(m).reshape(1, m) + m * np.arange(n_tubes).reshape(n_tubes, 1)
        j = np.arange(m - 1)

        def add(nodes, signs, weight):
            """weight_j (sum_a sign_a e_(nodes_a,j)) (sum_b sign_b e_(nodes_b,j))^T, each j."""
            for a, sa in zip(nodes, signs):
                for b, sb in zip(nodes, signs):
                    np.add.at(H, (a, b), sa * sb * weight)

        for i in range(n_tubes):
            # the twist GJ_i / (2 L) ((psi_i,j+1 - psi_i,j) / h)^2 h and the spring at s = 0
            add((ix[i, j], ix[i, j + 1]), (-1, 1), np.full(m - 1, GJ[i] / (L * h)))
            H[ix[i, 0], ix[i, 0]] += GJ[i] / Lt
        mid = 0.5 * (psi[:, 1:] + psi[:, :-1])
        for i in range(n_tubes):
            for q in range(i + 1, n_tubes):
                # L h W contains -k_iq cos(psi_q - psi_i): its second derivative in the
                # difference d = psi_q - psi_i is k_iq cos(d), d's gradient (e_q - e_i) / 2
                # at each of the interval's two nodes
                add((ix[i, j], ix[i, j + 1], ix[q, j], ix[q, j + 1]), (-1, -1, 1, 1),
                    L * h * k[i, q] * np.cos(mid[q] - mid[i]) / 4)
        return H

    return hessian


@pytest.mark.parametrize("n_tubes", [2, 3])
def test_index_is_the_discretised_energys(tubes, n_tubes):
    """At every point of the base's turn off the folds, the index equals the number of
    negative eigenvalues of the Hessian of the energy discretised on the stored profile (100
    intervals): the two-tube robot (defaults) and the three-tube one."""
    if n_tubes == 2:
        problem, name, p = tubes, "beta", dict(DEFAULTS)
    else:
        problem, name = ea.load_problem(EXAMPLES / "three_tubes.py"), "beta3"
        p = three_tube_params(problem)
    (br,) = ea.continuation(problem, {name: 0.0}, name, bounds=(-0.1, TWO_PI + 0.1),
                            directions="+")
    hessian = discrete_hessian(p, n_tubes)
    counted = 0
    for pt in br.points:
        if pt.type == "LP":
            continue
        eig = np.linalg.eigvalsh(hessian(pt.profile[:n_tubes]))
        assert int(np.sum(eig < 0)) == pt.index, (pt.params[name], eig[:3])
        counted += pt.index
    assert counted > 0                       # the unstable stretch is among them


def test_the_drawn_backbone_is_the_arc_of_the_shared_curvature():
    """Unturned tubes (beta = 0) share the constant curvature (EI1 kappa1 + EI2 kappa2) / K
    about d1: the backbone is a circular arc in the y-z plane, r(l) = (0, -(1 - cos(u l)) / u,
    sin(u l) / u); opposed ones (beta = pi) bend with (EI1 kappa1 - EI2 kappa2) / K. The drawn
    backbone's tip against these to the grid's second order."""
    from matplotlib.figure import Figure
    p = dict(OTHER)
    grid = np.linspace(0.0, 1.0, 101)
    for beta, u in ((0.0, (p["EI1"] * p["kappa1"] + p["EI2"] * p["kappa2"])),
                    (math.pi, (p["EI1"] * p["kappa1"] - p["EI2"] * p["kappa2"]))):
        u /= p["EI1"] + p["EI2"]
        profile = ct.exact_start(grid, {**p, "beta": beta})
        ax = Figure().add_subplot(projection="3d")
        ct.draw(ax, profile, {**p, "beta": beta})
        (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == "backbone"]
        x, y, z = line.get_data_3d()
        length = p["L"]
        assert np.allclose((x[-1], y[-1], z[-1]),
                           (0.0, -(1 - math.cos(u * length)) / u, math.sin(u * length) / u),
                           atol=1e-4)


def test_the_shipped_runs_give_the_documented_answers(tmp_path):
    """runs/concentric_tubes and concentric_tubes_folds in restart order: the fold pair at the
    shooting's beta = pi +- d, 0 -> 1 then 1 -> 0, and the fold curve's turn at the closed-form
    bound (docs/soft-robots.md gives these numbers)."""
    out = {}
    for run in ("concentric_tubes", "concentric_tubes_folds"):
        plan = runfile.load(REPO / "runs" / f"{run}.toml", out_dir=tmp_path)
        out[run] = run_plan(plan, tmp_path).result.branches
    (turn,) = out["concentric_tubes"]
    ((_, beta),) = shooting_folds(DEFAULTS)
    lps = [p for p in turn.points if p.type == "LP"]
    assert [p.params["beta"] for p in lps] == pytest.approx([beta, TWO_PI - beta], abs=1e-8)
    assert [turn.transition(p) for p in lps] == ["0 -> 1", "1 -> 0"]
    (cusp,) = [p for b in out["concentric_tubes_folds"] for p in b.points
               if p.type in ("CP", "BP")]
    assert cusp.ordinates["lam"] == pytest.approx(ct.snap_free_bound(DEFAULTS), abs=1e-8)
