"""Models the project does not ship, written by a user from docs/energy.md alone (hostile
round 4), each against an answer derived here independently of the engine.

- A column with a rotational spring at its base (stiffness k, an end term `B0 = k theta(0)^2 /
  2` on a natural end) and a dead load P at its free top. Linearised on the straight column,
  `theta'' + P theta = 0`, `theta'(1) = 0` (the free end) and `theta'(0) = k theta(0)` (the
  natural condition `-m(0) + k theta(0) = 0`): `theta = cos(w (1 - s))`, `w = sqrt(P)`, so the
  critical loads are the roots of `w tan(w) = k`, one in each `((n - 1) pi, (n - 1/2) pi)`.
  The straight column's index is the number of them below P.
- Half of a clamped circular arch under a load on its apex (a constraint with its
  multiplier, the thrust): its snap-through folds against shooting, its index against the
  Hessian of its energy discretised here.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
from pytest import approx as pytest_approx
from scipy.optimize import brentq

import elastica_auto as ea
from elastica_auto.core.errors import EXIT_OK
from helpers import run_cli

SPRING_COLUMN = '''
import numpy as np
from pytest import approx as pytest_approx

from elastica_auto import Ordinate


def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy, Param
    s, P, k = sp.symbols("s P k", real=True)
    theta, x, y = (sp.Function(n)(s) for n in ("theta", "x", "y"))
    return Energy(density=theta.diff(s) ** 2 / 2, end0=k * theta ** 2 / 2, end1=P * y,
                  s=s, coordinates=[theta], quadratures={x: -sp.sin(theta), y: sp.cos(theta)},
                  fixed0={x: 0, y: 0},
                  parameters={P: Param(0.0, doc="the dead load on the top"),
                              k: Param(2.0, doc="the base spring's stiffness")})


def exact_start(s, p):
    return np.vstack((np.zeros((3, len(s))), s))
'''

# a gauge a user adds: the tip's angle over the base's, 0/0 on the straight column
GAUGE = '''

def _ratio(s, y, p):
    with np.errstate(invalid="ignore", divide="ignore"):
        return float(np.float64(y[0, -1]) / np.float64(y[0, 0]))


ORDINATES = [Ordinate("ratio", "r", _ratio, None, "theta(1) / theta(0)")]
'''


def critical_loads(k: float, count: int) -> list[float]:
    """The roots of sqrt(P) tan(sqrt(P)) = k, the straight column's critical loads."""
    out = []
    for n in range(count):
        lo, hi = n * math.pi + 1e-12, (n + 0.5) * math.pi - 1e-12
        out.append(brentq(lambda w: w * math.tan(w) - k, lo, hi, xtol=1e-15) ** 2)
    return out


def _module(tmp_path, text):
    path = tmp_path / "spring_column.py"
    path.write_text(textwrap.dedent(text))
    return ea.load_problem(path, cache=False)


def _straight(problem):
    (branch,) = ea.continuation(problem, {"P": 0.0}, "P", bounds=(-1, 16), ds=0.2, ds_max=1.0)
    return branch


def test_a_spring_at_the_clamp_buckles_where_sqrt_p_tan_sqrt_p_is_k(tmp_path):
    """The end term B0 on a natural end: the branch points of the straight column are the
    closed form's critical loads, and its index counts those below P."""
    branch = _straight(_module(tmp_path, SPRING_COLUMN))
    loads = critical_loads(2.0, 2)                   # 1.15966, 13.2758
    bps = [p.params["P"] for p in branch.labelled if p.type == "BP"]
    np.testing.assert_allclose(bps, loads, rtol=1e-8)
    for p in branch.points:
        if p.type or min(abs(p.params["P"] - c) for c in loads) < 1e-6:
            continue
        assert p.index == sum(c < p.params["P"] for c in loads), p.params


def test_a_gauge_that_is_nan_leaves_the_index_alone(tmp_path):
    """An ordinate of the user's own that is NaN (0/0 on the straight column) says nothing
    about the state's stability: the index is counted as without it (it was -1 at every
    point, the branch points' transitions lost, without a word)."""
    branch = _straight(_module(tmp_path, SPRING_COLUMN + GAUGE))
    assert all(math.isnan(r) for r in branch.columns["ratio"])
    loads = critical_loads(2.0, 2)
    for p in branch.points:
        if p.type or min(abs(p.params["P"] - c) for c in loads) < 1e-6:
            continue
        assert p.index_direct == p.index == sum(c < p.params["P"] for c in loads), p.params
    assert [branch.transition(p) for p in branch.labelled if p.type == "BP"] == ["0 -> 1",
                                                                                   "1 -> 2"]


