"""What a seventh careful user met (brief hostile7): a load inside the rod.

* A density or rate with a step in s (a point load at mid-span written with
  ``Heaviside(1/2 - s)``) was derived and loaded, and its branch ended MX at the first step
  with "error estimate ... > tol": refused now when the module is loaded, saying how to write
  it.
* The way the docs give (examples/midspan_load.py: the two halves folded onto s in [0, 1],
  meeting at s = 1) against a shooting of the rod in its own arclength with the load's jump
  (solve_ivp on each half, a root in theta'(0)), and its index against the finite-difference
  Hessian of the rod's energy discretised here, not by the derived code.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, root

import elastica_auto as ea
from elastica_auto.energy import cache as energy_cache
from elastica_auto.execution import runfile
from helpers import EXAMPLES, run_plan

P = 3.0                                 # examples/midspan_load.toml


@pytest.fixture(autouse=True, scope="module")
def own_cache(tmp_path_factory):
    """The generated code in a folder of this module's own, not the user's cache."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
        mp.delenv(energy_cache.ENV, raising=False)
        yield


# -- a step in s is refused ---------------------------------------------------------------

MODULE = """
def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy
    s, P, F = sp.symbols("s P F", real=True)
    theta, x, xh = (sp.Function(n)(s) for n in ("theta", "x", "xh"))
    return Energy(density={density}, end1=P * x - F * xh, s=s, coordinates=[theta],
                  quadratures={{x: sp.cos(theta), xh: {rate}}},
                  fixed0={{theta: 0, x: 0, xh: 0}}, parameters={{P: 0.0, F: 0.0}})
"""
SMOOTH_DENSITY = "theta.diff(s) ** 2 / 2"
SMOOTH_RATE = "-sp.sin(theta)"


@pytest.mark.parametrize("density, rate, found", [
    (SMOOTH_DENSITY, "-sp.Heaviside(sp.Rational(1, 2) - s) * sp.sin(theta)",
     "the rate of xh contains Heaviside(1/2 - s)"),
    ("theta.diff(s) ** 2 / 2 * sp.Piecewise((1, s < 0.5), (2, True))", SMOOTH_RATE,
     "the density contains Piecewise"),
    ("theta.diff(s) ** 2 / 2 - F * sp.DiracDelta(s - 0.5) * sp.sin(theta)", SMOOTH_RATE,
     "the density contains DiracDelta"),
    ("theta.diff(s) ** 2 / 2 + sp.Max(s, 0.5) * sp.cos(theta)", SMOOTH_RATE,
     "the density contains Max"),
])
def test_a_step_in_s_is_refused_saying_how_to_write_it(tmp_path, density, rate, found):
    path = tmp_path / "mid.py"
    path.write_text(textwrap.dedent(MODULE.format(density=density, rate=rate)))
    with pytest.raises(ea.ProblemError) as info:
        ea.load_problem(path)
    message = str(info.value)
    assert found in message
    assert "jumps in s inside the rod" in message and "docs/energy.md" in message


def test_a_step_in_a_coordinate_alone_is_not_refused_as_a_point_of_the_rod():
    """Only s in the function's own argument makes the jump a point of the rod: a kink in a
    coordinate's value (a one-sided foundation Max(theta, 0)) is at no fixed s, and is not
    this refusal's (its second derivative, a DiracDelta of theta, is then refused as a
    function numpy has not)."""
    import sympy as sp

    from elastica_auto.energy.derive import _check_smooth_in_s
    s = sp.Symbol("s", real=True)
    theta = sp.Function("theta")(s)
    _check_smooth_in_s(theta.diff(s) ** 2 / 2 + sp.Max(theta, 0) ** 2 * (1 + s),
                       "the density", s)
    with pytest.raises(ea.ProblemError, match="jumps in s inside the rod"):
        _check_smooth_in_s(theta.diff(s) ** 2 / 2 + sp.Max(theta, s) ** 2, "the density", s)


# -- the folded halves against a shooting of the rod --------------------------------------

