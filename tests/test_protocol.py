"""What the module protocol can say beyond one condition per state, checked on known answers.

* Integral conditions (AUTO-07p's NINT): the Bratu problem with a prescribed mean,
  examples/bratu_mean.py, continued in the mean M with lam solved for. On the closed-form
  family u = -2 ln(cosh(z (x - 1/2)) / cosh(z / 2)), lam = 2 z^2 / cosh^2(z / 2), the mean is
  M(z) = int_0^1 u dx (scipy's quad here).
* More boundary conditions than states (NBC > NDIM): u'' + p u (1 + u^2) = 0, u(0) = u(1) = 0,
  u'(0) = a, examples/eigenvalue_slope.py, p solved for as a is continued; p(a) by shooting.
* Stops on an ordinate's value, located exactly; starts from a guess, solved from.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

import elastica_auto as ea
from elastica_auto.execution import runfile
from elastica_auto.core.errors import EXIT_USER
from helpers import EXAMPLES, run_cli, run_plan


def lam_of(z):
    return 2 * z * z / math.cosh(z / 2) ** 2


def z_of_du0(du0):
    """z from u'(0) = 2 z tanh(z / 2), increasing in z."""
    return brentq(lambda z: 2 * z * math.tanh(z / 2) - du0, 0.0, 60.0, xtol=1e-14) \
        if du0 > 0 else 0.0


def mean_of(z):
    return quad(lambda x: -2 * math.log(math.cosh(z * (x - 0.5)) / math.cosh(z / 2)), 0, 1,
                epsabs=1e-13, epsrel=1e-13)[0]


@pytest.fixture(scope="module")
def bratu_mean():
    return ea.load_problem(str(EXAMPLES / "bratu_mean.py"))


@pytest.mark.parametrize("corrector", ["collocation", "solve_bvp"])
def test_an_integral_condition_passes_the_bratu_fold(bratu_mean, corrector):
    """Continued in M, lam (solved for) rises to lam_c and falls again with no fold on the
    way; every point is on the closed form."""
    (br,) = ea.continuation(bratu_mean, {"M": 0.0}, "M", bounds=(0, 2.5), corrector=corrector)
    assert br.end == "EP" and br.folds == [] and br.warnings == []
    c = br.columns
    assert c["M"][-1] == pytest.approx(2.5, abs=1e-12)
    z_c = brentq(lambda z: z * math.tanh(z / 2) - 2, 1.0, 4.0, xtol=1e-15)
    k = int(np.argmax(c["lam"]))
    assert 0 < k < len(c["lam"]) - 1 and c["lam"][k] < lam_of(z_c)
    assert c["lam"][-1] < 3.0                   # well past the fold in lam
    for du0, lam, M in zip(c["du0"], c["lam"], c["M"]):
        z = z_of_du0(du0)
        assert abs(lam - lam_of(z)) <= 1e-5 * (1 + lam), (M, lam, lam_of(z))
        assert abs(M - mean_of(z)) <= 1e-6, (M, mean_of(z))


def test_a_stop_on_a_free_parameter_is_located(bratu_mean):
    """``lam < 3``: the branch ends where lam, past its maximum, falls through 3."""
    (br,) = ea.continuation(bratu_mean, {"M": 0.0}, "M", bounds=(0, 10), stop=["lam < 3"])
    end = br.points[-1]
    assert br.end == "EP" and br.message == "reached lam = 3 (stop lam < 3)"
    assert end.params["lam"] == pytest.approx(3.0, abs=1e-9)
    z = z_of_du0(end.ordinates["du0"])
    assert z > 2.4 and abs(lam_of(z) - 3.0) <= 1e-5     # the upper solution at lam = 3
    assert end.params["M"] == pytest.approx(mean_of(z), abs=1e-6)


def _shoot_p(a):
    """p with u(1) = 0 for u(0) = 0, u'(0) = a, u positive inside: by shooting."""
    def end(p):
        sol = solve_ivp(lambda x, z: [z[1], -p * z[0] * (1 + z[0] ** 2)], (0, 1), [0.0, a],
                        method="DOP853", rtol=1e-12, atol=1e-13)
        return sol.y[0, -1]
    hi = math.pi ** 2 + 0.01                      # u(1) < 0 there: past the first mode
    lo = next(q for q in np.linspace(hi, 0.1, 200) if end(q) > 0)
    return brentq(end, lo, hi, xtol=1e-13)