# Half of a circular arch clamped at both ends (clamp to apex, by the symmetry of a symmetric
# load), its natural curvature -a (theta the angle from the horizontal, a the clamp's), the
# half-span held by the constraint x(1) = sin(a) / a with the thrust H its multiplier (E - H
# (x(1) - X)), theta(1) = 0 at the apex, and a dead load F down on the apex (its potential F
# y(1)). Continued in F from the unloaded arch, it snaps through at a fold.
ARCH = '''
import numpy as np
from pytest import approx as pytest_approx


def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy, Param
    s, F, H, a = sp.symbols("s F H a", real=True)
    theta, x, y = (sp.Function(n)(s) for n in ("theta", "x", "y"))
    return Energy(density=(theta.diff(s) + a) ** 2 / 2, end1=F * y,
                  s=s, coordinates=[theta], quadratures={x: sp.cos(theta), y: sp.sin(theta)},
                  fixed0={theta: a, x: 0, y: 0}, fixed1={theta: 0, x: sp.sin(a) / a},
                  multipliers={x: -H},
                  parameters={F: Param(0.0, doc="the load on the apex"),
                              H: Param(0.0, doc="the thrust, solved for"),
                              a: Param(0.5, doc="the clamp's angle")})


def exact_start(s, p):
    a = p["a"]
    th = a * (1 - s)
    return np.vstack((th, np.zeros_like(s), (np.sin(a) - np.sin(th)) / a,
                      (np.cos(th) - np.cos(a)) / a))
'''


def test_a_shooting_hook_that_free_parameters_keep_unused_is_said(tmp_path, cli_exe):
    """A module with free parameters (the arch's thrust) cannot have its equilibria
    enumerated by its `shooting` hook (docs/equation-modules.md): a run whose fold bounds a
    stable segment says that the hook is not used and why, instead of leaving the snap-back
    table empty without a word."""
    (tmp_path / "arch.py").write_text(ARCH + "\n\ndef shooting(p):\n    raise RuntimeError\n")
    (tmp_path / "arch.toml").write_text(
        'equation = "arch.py"\nstart = "trivial"\n[parameters]\nF = 0\n[continuation]\n'
        'parameter = "F"\nbounds = [-100, 100]\nstop = ["LP2"]\n[options]\nds = 0.5\n'
        'ds_max = 2.0\n')
    result = run_cli(cli_exe, "run", tmp_path / "arch.toml", "--out", tmp_path / "out", "-q",
                     "-j", "1")
    assert result.returncode == EXIT_OK, result.stderr
    assert ("warning: no snap-back targets: the module's shooting hook is not used with the "
            "free parameters H (the shooting scan enumerates the module's states at fixed "
            "parameters, and the free parameters are solved for)") in result.stdout


def _arch_shot(a, apex, guess):
    """Shooting, independent of the engine: theta'' = F cos(theta) + H sin(theta) (the
    Euler-Lagrange equation of (theta' + a)^2 / 2 + F sin(theta) - H cos(theta)) from
    theta(0) = a, x(0) = y(0) = 0, with theta'(0), F and H found so that theta(1) = 0,
    x(1) = sin(a) / a and the apex at y(1) = apex (the load the unknown: the load that holds
    the apex there)."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import fsolve

    def ends(u):
        k0, F, H = u
        z = solve_ivp(lambda s, z: [z[1], F * np.cos(z[0]) + H * np.sin(z[0]), np.cos(z[0]),
                                    np.sin(z[0])],
                      (0, 1), [a, k0, 0, 0], method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
        return [z[0], z[2] - math.sin(a) / a, z[3] - apex]
    u = fsolve(ends, guess, xtol=1e-12)
    assert np.abs(ends(u)).max() < 1e-10, ends(u)
    return u


def _arch_index(a, F, H, theta, n=200):
    """The index of the arch's equilibrium near ``theta`` (on a grid of n intervals) by a
    finite-difference Hessian of its energy discretised here, independently of the engine:
    E_h = sum h ((theta_j+1 - theta_j) / h + a)^2 / 2 + F h sum sin(theta_mid), theta held
    at the ends, on the constraint c = h sum cos(theta_mid) - sin(a) / a = 0 (multiplier
    mu = -H). Newton on the discrete stationarity (with the multiplier), then the negative
    eigenvalues of the Hessian of the Lagrangian (central differences of its gradient) on
    the constraint's tangent space."""
    h = 1.0 / n

    def full(t):
        return np.concatenate([[a], t, [0.0]])

    def gradient(t, mu):          # of E_h + mu c in the free values theta_1 .. theta_n-1
        th = full(t)
        slope, mid = np.diff(th) / h + a, (th[1:] + th[:-1]) / 2
        node = h * (F * np.cos(mid) - mu * np.sin(mid)) / 2     # each interval's midpoint
        g = np.zeros(n + 1)
        g[:-1] += -slope + node
        g[1:] += slope + node
        return g[1:-1]

    def constraint(t):
        th = full(t)
        return h * np.sum(np.cos((th[1:] + th[:-1]) / 2)) - math.sin(a) / a

    def constraint_gradient(t):
        th = full(t)
        half = -h * np.sin((th[1:] + th[:-1]) / 2) / 2
        return (half[:-1] + half[1:])

    def hessian(t, mu, e=1e-6):
        return np.array([(gradient(t + d, mu) - gradient(t - d, mu)) / (2 * e)
                         for d in np.eye(len(t)) * e])

    t = np.interp(np.linspace(0, 1, n + 1), np.linspace(0, 1, len(theta)), theta)[1:-1]
    mu = -H
    for _ in range(20):
        w = constraint_gradient(t)
        kkt = np.block([[hessian(t, mu), w[:, None]], [w[None, :], np.zeros((1, 1))]])
        step = np.linalg.solve(kkt, -np.concatenate([gradient(t, mu), [constraint(t)]]))
        t, mu = t + step[:-1], mu + step[-1]
        if np.abs(step).max() < 1e-11:
            break
    assert np.abs(gradient(t, mu)).max() < 1e-9 and abs(constraint(t)) < 1e-12
    basis = np.linalg.qr(np.column_stack([constraint_gradient(t),
                                          np.eye(len(t))[:, :-1]]))[0][:, 1:]
    return int(np.sum(np.linalg.eigvalsh(basis.T @ hessian(t, mu) @ basis) < 0))