def shoot(k, F, dense=False):
    """theta'' = -P sin(theta) + F H(1/2 - sigma) cos(theta), theta(0) = 0, theta'(0) = k, on
    [0, 1/2] and [1/2, 1] (the jump at a node of the integration), with d/dk of (theta,
    theta') along."""
    def field(load):
        def f(t, z):
            th, om, v, w = z
            return [om, -P * np.sin(th) + load * np.cos(th), w,
                    (-P * np.cos(th) - load * np.sin(th)) * v]
        return f
    opts = dict(rtol=1e-11, atol=1e-12, dense_output=dense)
    lower = solve_ivp(field(F), (0.0, 0.5), [0.0, k, 0.0, 1.0], **opts)
    upper = solve_ivp(field(0.0), (0.5, 1.0), lower.y[:, -1], **opts)
    return lower, upper


def end_moment(k, F):
    """theta'(1) (zero at an equilibrium: the free tip) and its derivative in k."""
    _, upper = shoot(k, F)
    return upper.y[1, -1], upper.y[3, -1]


def equilibria(F):
    """theta'(0) of every equilibrium with |theta'(0)| < 6 (every one with |theta| < pi)."""
    ks = np.linspace(-6, 6, 241)
    g = [end_moment(k, F)[0] for k in ks]
    return [brentq(lambda k: end_moment(k, F)[0], a, b, xtol=1e-14)
            for a, b, ga, gb in zip(ks, ks[1:], g, g[1:]) if ga * gb < 0]


def dE_dF(k, F):
    """-x(1/2) = int_0^{1/2} sin(theta) d sigma."""
    lower, _ = shoot(k, F, dense=True)
    t = np.linspace(0, 0.5, 4001)
    th = lower.sol(t)[0]
    return float(np.sum((np.sin(th[1:]) + np.sin(th[:-1])) / 2 * np.diff(t)))


def fd_index(k, F, N=100):
    """The negative eigenvalues of the finite-difference Hessian of the rod's energy by the
    midpoint rule on N intervals of sigma, E_h = sum (theta_{j+1} - theta_j)^2 / (2 h)
    + P h sum cos(theta_mid) + F h sum_{sigma_mid < 1/2} sin(theta_mid), theta_0 = 0, at the
    shooting's solution at the nodes."""
    lower, upper = shoot(k, F, dense=True)
    h = 1.0 / N
    sig = np.linspace(0, 1, N + 1)[1:]
    th = np.where(sig <= 0.5, lower.sol(np.minimum(sig, 0.5))[0],
                  upper.sol(np.maximum(sig, 0.5))[0])
    on_lower = (np.arange(N) + 0.5) * h < 0.5

    def energy(t):
        t = np.concatenate([[0.0], t])
        mid = (t[1:] + t[:-1]) / 2
        return (np.sum(np.diff(t) ** 2) / (2 * h) + P * h * np.sum(np.cos(mid))
                + F * h * np.sum(np.sin(mid[on_lower])))

    d, n = 1e-4, N
    e = np.eye(n) * d
    e0 = energy(th)
    ei = np.array([energy(th + e[i]) for i in range(n)])
    H = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            H[i, j] = H[j, i] = (energy(th + e[i] + e[j]) - ei[i] - ei[j] + e0) / d ** 2
    return int(np.sum(np.linalg.eigvalsh(H) < 0))


@pytest.fixture(scope="module")
def midspan(tmp_path_factory):
    plan = runfile.load(EXAMPLES / "midspan_load.toml")
    return run_plan(plan, tmp_path_factory.mktemp("mid")).result.branches


def test_the_midspan_load_agrees_with_shooting_and_a_discrete_hessian(midspan):
    """Every UZ point of the first branch (F = 0.5 on both sides of its fold, -0.5, -2) is an
    equilibrium of the shooting: its mid-span deflection dE_dF = -x(1/2) is that of one
    root to 1e-7, and its index (rule and direct count) is the number of negative
    eigenvalues of the discrete Hessian there. The straight rod at P = 3 > pi^2/4 has
    index 1, and the fold is the shooting's (theta'(1) = 0 and d theta'(1)/dk = 0)."""
    br = midspan[0]
    uz = [p for p in br.points if p.type == "UZ"]
    assert [p.params["F"] for p in uz] == [0.5, 0.5, -0.5, -2.0]
    by_F = {F: equilibria(F) for F in {0.5, -0.5, -2.0}}
    for p in uz:
        F = p.params["F"]
        (k,) = [k for k in by_F[F] if abs(dE_dF(k, F) - p.ordinates["dE_dF"]) < 1e-7]
        assert p.index == p.index_direct == fd_index(k, F)
    assert [p.index for p in uz] == [1, 0, 0, 0]
    (lp,) = br.folds
    fold = root(lambda z: end_moment(*z), [1.0, 0.69], tol=1e-13)
    assert fold.success
    assert lp.params["F"] == pytest.approx(fold.x[1], rel=1e-8)
    assert lp.ordinates["dE_dF"] == pytest.approx(dE_dF(*fold.x), rel=1e-7)
    assert br.transition(lp) == "1 -> 0"
    assert br.points[0].index == 1 == fd_index(0.0, 0.0)