def test_more_conditions_than_states_solve_for_the_eigenvalue():
    problem = ea.load_problem(str(EXAMPLES / "eigenvalue_slope.py"))
    (br,) = ea.continuation(problem, {"a": 0.1}, "a", bounds=(0.1, 5))
    assert br.end == "EP" and br.points[-1].params["a"] == pytest.approx(5, abs=1e-12)
    c = br.columns
    assert np.all(np.diff(c["p"]) < 0)            # the restoring force stiffens
    for a, p in list(zip(c["a"], c["p"]))[::4] + [(c["a"][-1], c["p"][-1])]:
        assert p == pytest.approx(_shoot_p(a), rel=1e-7), a
    stored = br.label("EP1")                        # the start: solved from the guess
    assert stored.state.y.shape[0] == 3             # u, v and p carried as a state


def test_a_stop_on_an_ordinate_is_located():
    """Bratu from u = 0: ``u_half > 3`` ends the branch on the upper family at u(1/2) = 3."""
    problem = ea.load_problem(str(EXAMPLES / "bratu.py"))
    (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4),
                            stop=["u_half > 3"], max_points=500)
    end = br.points[-1]
    assert br.end == "EP" and "stop u_half > 3" in br.message and len(br.folds) == 1
    assert end.ordinates["u_half"] == pytest.approx(3.0, abs=1e-9)
    z = 2 * math.acosh(math.exp(1.5))                # u(1/2) = 2 ln cosh(z / 2) = 3
    assert end.params["lam"] == pytest.approx(lam_of(z), abs=1e-5)


GUESSING = '''
import numpy as np
from elastica_auto.model.problem import Ordinate, Parameter
STATES = ("u", "v")
PARAMETERS = [Parameter("lam", 2.0, "lam", "ode")]
def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))
def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))
def guess(s, p):
    """A hump of height 4: near the upper Bratu solution."""
    return np.vstack((4 * np.sin(np.pi * s), 4 * np.pi * np.cos(np.pi * s)))
ORDINATES = [Ordinate("du0", "u'(0)", lambda s, y, p: y[1, 0], "lam")]
'''


def test_a_start_from_a_guess_is_solved_from(tmp_path):
    path = tmp_path / "guessing.py"
    path.write_text(GUESSING)
    problem = ea.load_problem(str(path))
    (br,) = ea.continuation(problem, {"lam": 2.0}, "lam", bounds=(1.5, 4), max_points=5)
    start = br.points[0]
    assert start.params["lam"] == 2.0
    z = z_of_du0(start.ordinates["du0"])
    assert z > 3 and abs(lam_of(z) - 2.0) <= 1e-6   # the upper of the two solutions at 2
    with pytest.raises(ea.StartError, match="no solution found from its guess at lam=4"):
        ea.continuation(problem, {"lam": 4.0}, "lam")  # above lam_c: there is none


WRONG_EXACT = '''
import numpy as np
from elastica_auto.model.problem import Parameter
STATES = ("u", "v")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode"), Parameter("b", 0.0, "b", "ode")]
def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))
def bc(ya, yb, p):
    return np.array((ya[0], yb[0] - p["b"]))
def exact_start(s, p):
    """u = 0: Bratu's solution at lam = 0 and b = 0 only; the newcomer forgot both."""
    return np.zeros((2, len(s)))
'''


