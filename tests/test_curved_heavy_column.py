"""A naturally curved heavy column (issue 49 item 4; equations/curved_heavy_column.py,
docs/soft-robots.md "Heavy and pre-curved rods").

Checked against what is derived here, independently of the module:

* at k0 = 0 it is Greenhill's column of examples/heavy_column.py: the same equations at
  random states, and its straight column buckles at Greenhill's load (3 j / 2)^2, j the first
  zero of J_{-1/3};
* loaded beyond that (q = 10), the buckled column leaning against its natural curvature snaps
  where the curvature reaches k_f: the folds in k0 against a shooting of theta' = m + k0,
  m' = -q (1 - s) sin(theta) from the clamp in m(0), the fold where k0 is extremal along the
  curve of equilibria m(1) = 0 (a scan and a root bracket of dk0/dm(0) = -r_m / r_k0, from the
  variational equations);
* the fold curve in (k0, q) turns at k0 = 0 in a cusp at Greenhill's load, with k_f growing
  like (q - q_c)^(3/2) (the unfolded pitchfork);
* the index two ways at every point off the folds, and 0 -> 1 at the snap; and against the
  negative eigenvalues of the Hessian of the energy discretised here (midpoint rule).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import jv

import elastica_auto as ea
from elastica_auto.energy import cache as energy_cache
from elastica_auto.execution import runfile
from helpers import EXAMPLES, REPO, run_plan

ODE = dict(method="DOP853", rtol=1e-12, atol=1e-13)
Q = 10.0


@pytest.fixture(autouse=True, scope="module")
def own_cache(tmp_path_factory):
    """The generated code in a folder of this module's own, not the user's cache."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
        mp.delenv(energy_cache.ENV, raising=False)
        yield


@pytest.fixture(scope="module")
def column():
    return ea.load_problem("curved_heavy_column")


def greenhill():
    j = brentq(lambda x: jv(-1 / 3, x), 1.0, 2.5, xtol=1e-15)
    return (1.5 * j) ** 2


def residual(mu, k0, q):
    """m(1) for the clamp's moment m(0) = mu (theta(0) = 0), with its derivatives in mu and
    k0 from the variational equations of theta' = m + k0, m' = -q (1 - s) sin(theta)."""
    def f(s, y):
        th, m, a, b, c, d = y          # (a, b) = d(theta, m)/dmu, (c, d) = d(theta, m)/dk0
        g = -q * (1 - s) * math.cos(th)
        return [m + k0, -q * (1 - s) * math.sin(th), b, g * a, d + 1, g * c]
    y1 = solve_ivp(f, (0.0, 1.0), [0.0, mu, 0.0, 1.0, 0.0, 0.0], **ODE).y[:, -1]
    return y1[1], y1[3], y1[5]


def shooting_fold(q):
    """The fold with k0 > 0 at the weight q: along the equilibria m(1) = 0, followed in mu from
    the buckled column leaning right at k0 = 0 (mu < 0) to the straight one (mu = 0), k0 is
    largest where r_mu = 0 (dk0/dmu = -r_mu / r_k0). Returns (k0, mu) there."""
    def k0_at(mu, k0):
        for _ in range(30):
            r, r_mu, r_k0 = residual(mu, k0, q)
            if abs(r) < 1e-13:
                return k0, r_mu
            k0 -= r / r_k0
        raise AssertionError(f"shooting: no equilibrium at m(0) = {mu}")

    # the buckled column at k0 = 0: the root of m(1) in mu < 0 (the straight one is mu = 0)
    grid = np.linspace(-6.0, -0.05, 60)
    r = [residual(mu, 0.0, q)[0] for mu in grid]
    (i,) = [i for i in range(len(grid) - 1) if r[i] * r[i + 1] < 0]
    mu_b = brentq(lambda mu: residual(mu, 0.0, q)[0], grid[i], grid[i + 1], xtol=1e-14)
    k0, prev = 0.0, None
    for mu in np.linspace(mu_b, 0.0, 41)[1:-1]:
        k0, r_mu = k0_at(mu, k0)
        if prev is not None and prev[2] * r_mu < 0:
            guess = prev[1]
            mu_f = brentq(lambda t: k0_at(t, guess)[1], prev[0], mu, xtol=1e-14)
            return k0_at(mu_f, guess)[0], mu_f
        prev = (mu, k0, r_mu)
    raise AssertionError("shooting: no fold")


