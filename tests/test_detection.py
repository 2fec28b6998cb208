"""Which folds a branch reports, and the option that switches fold or branch-point detection
off (issue 45 item 6); the border update that divided by zero (hostile L12) and the Bratu
branch to its end.

The checks are against closed forms: the vertical branch of `VERTICAL` (u = c at lam = 1 for
every c), the Bratu branch u(x) = -2 ln(cosh(z (x - 1/2)) / cosh(z / 2)),
lam = 2 z^2 / cosh(z / 2)^2 (examples/bratu.py), whose one fold is where z tanh(z / 2) = 2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import elastica_auto as ea
from helpers import EXAMPLES, REFERENCE, run_cli, scaled_module

#: u'' + (lam - 1) u (1 + u^2) = 0 with u'(0) = u'(1) = 0: u = 0 for every lam, with a branch
#: point at lam = 1 (the kernel u = const), where the constants u = c solve for every c: the
#: other branch there is the line lam = 1, along which the parameter does not move at all.
VERTICAL = '''\
"""u'' + (lam - 1) u (1 + u^2) = 0, u'(0) = u'(1) = 0."""
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u", "du")
PARAMETERS = [Parameter("lam", 0.0, r"\\lambda", "ode")]


def rhs(s, y, p):
    return np.vstack((y[1], -(p["lam"] - 1) * y[0] * (1 + y[0] ** 2)))


def bc(ya, yb, p):
    return np.array((ya[1], yb[1]))


def exact_start(s, p):
    return np.zeros((2, len(s)))


ORDINATES = [Ordinate("u0", "$u(0)$", lambda s, y, p: y[0, 0], "lam")]
'''

#: The Bratu fold: z tanh(z / 2) = 2, lam_c = 2 z^2 / cosh(z / 2)^2.
Z_FOLD = brentq(lambda z: z * math.tanh(z / 2) - 2, 1.0, 5.0)
LAM_FOLD = 2 * Z_FOLD ** 2 / math.cosh(Z_FOLD / 2) ** 2


def _bratu_lam(du0: float) -> float:
    """lam on the Bratu branch at the point with u'(0) = du0 = 2 z tanh(z / 2) (z >= 0)."""
    z = brentq(lambda z: 2 * z * math.tanh(z / 2) - du0, 0.0, 1e4) if du0 > 0 else 0.0
    return 2 * z * z / math.cosh(z / 2) ** 2


@pytest.fixture(scope="module")
def vertical(tmp_path_factory):
    path = tmp_path_factory.mktemp("vertical") / "vertical.py"
    path.write_text(VERTICAL)
    return ea.load_problem(str(path))


def test_no_fold_where_the_parameter_only_turns_by_rounding(vertical):
    """Issue 45 item 6: the branch switched at lam = 1 is the line lam = 1, where the
    tangent's lam component is rounding (1e-17) of either sign. It gets no LP (before: an LP
    'fold not located' where that rounding changed sign, and a fold pair suspected inside a
    step down to ds_min, MX) and no warning; it ends at max_points, every point at lam = 1
    with u constant."""
    run = ea.continuation(vertical, {"lam": 0.5}, "lam", bounds=(0, 2), switch=1,
                          max_points=60, jobs=1)
    assert [p.params["lam"] for p in run[0].points if p.type == "BP"] == \
        pytest.approx([1.0], abs=1e-12)
    for br in run[1:]:
        assert br.start == "switch at BP1"
        assert [p.type for p in br.points if p.type] == ["EP", "EP"], br.message
        assert br.message == "reached max_points = 60" and not br.warnings
        np.testing.assert_allclose(br.columns["lam"], 1.0, atol=1e-12)
        assert np.ptp(br.columns["u0"]) > 1.0          # it moved, along u


