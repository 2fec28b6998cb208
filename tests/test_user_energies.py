"""Models the project does not ship, written by a user from docs/energy.md alone (hostile
round 4), each against an answer derived here independently of the engine.

- A column with a rotational spring at its base (stiffness k, an end term `B0 = k theta(0)^2 /
  2` on a natural end) and a dead load P at its free top. Linearised on the straight column,
  `theta'' + P theta = 0`, `theta'(1) = 0` (the free end) and `theta'(0) = k theta(0)` (the
  natural condition `-m(0) + k theta(0) = 0`): `theta = cos(w (1 - s))`, `w = sqrt(P)`, so the
  critical loads are the roots of `w tan(w) = k`, one in each `((n - 1) pi, (n - 1/2) pi)`.
  The straight column's index is the number of them below P.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
from scipy.optimize import brentq

import elastica_auto as ea
from elastica_auto.core.errors import EXIT_OK
from helpers import run_cli

SPRING_COLUMN = '''
import numpy as np

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
