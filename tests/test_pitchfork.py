"""Pitchfork curves (`elastica_auto.branches.pitchfork`): a symmetry-breaking branch point of a
computed branch followed in two parameters.

Checked against what is not the engine's: on examples/bratu_pitchfork.py the curve is mu =
Lambda_1(lam), the first Dirichlet eigenvalue of -d^2/dx^2 - lam exp(u(x; lam)) on Bratu's
closed form, computed here by finite differences (Richardson-extrapolated); on the tendon
robot, its points are the branch points that one-parameter runs at fixed tau4 locate. The
formulation's regularity: Newton returns to the symmetric solution from a guess kicked off it,
and the unfolding direction (the left null vector) is not the null vector, which for these
energies is orthogonal to the left one at every s (why phi = v would not unfold).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import eigh_tridiagonal
from scipy.optimize import brentq, minimize_scalar

import elastica_auto as ea
from elastica_auto.branches import pitchfork
from elastica_auto.core.options import ContinuationOptions
from elastica_auto.core.solution import State
from elastica_auto.numerics.correctors import make_corrector
from helpers import EXAMPLES, REPO, run_cli

BRATU = EXAMPLES / "bratu_pitchfork.py"
ROBOT = REPO / "equations" / "tendon_robot.py"
# Two-parameter points solved to tol = 1e-7 are as accurate as one-parameter branch points
# (docs/two-parameter.md: 1e-9 to 1e-10 for fold curves); the largest difference seen here
# is 1.5e-9 in mu (Bratu) and 9e-9 in tau2 (the robot, whose tensions are ~100).
MU_ATOL, TAU_ATOL = 5e-9, 3e-8


def _lam_of_z(z):
    return 2 * z * z / np.cosh(z / 2) ** 2


Z_FOLD = minimize_scalar(lambda z: -_lam_of_z(z), bounds=(1, 4), method="bounded",
                         options={"xatol": 1e-12}).x


def lambda_1(lam: float, du0: float) -> float:
    """The first Dirichlet eigenvalue of -d^2/dx^2 - lam exp(u) on Bratu's closed form
    u = -2 ln(cosh(z (x - 1/2)) / cosh(z / 2)), lam = 2 z^2 / cosh(z/2)^2 (the branch of z
    told by u'(0) = 2 z tanh(z/2)): second-order differences on 1000 and 2000 intervals,
    extrapolated (the error is c2 h^2 + c4 h^4: ~1e-12 left)."""
    upper = du0 > 2 * Z_FOLD * np.tanh(Z_FOLD / 2)
    z = brentq(lambda z: _lam_of_z(z) - lam, *((Z_FOLD, 30.0) if upper else (1e-12, Z_FOLD)),
               xtol=1e-15)
    values = []
    for n in (1000, 2000):
        h = 1.0 / n
        x = np.arange(1, n) * h
        u = -2 * np.log(np.cosh(z * (x - 0.5)) / np.cosh(z / 2))
        values.append(eigh_tridiagonal(2 / h ** 2 - lam * np.exp(u), -np.ones(n - 2) / h ** 2,
                                       select="i", select_range=(0, 0), eigvals_only=True)[0])
    return (4 * values[1] - values[0]) / 3


@pytest.fixture(scope="module")
def bratu():
    return ea.load_problem(BRATU)


@pytest.fixture(scope="module")
def bratu_bp(bratu):
    """The first branch point of w = 0 in lam at mu = 5 (BP1, lam = 2.89993)."""
    (b,) = ea.continuation(bratu, {"lam": 0.0, "mu": 5.0, "a": 1.0}, "lam", bounds=(-1, 4),
                           max_points=80, ds_max=0.5)
    return b.label("BP1")


def test_the_pitchfork_curve_is_the_first_eigenvalue_of_the_closed_form(bratu, bratu_bp):
    curves = ea.continuation(bratu, bratu_bp, ["lam", "mu"], bounds=(1, 9), tol=1e-7,
                             directions="both")
    assert [c.end for c in curves] == ["EP", "EP"]
    ends = sorted(c.columns["mu"][-1] for c in curves)
    assert ends == [pytest.approx(1.0, abs=1e-12), pytest.approx(9.0, abs=1e-12)]
    for c in curves:
        col = c.columns
        assert len(col["mu"]) >= 8
        for lam, mu, du0 in zip(col["lam"], col["mu"], col["du0"]):
            assert abs(lambda_1(lam, du0) - mu) <= MU_ATOL
        # the symmetric solution, unfolded by nothing
        assert np.abs(col["dw0"]).max() <= 1e-14 and np.abs(col["unfolding"]).max() <= 1e-14


def test_newton_returns_to_the_symmetric_solution_from_a_kick(bratu, bratu_bp):
    """A regular system: from (y + k v, v + k y, unfolding k) off the symmetric subspace,
    Newton at the BP's mu lands on the BP again (w = 0, unfolding 0, the BP's lam)."""
    opts = ContinuationOptions(tol=1e-7)
    ref = pitchfork.reference(bratu, bratu_bp.state, bratu_bp.tangent, "lam", opts)
    problem = pitchfork.pitchfork_problem(bratu, "lam", ref)
    n = bratu.n
    for kick in (1e-2, 5e-2):
        start = pitchfork.pitchfork_start(problem, ref, bratu_bp.state.params)
        y = start.y.copy()
        y[:n] += kick * ref.null
        y[n:2 * n] += kick * ref.state.y
        y[problem.states.index(f"free:{pitchfork.UNFOLDING}")] += kick
        sol = make_corrector(problem, "mu", opts).point(State.from_values(problem, start.s, y,
                                                                          start.params))
        p = problem.point_params(sol.state.params, sol.state.y)
        assert abs(p["lam"] - bratu_bp.state.params["lam"]) <= 1e-8
        assert abs(p[pitchfork.UNFOLDING]) <= 1e-14 and np.abs(sol.state.y[2]).max() <= 1e-14


def test_the_unfolding_is_the_left_null_vector_not_the_null_vector(bratu, bratu_bp):
    """Along w = 0 the w-block is v' = (0, 1; -k, 0) v: its left null vector is (-w', w)
    for the null vector (w, w'), orthogonal to it at every s. The reference's phi is that
    left null vector (a multiple of it, to the mesh's accuracy), so phi.v = 0 where phi = v
    would have |v|^2."""
    ref = pitchfork.reference(bratu, bratu_bp.state, bratu_bp.tangent, "lam",
                              ContinuationOptions(tol=1e-7))
    h = np.diff(ref.state.s)
    v = 0.5 * (ref.null[:, :-1] + ref.null[:, 1:])       # at the midpoints, where phi is
    phi = ref.phi
    assert np.abs(v[:2]).max() <= 1e-12 and np.abs(phi[:2]).max() <= 1e-6 * np.abs(phi).max()
    left = np.vstack((-v[3], v[2]))                      # (-w', w)
    c = np.sum(phi[2:] * left) / np.sum(left * left)
    assert np.abs(phi[2:] - c * left).max() <= 1e-3 * np.abs(phi).max()
    assert abs(np.sum(np.sum(phi * v, axis=0) * h)) <= 1e-3 * abs(c)


def test_the_tendon_robots_out_of_plane_loss_followed_in_the_antagonist():
    """tendon_lift's BP1 (tau2 = 48.717 at tau4 = 0) followed in tau4 to 20 is the BP a
    one-parameter run in tau2 at tau4 = 20 locates, with the unfolding 0 to rounding."""
    robot = ea.load_problem(ROBOT)
    (weight,) = ea.continuation(robot, {"P": 0.0}, "P", bounds=(0, 6), uz=[5], ds_max=1.0)
    lifted = weight.label("UZ1")
    (lift,) = ea.continuation(robot, lifted, "tau2", bounds=(0, 50), ds_max=5.0)
    (curve,) = ea.continuation(robot, lift.label("BP1"), ["tau2", "tau4"], bounds=(0, 20),
                               tol=1e-7, ds_max=5.0)
    col = curve.columns
    assert curve.end == "EP" and col["tau4"][-1] == pytest.approx(20.0, abs=1e-12)
    assert np.abs(col["unfolding"]).max() <= 1e-12
    (one,) = ea.continuation(robot, lifted, "tau2", params={"tau4": 20.0}, bounds=(0, 75),
                             ds_max=5.0)
    (bp,) = [p for p in one.points if p.type == "BP"]
    assert abs(bp.params["tau2"] - col["tau2"][-1]) <= TAU_ATOL
    # the planar lift (x = 0) along the curve
    assert np.abs(col["x1"]).max() <= 1e-12


TRANSCRITICAL = '''
import numpy as np
from elastica_auto import Parameter
STATES = ("u", "du")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode"), Parameter("mu", 1.0, "mu", "ode"),
              Parameter("c", 0.0, "c", "ode")]
def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * y[0] - p["mu"] * y[0] ** 2
                      - p["c"] * np.sin(np.pi * s)))
def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))
def guess(s, p):
    return np.zeros((2, len(s)))
'''


def test_a_curve_from_a_transcritical_bp_warns_where_its_points_are_not_branch_points(tmp_path):
    """u'' + lam u + mu u^2 + c sin(pi s) = 0, u(0) = u(1) = 0: at c = 0 the branch u = 0
    crosses another at lam = pi^2, a transcritical BP (no symmetry while mu != 0). In mu it
    persists (the linearisation at u = 0 is u'' + lam u whatever mu): the curve is lam = pi^2,
    the unfolding 0, no warning. The imperfection c destroys it (the two branches separate at
    folds), so the system's points off c = 0 solve an unfolded problem, not the module's:
    the curve used to end without a word, its lam(c) looking like branch points."""
    path = tmp_path / "transcritical.py"
    path.write_text(TRANSCRITICAL)
    pb = ea.load_problem(str(path))
    (trivial,) = ea.continuation(pb, {"lam": 5.0}, "lam", bounds=(0, 15))
    bp = trivial.label("BP1")
    assert bp.state.params["lam"] == pytest.approx(np.pi ** 2, rel=1e-8)
    for curve in ea.continuation(pb, bp, ["lam", "mu"], bounds=(0.5, 2), directions="both"):
        assert curve.end == "EP" and curve.warnings == []
        assert np.abs(curve.columns["lam"] - np.pi ** 2).max() <= 1e-8 * np.pi ** 2
    for curve in ea.continuation(pb, bp, ["lam", "c"], bounds=(-0.5, 0.5), directions="both"):
        (warning,) = curve.warnings
        assert "points are not branch points: the unfolding term" in warning
        assert "the start is not a symmetry-breaking branch point" in warning
        assert abs(curve.columns["unfolding"][-1]) > 0.01


def test_show_prints_a_branchs_warnings(tmp_path, cli_exe):
    """show listed a branch "that has warnings" by its end alone (`branch 1: EP: reached c =
    0.5`), never saying what the warning was: now each follows it, as run prints it."""
    path = tmp_path / "transcritical.py"
    path.write_text(TRANSCRITICAL)
    pb = ea.load_problem(str(path))
    (trivial,) = ea.continuation(pb, {"lam": 5.0}, "lam", bounds=(0, 15))
    curves = ea.continuation(pb, trivial.label("BP1"), ["lam", "c"], bounds=(0, 0.5))
    ea.save(curves, tmp_path / "curve.h5")
    result = run_cli(cli_exe, "show", tmp_path / "curve.h5")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    k = lines.index("branch 1: EP: reached c = 0.5")
    (warning,) = curves[0].warnings
    assert lines[k + 1] == f"  warning: {warning}"


def test_a_pitchfork_curve_starts_from_one_bp(bratu, bratu_bp):
    with pytest.raises(ea.PlanError, match="starts from one BP label"):
        ea.continuation(bratu, [bratu_bp, bratu_bp], ["lam", "mu"], bounds=(1, 9))