def test_the_bratu_fold_on_a_module_scaled_by_1e3_and_1e_3(tmp_path):
    """Issue 45 item 5's check for the fold rule's noise bound (events.TURN_NOISE): the
    Bratu module (the hand-written one, whose functions the scaled copy calls) with its
    states scaled by 1e3 and 1e-3 has its one fold at lam_c, as the module itself. Steps
    and ds_min in the units of each (a step is a distance in y; the fold of the 1e-3 module
    turns within 1e-6 of arclength)."""
    for scale in (1.0, 1e3, 1e-3):
        problem = ea.load_problem(str(scaled_module(REFERENCE / "bratu.py", scale, tmp_path)))
        unit = max(scale, 1.0)
        (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), directions="+",
                                max_points=120, ds=0.05 * unit, ds_max=0.5 * unit,
                                ds_min=1e-6 * min(scale, 1.0) ** 2)
        folds = [p.params["lam"] for p in br.points if p.type == "LP"]
        assert folds == pytest.approx([LAM_FOLD], rel=1e-9), scale
        assert not [p for p in br.points if p.type == "BP"] and not br.warnings


def test_a_border_update_that_would_lose_its_digits_is_refused():
    """Hostile L12: Sherman-Morrison's 1 + <delta, u> was divided by unguarded, and a new
    border row that makes the system singular divided by zero (ZeroDivisionError). It is
    refused now (IllConditionedUpdate), and the solve with that row falls back to a
    factorisation of its own: finite where the system is singular, and where it is not,
    equal to the update's and to a direct solve."""
    from elastica_auto.numerics import bordered, newton
    from elastica_auto.numerics.correctors import make_corrector
    from elastica_auto.core.solution import State
    from elastica_auto.core.options import ContinuationOptions
    problem = ea.load_problem(str(EXAMPLES / "bratu.py"))
    s = np.linspace(0, 1, 21)
    state = State.from_values(problem, s, np.zeros((2, 21)), {"lam": 0.0})
    corr = make_corrector(problem, "lam", ContinuationOptions())
    lin = corr.point(state).lin
    fact, rng = lin.fact, np.random.default_rng(1)
    col, bc, g = rng.standard_normal((2, 20)), rng.standard_normal(2), 0.3
    u_y, u_p = fact.null_direction()
    c0, d0 = fact.border[-1]
    # a row that makes 1 + <delta, u> vanish exactly: delta = -u / |u|^2 (its state part)
    weight = float((u_y * u_y).sum() + u_p[0] ** 2)
    singular_c, singular_d = c0 - u_y / weight, float(d0[0] - u_p[0] / weight)
    with pytest.raises(bordered.IllConditionedUpdate):
        fact.solve_with_border(singular_c, [singular_d], col, bc, [g])
    dy, dp = newton.with_border(fact, lin.blocks, "lam", lin.split, singular_c, singular_d,
                                 col, bc, g)
    assert np.all(np.isfinite(dy)) and np.isfinite(dp).all()
    # a well-conditioned exchange: the update, the fallback and a direct solve agree
    c1, d1 = c0 + 0.1 * rng.standard_normal(c0.shape), 0.5
    direct = bordered.factor(lin.blocks, ("lam",), [(c1, [d1])], lin.split).solve(col, bc, [g])
    update = fact.solve_with_border(c1, [d1], col, bc, [g])
    for a, b in zip(update, direct):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)


def test_the_bratu_branch_to_its_end(cli_exe, tmp_path):
    """Hostile L12: `run examples/bratu.toml --set max_points=2000` ended MX with a
    ZeroDivisionError (a rounding 'fold' at lam = 8.6e-18 sent to the fold locator). The
    branch has no end: past its fold lam -> 0 like 8 z^2 exp(-z) while u(1/2) ~ z grows. It
    is followed against the closed form (lam to 1e-7 relative down to 1e-15, where lam exp(u)
    is still computed to the corrector's tolerance, and to 1e-5 after), with its one fold,
    until lam ~ 1e-20, where lam is known only to the corrector's absolute accuracy: an MX
    where the corrector gives up, without an exception."""
    out = run_cli(cli_exe, "run", EXAMPLES / "bratu.toml", "--set", "max_points=2000",
                  "--out", tmp_path, "-j", "1", "-q")
    assert out.returncode == 1, out.stderr
    assert "Error" not in out.stdout and "Traceback" not in out.stderr
    (br,) = ea.BranchFile(tmp_path / "bratu.h5").branches
    c = br.columns
    # where the corrector gives up depends on rounding (lam ~ 1e-20 here, 1e-19 with another
    # BLAS kernel; the meshes reach max_nodes on the way, or do not): a corrector failure
    assert c["type"][-1] == "MX" and br.attrs["message"].startswith(
        "corrector failed at ds < ds_min"), br.attrs["message"]
    assert list(c["type"]).count("LP") == 1
    assert c["lam"][list(c["type"]).index("LP")] == pytest.approx(LAM_FOLD, rel=1e-9)
    lam = c["lam"].astype(float)
    exact = np.array([_bratu_lam(d) for d in c["du0"].astype(float)])
    assert lam.min() < 1e-18
    resolved = lam >= 1e-15
    np.testing.assert_allclose(lam[resolved], exact[resolved], rtol=1e-7)
    np.testing.assert_allclose(lam, exact, rtol=1e-5, atol=0)