def test_an_exact_start_that_does_not_solve_the_problem_is_a_user_error(tmp_path, cli_exe):
    """An exact_start that is not a solution (the module's end condition or equation changed,
    not its start) is refused before anything is computed, saying where it fails, instead of
    a first step whose corrector fails (exit 1, "the corrector moved 1.15 from the
    predictor"). u = 0 solves u'' = -lam e^u, u(0) = 0, u(1) = b at lam = b = 0 only: at
    b = 1/2 its end condition u(1) = b is off by 1/2, at lam = 1 its equation by lam."""
    path = tmp_path / "wrong_exact.py"
    path.write_text(WRONG_EXACT)
    problem = ea.load_problem(str(path))
    (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(0, 1), max_points=5)
    assert br.points[0].params["lam"] == 0.0       # the true solution starts as before
    with pytest.raises(ea.StartError, match=r"its exact start at lam=0, b=0.5 does not solve "
                       r"the problem: the residual is 0.5 in row 2 of the 2 end conditions"):
        ea.continuation(problem, {"b": 0.5}, "lam")
    with pytest.raises(ea.StartError, match=r"its exact start at lam=1, b=0 does not solve the "
                       r"problem: the residual is 0.02 in the equation of v near s = "):
        ea.continuation(problem, {"lam": 1.0}, "lam")   # 0.02 = lam h in every interval
    toml = tmp_path / "wrong.toml"
    toml.write_text('equation = "wrong_exact.py"\n[parameters]\nb = 0.5\n'
                    '[continuation]\nparameter = "lam"\n')
    result = run_cli(cli_exe, "run", toml, "--out", tmp_path / "out", "-q")
    assert result.returncode == EXIT_USER and result.stdout == ""
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("elastica-auto: error: ") and "exact_start(s, p) must return" in line
    assert not (tmp_path / "out" / "wrong.h5").exists()


def test_run_file_free_and_stop_are_the_api_s(tmp_path, bratu_mean):
    toml = tmp_path / "mean.toml"
    toml.write_text(f'equation = "{EXAMPLES / "bratu_mean.py"}"\n[parameters]\nM = 0\n'
                    '[continuation]\nparameter = "M"\ndirections = "+"\nbounds = [0, 10]\n'
                    'free = ["lam"]\nstop = ["lam < 3"]\n')
    from_file = run_plan(runfile.load(toml), tmp_path / "out")
    (a,) = from_file.result.branches
    (b,) = ea.continuation(bratu_mean, {"M": 0.0}, "M", bounds=(0, 10), stop=["lam < 3"])
    for name, col in a.columns.items():
        np.testing.assert_array_equal(col, b.columns[name], err_msg=name)
    stored = from_file.file.branches[0].columns
    np.testing.assert_array_equal(stored["lam"], b.columns["lam"])   # the free one, stored


@pytest.mark.parametrize("kwargs, key, words", [
    ({"free": []}, "free", "need 1 free parameters, got 0"),
    ({"free": ["lam", "M"]}, "free", "got 2"),
    ({"free": ["mu"]}, "free", "'mu' is not a parameter"),
    ({"free": "lam"}, "free", "list of parameter names"),
    ({"parameter": "lam"}, "parameter", "free parameter"),
    ({"stop": ["mean > 1"]}, "stop", "not an ordinate or a free parameter"),
    ({"stop": ["lam > x"]}, "stop", "cannot evaluate"),
])
def test_bad_free_parameters_and_stops(bratu_mean, kwargs, key, words):
    args = {"parameter": "M", **kwargs}
    with pytest.raises(ea.PlanError) as info:
        ea.continuation(bratu_mean, {"M": 0.0}, args.pop("parameter"), **args)
    assert info.value.key == key and words in str(info.value), str(info.value)