def test_at_k0_0_it_is_greenhills_column(column):
    """The same equations as examples/heavy_column.py at random states (k0 = 0), and the
    straight column buckles at Greenhill's load, 0 -> 1."""
    heavy = ea.load_problem(EXAMPLES / "heavy_column.py")
    rng = np.random.default_rng(3)
    s = np.sort(np.r_[0.0, rng.uniform(0, 1, 11), 1.0])
    y = rng.uniform(-2, 2, (2, 13))
    for q in (-3.0, 7.0, 20.0):
        assert np.allclose(column.rhs(s, y, {"q": q, "k0": 0.0}), heavy.rhs(s, y, {"q": q}),
                           rtol=1e-14, atol=1e-14)
        assert np.allclose(column.bc(y[:, 0], y[:, -1], {"q": q, "k0": 0.0}),
                           heavy.bc(y[:, 0], y[:, -1], {"q": q}), rtol=1e-14, atol=1e-14)
    (br,) = ea.continuation(column, {"q": 0.0, "k0": 0.0}, "q", bounds=(0, 12),
                            directions="+")
    (bp,) = [p for p in br.points if p.type == "BP"]
    assert bp.params["q"] == pytest.approx(greenhill(), rel=1e-8)
    assert br.transition(bp) == "0 -> 1"


@pytest.fixture(scope="module")
def snap(column):
    """The buckled columns at q = 10, k0 = 0 (switched at Greenhill's branch point), each
    continued in k0 both ways."""
    (br,) = ea.continuation(column, {"q": 0.0, "k0": 0.0}, "q", bounds=(0, 12),
                            directions="+")
    buckled = ea.continuation(column, ea.Switch(br.label("BP1")), "q", bounds=(0, 12),
                              uz=[Q])
    return ea.continuation(column, [buckled.label("UZ1"), buckled.label("UZ2")], "k0",
                           bounds=(-1, 1), directions="both")


def test_the_snap_against_shooting(column, snap):
    """At q = 10 each buckled column, curved against its lean, snaps at |k0| = k_f, where it
    loses its stability (0 -> 1): the folds of the branches (on each, past its snap, the
    unstable column through the straight one to the mirror image's fold, 1 -> 0) are at the
    shooting's k_f and clamp moment, with the signs of the mirror images."""
    k_f, mu_f = shooting_fold(Q)
    lps = [p for b in snap for p in b.points if p.type == "LP"]
    assert {math.copysign(1.0, p.params["k0"]) for p in lps} == {-1.0, 1.0}
    for lp in lps:
        sign = math.copysign(1.0, lp.params["k0"])
        assert lp.params["k0"] == pytest.approx(sign * k_f, abs=1e-8)
        assert lp.ordinates["m0"] == pytest.approx(sign * mu_f, abs=1e-6)
        # leaning against the curvature: the tip on the other side
        assert lp.ordinates["theta1"] * lp.params["k0"] < 0
    for b in snap:
        for p in b.points:
            if p.type not in ("LP", "BP"):
                assert p.index_direct == p.index_rule == p.index >= 0
        folds = [b.transition(p) for p in b.points if p.type == "LP"]
        assert folds in ([], ["0 -> 1"], ["0 -> 1", "1 -> 0"])      # none curving with it