def test_the_arch_snaps_through_at_the_load_of_its_own_shooting(tmp_path):
    """The fold: the load that holds the apex at the engine's fold's height, by shooting, is
    the engine's and a maximum (the loads holding it a little higher or lower are smaller);
    the second fold, a minimum, likewise. The index before, between and after the folds, by
    the fold rule and combined, is that of the energy discretised independently (0, 1, 0)."""
    problem = _module(tmp_path, ARCH)
    (branch,) = ea.continuation(problem, {"F": 0.0}, "F", bounds=(-100, 8), ds=0.5,
                                ds_max=2.0)
    folds = branch.folds
    assert [p.name for p in folds] == ["LP1", "LP2"]
    assert [branch.transition(p) for p in folds] == ["0 -> 1", "1 -> 0"]
    for p, top in zip(folds, (True, False)):
        apex, guess = p.ordinates["dE_dF"], [p.state.y[1, 0] - 0.5, p.params["F"],
                                             p.params["H"]]
        k0, F, H = _arch_shot(0.5, apex, guess)
        assert F == pytest_approx(p.params["F"], rel=1e-7)
        assert H == pytest_approx(p.params["H"], rel=1e-6)
        for d in (-1e-3, 1e-3):
            near = _arch_shot(0.5, apex + d, [k0, F, H])[1]
            assert (near < F) if top else (near > F)
    cols = branch.columns
    for k in range(0, len(branch.points), 7):
        p = branch.points[k]
        if p.type == "LP":
            continue
        fd = _arch_index(0.5, cols["F"][k], cols["H"][k], p.profile[0])
        assert p.index == p.index_rule == fd, k


def test_a_distinguished_ordinate_that_is_nan_at_a_fold_leaves_the_rule_unapplied(tmp_path):
    """Bratu's hand-written module (tests/reference/bratu.py) with its distinguished ordinate
    dE/dlam NaN above lam = 3.4, around its fold at lam_c = 3.5138: the fold rule cannot read
    the fold's sign there and restarts from the direct count past it, as where the parameter
    has no distinguished ordinate. It raised ValueError (int of NaN) in the labelling, an
    internal error (exit 4) ending the branch MX with every index lost. Below lam = 3.4 the
    lower family is stable and the upper has index 1 (the closed form's fold, the module's
    own tests)."""
    from helpers import REFERENCE
    source = (REFERENCE / "bratu.py").read_text()
    head = "def _de_dlam(s, y, p):\n"
    assert source.count(head) == 1
    path = tmp_path / "bratu_nan.py"
    path.write_text(source.replace(head, head + "    if p['lam'] > 3.4:\n"
                                                "        return float('nan')\n"))
    problem = ea.load_problem(path)
    (branch,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 5), stop=["u_half > 3"])
    assert branch.end == "EP" and [p.name for p in branch.folds] == ["LP1"]
    fold = branch.points.index(branch.folds[0])
    for k, p in enumerate(branch.points):
        if p.params["lam"] < 3.4:
            assert p.index == (0 if k < fold else 1), (k, p.params)