@pytest.mark.parametrize("text, words", [
    ('INTEGRALS = ("m",)\n', "INTEGRALS and integrals(s, y, p) go together"),
    ('INTEGRALS = ("m",)\ndef integrals(s, y, p):\n    return y\n',
     "integrals(s, y, p) returned shape (2, 3); expected (1, 3)"),
    ('FREE = ("q",)\n', "FREE names unknown parameters ['q']"),
    ('def bc(ya, yb, p):\n    return ya[:1]\n', "bc(ya, yb, p) returned shape (1,)"),
    ('PARAMETERS = [Parameter("lam", 2.0, "lam", "ode", period=1.0,\n'
     '                        period_shift={"w": 1.0})]\n',
     "parameter 'lam': period_shift and period_flip name no state ['w']"),
    ('PARAMETERS = [Parameter("lam", 2.0, "lam", "ode", period_flip=("u",))]\n',
     "parameter 'lam': period_shift and period_flip need a period"),
    ('from elastica_auto import Mirror\nMIRROR = Mirror({"u": "-w"}, ("lam",))\n',
     "MIRROR names ['w'], which are not states, parameters or ordinates"),
    ('from elastica_auto import Mirror\nMIRROR = Mirror({}, ("mu",), ("du1",))\n',
     "MIRROR names ['du1', 'mu']"),
    ('from elastica_auto import Mirror\nMIRROR = Mirror({"u": "v"})\n',
     "is not a signed permutation that is its own inverse"),
    ('from elastica_auto import Mirror\nMIRROR = Mirror({"u": "v", "v": "-u"})\n',
     "is not a signed permutation that is its own inverse"),
    ('from elastica_auto import Mirror\nMIRROR = Mirror({"u": 1})\n',
     "MIRROR: states must map state names to state names"),
    ('MIRROR = ("u",)\n', "MIRROR must be a Mirror, got tuple"),
    ('def symmetric_values(name, lo, hi, p):\n    return []\n',
     "symmetric_values(name, lo, hi, p) needs the hook symmetry(s, y, p)"),
])
def test_protocol_mistakes_are_named_on_load(tmp_path, text, words):
    path = tmp_path / "bad.py"
    path.write_text(GUESSING + text)
    with pytest.raises(ea.ProblemError, match=words.replace("(", r"\(").replace(")", r"\)")
                       .replace("[", r"\[").replace("]", r"\]")):
        ea.load_problem(str(path))


@pytest.mark.parametrize("text, words", [
    ('PARAMETERS = [Parameter("lam", 2.0, "lam", "ode"), Parameter("a\\x00b", 1.0, "q", "ode")]\n',
     "parameter name 'a\\x00b' cannot name a column"),
    ('ORDINATES = [Ordinate("d\\x00u0", "du0", lambda s, y, p: y[1, 0], "lam")]\n',
     "ordinate name 'd\\x00u0' cannot name a column"),
    ('STATES = ("u", "v\\x00w")\n', "state name 'v\\x00w' contains a NUL"),
])
def test_a_nul_in_a_name_is_refused_on_load(tmp_path, text, words):
    """Hostile L1: a NUL in a parameter, ordinate or state name is refused when the module is
    loaded (HDF5 names and strings end at a NUL: the branch was lost at its save, or the
    file read back as damaged), with the other names a branch file cannot hold."""
    path = tmp_path / "nul.py"
    path.write_text(GUESSING + text)
    with pytest.raises(ea.ProblemError) as info:
        ea.load_problem(str(path))
    assert words in str(info.value), str(info.value)


def test_an_exact_start_that_is_not_finite_is_a_user_error(tmp_path, cli_exe):
    """An exact_start that returns NaN (a 0/0 in the user's formula at the start's
    parameters) is refused as an exact start that does not solve the problem, naming the
    state and the place, exit status 2: it was a branch ending MX at its start (exit 1)
    with "no tangent at the start point (the error estimate is not finite ...)", which does
    not say that the start was NaN."""
    path = tmp_path / "nan_exact.py"
    nan_at_0 = "return np.vstack((0 * s, np.where(s == 0, np.nan, 0 * s)))"
    path.write_text(WRONG_EXACT.replace("return np.zeros((2, len(s)))", nan_at_0))
    problem = ea.load_problem(str(path))
    with pytest.raises(ea.StartError, match=r"its exact start at lam=0, b=0 is not finite: "
                       r"exact_start\(s, p\) returned nan in v at s = 0 \(1 of its 102 values"):
        ea.continuation(problem, {"lam": 0.0}, "lam")
    toml = tmp_path / "nan.toml"
    toml.write_text('equation = "nan_exact.py"\n[continuation]\nparameter = "lam"\n')
    result = run_cli(cli_exe, "run", toml, "--out", tmp_path / "out", "-q")
    assert result.returncode == EXIT_USER and result.stdout == ""
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("elastica-auto: error: ") and "is not finite" in line
    assert not (tmp_path / "out" / "nan.h5").exists()