def _bratu(**options):
    """The Bratu branch round its fold, up to int exp(u) = 50 (lam = 0.52) past it."""
    problem = ea.load_problem(str(EXAMPLES / "bratu.py"))
    (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), directions="+",
                            uz=[1, 2, 3], stop=["dE_dlam < -50"], **options)
    return br


def test_fold_detection_switched_off():
    """Issue 45 item 6 (AUTO-07p's ILP = 0): with detect = {LP = false} the Bratu branch has no
    LP label, and otherwise the same points: every other point, its parameters, ordinates
    and index, as the run that looks for folds."""
    on, off = _bratu(), _bratu(detect={"LP": False})
    assert [p.type for p in on.points].count("LP") == 1
    assert "LP" not in [p.type for p in off.points]
    kept = [p for p in on.points if p.type != "LP"]
    assert len(kept) == len(off.points)
    for p, q in zip(kept, off.points):
        assert (p.type, p.params, p.ordinates, p.index) == (q.type, q.params, q.ordinates,
                                                            q.index)


def test_branch_point_detection_switched_off(vertical):
    """ISP = 0: detect = {BP = false} finds no branch point on u = 0 of `VERTICAL`, and the
    points are otherwise those of the run that does; switch = N then has nothing to switch
    at, and asking for both is an error."""
    on = ea.continuation(vertical, {"lam": 0.5}, "lam", bounds=(0, 2), jobs=1)[0]
    off = ea.continuation(vertical, {"lam": 0.5}, "lam", bounds=(0, 2), jobs=1,
                          detect={"BP": False})[0]
    assert [p.type for p in on.points].count("BP") == 1
    kept = [p for p in on.points if p.type != "BP"]
    assert [(p.type, p.params) for p in kept] == [(p.type, p.params) for p in off.points]
    with pytest.raises(ea.PlanError, match="detect.BP = false"):
        ea.continuation(vertical, {"lam": 0.5}, "lam", switch=1, detect={"BP": False})
    with pytest.raises(ea.PlanError, match="detect.LP = false"):
        ea.continuation(vertical, {"lam": 0.5}, "lam", stop=["LP2"], detect={"LP": False})


@pytest.mark.parametrize("value, words", [
    ("{ LP = false, XP = false }", "[options] detect.XP: unknown kind; expected one of LP, BP"),
    ("{ LP = 0 }", "[options] detect.LP: expected true or false"),
    ("false", "[options] detect: expected a table such as { LP = false }"),
])
def test_the_run_file_s_detect_is_checked(cli_exe, tmp_path, value, words):
    """An unknown kind (or a value not true or false) is a user error: one line, exit 2."""
    path = tmp_path / "detect.toml"
    path.write_text((EXAMPLES / "bratu.toml").read_text().replace(
        'equation = "bratu.py"', f'equation = "{EXAMPLES / "bratu.py"}"')
        + f"detect = {value}\n")
    out = run_cli(cli_exe, "run", path, "--out", tmp_path / "o")
    assert out.returncode == 2 and "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], out.stderr


@pytest.mark.parametrize("value, words", [
    ({"XP": False}, "detect: unknown kind 'XP'; the kinds are LP, BP"),
    ({"LP": "no"}, "detect.LP must be true or false"),
])
def test_the_api_s_detect_is_checked(vertical, value, words):
    with pytest.raises(ea.PlanError, match=words):
        ea.continuation(vertical, {"lam": 0.5}, "lam", detect=value)