# -- a module's NaN in the Jacobian is the module's, not a singular Jacobian ----------------

BRATU_NAN = '''
"""Two uncoupled Bratu problems, u'' + lam exp(u) = 0 = w'' + lam exp(w), all ends 0, whose
rhs is NaN beyond lam = 2 (the branch crosses a branch point's test there)."""
import numpy as np
from elastica_auto import Parameter

STATES = ("u", "w", "v", "z")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode")]


def rhs(s, y, p):
    if p["lam"] > 2:
        return np.full_like(y, np.nan)
    return np.vstack((y[2], y[3], -p["lam"] * np.exp(y[0]), -p["lam"] * np.exp(y[1])))


def bc(ya, yb, p):
    return np.array((ya[0], yb[0], ya[1], yb[1]))


def exact_start(s, p):
    return np.zeros((4, len(s))) if p["lam"] == 0 else None
'''
BRATU_NAN_JAC = '''
"""Bratu, u'' + lam exp(u) = 0, u(0) = u(1) = 0, whose rhs_jac is NaN beyond lam = 2."""
import numpy as np
from elastica_auto import Parameter

STATES = ("u", "v")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode")]


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["lam"] * np.exp(y[0]) if p["lam"] <= 2 else np.nan
    return jac


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def exact_start(s, p):
    return np.zeros((2, len(s))) if p["lam"] == 0 else None
'''


@pytest.mark.parametrize("where", ["rhs", "rhs_jac"])
def test_a_jacobian_the_module_makes_nan_is_said_to_be_the_modules(tmp_path, where):
    """The module's values are NaN beyond lam = 2 (the rhs of two uncoupled Bratu problems,
    whose central differences in lam at a point just below 2 read lam > 2; or the rhs_jac of
    one), the residual at the last point finite: the branch ends MX saying the module
    returned NaN there. It said "a singular Jacobian" (rhs), which sends the user to the
    end conditions, and ended with an internal error, a NaN count of mesh intervals from
    the kernel's error estimate (rhs_jac: exit status 4, the engine blamed)."""
    path = tmp_path / "bratu_nan.py"
    path.write_text(BRATU_NAN if where == "rhs" else BRATU_NAN_JAC)
    (br,) = ea.continuation(ea.load_problem(path), {"lam": 0.0}, "lam", bounds=(-1, 4),
                            uz=[1, 2, 3], max_points=40)
    assert br.end == "MX"
    assert "the equation module returned NaN or inf there" in br.message, br.message
    assert "singular Jacobian" not in br.message


# -- a second variation whose A is not positive definite is said so -------------------------

BRATU_LEGENDRE = '''
"""Bratu, u'' + lam exp(u) = 0, u(0) = u(1) = 0, whose second variation's A turns negative
beyond lam = 2 (a wrong hook: the Legendre condition fails there)."""
import numpy as np
from elastica_auto import Parameter, SecondVariation

STATES = ("u", "v")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode")]


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def exact_start(s, p):
    return np.zeros((2, len(s))) if p["lam"] == 0 else None


def second_variation(s, y, p):
    return SecondVariation(-1.0 if p["lam"] > 2 else 1.0, -p["lam"] * np.exp(y[0]),
                           fixed0=[0], fixed1=[0])
'''


def _branch_without_index_past_2(tmp_path, name, text):
    """The branch of the module ``text`` (saved as ``name``) from lam = 0 to 3, whose form has
    no index past lam = 2: its points there uncounted (LP/BP aside), those below counted, and
    its one warning, which names how many points and where."""
    path = tmp_path / name
    path.write_text(text)
    (br,) = ea.continuation(ea.load_problem(path), {"lam": 0.0}, "lam", bounds=(-1, 3),
                            max_points=30)
    undefined = [k for k, p in enumerate(br.points, 1) if p.index_direct == -1
                 and p.type not in ("LP", "BP")]
    assert undefined and all(br.points[k - 1].params["lam"] > 2 for k in undefined)
    assert all(p.index_direct >= 0 for p in br.points if p.params["lam"] < 2)
    (warning,) = [w for w in br.warnings if "no stability index" in w]
    assert warning.startswith(f"no stability index at {len(undefined)} points "
                              f"(pt {undefined[0]} to {undefined[-1]}, lam from ")
    return br, undefined, warning