def test_fold_curve_ends_in_a_cusp_at_greenhills_load(column, snap):
    """The fold followed in (k0, q) turns at k0 = 0 at Greenhill's load (to 1e-8: the cusp of
    the unfolded pitchfork), and k_f / (q - q_c)^(3/2) tends to a constant as q -> q_c."""
    (label,) = [snap.label(name) for name in ("LP1", "LP2")
                if snap.label(name).state.params["k0"] > 0]
    curves = ea.continuation(column, label, ["k0", "q"], bounds=(5, 20),
                             directions="both", tol=1e-7)
    turns = [p for c in curves for p in c.points if p.type in ("CP", "BP")]
    assert len(turns) == 1
    (cusp,) = turns
    q_c = greenhill()
    assert cusp.params["q"] == pytest.approx(q_c, abs=1e-8)
    assert cusp.params["k0"] == pytest.approx(0.0, abs=1e-8)
    ratios = [abs(k) / (q - q_c) ** 1.5 for c in curves
              for k, q in zip(c.columns["k0"], c.columns["q"]) if 1e-3 < q - q_c < 0.3]
    assert len(ratios) >= 2
    assert max(ratios) / min(ratios) < 1.1


def discrete_hessian(theta, q):
    """The Hessian of E_h = sum_j h [ ((theta_j+1 - theta_j) / h - k0)^2 / 2 + q (1 - s_mid)
    cos(theta_mid) ] (the midpoint rule, written here from the model) in the free nodes'
    values (theta_0 = 0 is held by the clamp), at the nodes' values ``theta`` on a uniform
    grid: 1/h on the bending's tridiagonal, and -q (1 - s_mid) cos(theta_mid) h / 4 on each
    interval's 2 x 2 block (k0 enters only the gradient)."""
    m = len(theta)
    h = 1.0 / (m - 1)
    s_mid = (np.arange(m - 1) + 0.5) * h
    pot = -q * (1 - s_mid) * np.cos(0.5 * (theta[1:] + theta[:-1])) * h / 4
    H = np.zeros((m, m))
    for j in range(m - 1):
        H[j:j + 2, j:j + 2] += np.array([[1, -1], [-1, 1]]) / h + pot[j]
    return H[1:, 1:]


def test_index_is_the_discretised_energys(snap):
    """At every point of the snap runs off the folds, the index equals the number of negative
    eigenvalues of the Hessian of the energy discretised on the stored profile (100
    intervals)."""
    unstable = 0
    for b in snap:
        for p in b.points:
            if p.type == "LP":
                continue
            eig = np.linalg.eigvalsh(discrete_hessian(p.profile[0], p.params["q"]))
            assert int(np.sum(eig < 0)) == p.index, (p.params, eig[:2])
            unstable += p.index
    assert unstable > 0


def test_the_shipped_runs_give_the_documented_answers(tmp_path):
    """runs/curved_heavy_column, curved_heavy_snap and curved_heavy_folds in restart order:
    Greenhill's branch point, the snap of the stable buckled columns at q = 10 at the
    shooting's k_f (0 -> 1), and one fold curve through both folds with its cusp at
    Greenhill's load (docs/soft-robots.md gives these numbers)."""
    out = {}
    for run in ("curved_heavy_column", "curved_heavy_snap", "curved_heavy_folds"):
        plan = runfile.load(REPO / "runs" / f"{run}.toml", out_dir=tmp_path)
        out[run] = run_plan(plan, tmp_path).result.branches
    q_c = greenhill()
    (bp,) = [p for b in out["curved_heavy_column"] for p in b.points if p.type == "BP"]
    assert bp.params["q"] == pytest.approx(q_c, rel=1e-8)
    k_f, _ = shooting_fold(Q)
    snaps = [(p.params["k0"], b.transition(p)) for b in out["curved_heavy_snap"]
             for p in b.points if p.type == "LP"]
    assert sorted({round(k, 6) for k, _ in snaps}) == [round(-k_f, 6), round(k_f, 6)]
    assert all(abs(abs(k) - k_f) < 1e-8 for k, _ in snaps)
    assert len(out["curved_heavy_folds"]) == 2           # one curve, from LP1 both ways
    (cusp,) = [p for b in out["curved_heavy_folds"] for p in b.points if p.type == "CP"]
    assert cusp.params["q"] == pytest.approx(q_c, abs=1e-8)