def test_points_without_an_index_are_a_warning_of_the_branch(tmp_path):
    """Where A is not positive definite the form has no index (docs/stability.md): each such
    point's index is unknown and its note says why, which nothing a user reads showed (the
    run exited 0 with an empty index column). The branch has one warning naming how many
    points, where, and the first reason; `run` and `show` print a branch's warnings."""
    _, _, warning = _branch_without_index_past_2(tmp_path, "legendre.py", BRATU_LEGENDRE)
    assert "A is not positive definite" in warning and "legendre.py" in warning


@pytest.mark.parametrize("where", ["B", "E1"])
def test_a_second_variation_that_is_not_finite_is_a_warning_of_the_branch(tmp_path, where):
    """A hook whose B (NaN on s > 1/2) or end term is NaN beyond lam = 2 at finite states:
    those points have no index, and the reason was dropped (only the Legendre condition's
    was kept as the point's note), so the run said nothing. Now the note and the branch's
    one warning say where the form is not finite; below lam = 2 the points are counted."""
    text = BRATU_LEGENDRE.replace(
        "return SecondVariation(-1.0 if p[\"lam\"] > 2 else 1.0, -p[\"lam\"] * np.exp(y[0]),",
        "bad = np.nan if p[\"lam\"] > 2 else 0.0\n"
        "    return SecondVariation(1.0, -p[\"lam\"] * np.exp(y[0])"
        + (" + np.where(s > 0.5, bad, 0.0)," if where == "B" else ", E1=bad,"))
    assert "bad = np.nan" in text
    br, undefined, warning = _branch_without_index_past_2(tmp_path, "nan_form.py", text)
    said = "nan_form.py: second_variation is not finite "
    assert said in warning and said in br.points[undefined[0] - 1].note
    if where == "B":    # the first point where it is not finite: the first node past 1/2
        at = float(warning.split(said + "at s = ")[1].split(":")[0])
        assert 0.5 < at < 0.6
    else:
        assert said + "in an end term" in warning


# -- a value given to a free parameter from a label is refused, not ignored -----------------

def test_a_value_for_a_free_parameter_from_a_label_is_refused(tmp_path, cli_exe):
    """The clamped column's lateral reaction Q is solved for (its energy's multiplier). From a
    label, `--set Q=1` was accepted and ignored: the branch started at the label's Q = 0, as
    h5py reads it from the output. It is a user error naming the parameter and the label's
    value; the label's own value is no change and is accepted."""
    import h5py

    from helpers import run_cli
    toml = tmp_path / "col.toml"
    toml.write_text(f'equation = "{EXAMPLES / "clamped_column.py"}"\n'
                    '[parameters]\nP = 0\n[continuation]\nparameter = "P"\n'
                    'directions = "+"\nbounds = [-1, 20]\nuz = [10]\n')
    assert run_cli(cli_exe, "run", toml, "--out", tmp_path / "a", "-q").returncode == 0
    with h5py.File(tmp_path / "a" / "col.h5", "r") as f:
        uz = list(f["branches/001/columns/type"][()]).index(b"UZ")     # UZ1
        q_stored = float(f["branches/001/columns/Q"][uz])
    assert abs(q_stored) < 1e-9
    bad = run_cli(cli_exe, "run", toml, "--from", tmp_path / "a" / "col.h5:UZ1", "--set", "Q=1",
                  "--out", tmp_path / "b", "-q")
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert bad.stderr.startswith("elastica-auto: error: ")
    assert "Q = 1 is given, but Q is a free parameter of this run, solved for" in bad.stderr
    assert not (tmp_path / "b" / "col.h5").exists()
    same = run_cli(cli_exe, "run", toml, "--from", tmp_path / "a" / "col.h5:UZ1", "--set",
                   f"Q={q_stored!r}", "--out", tmp_path / "c", "-q")
    assert same.returncode == 0, same.stderr
