"""User points and parameter bounds in a step that passes a fold.

Near psi ~ 0.8173 (eps = 0.25, P = pi^2/4) the psi-branch from the straight rod turns back.
A continuation step that passes the fold goes from psi_a below the fold to psi_b below the fold,
so every value between max(psi_a, psi_b) and the fold's psi is crossed twice within the step.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto as ea
import shooting
from helpers import elastica_run_file, run_plan
from elastica_auto.execution import runfile

P, EPS = math.pi ** 2 / 4, 0.25


@pytest.fixture(scope="module")
def the_fold():
    """(k0, psi) of the first fold of the straight-rod branch, by shooting from a rough guess
    (psi in (0.7, 0.9) is where the paper's figure 4 shows it)."""
    k0, psi, _ = shooting.fold(P, EPS, 1.8, 0.8)
    assert 0.8 < psi < 0.83
    return k0, psi


def _run(tmp_path, **kw):
    path = elastica_run_file(tmp_path / "near_fold.toml", directions="+", **kw)
    return run_plan(runfile.load(path), tmp_path / "out").result.branches[0]


def test_user_values_next_to_a_fold_are_labelled_on_both_sides(tmp_path, the_fold):
    k0_fold, psi_fold = the_fold
    values = [0.80, 0.81, 0.815, 0.817]
    assert all(v < psi_fold for v in values)
    br = _run(tmp_path, bounds=("-1", "1"), extra=f"uz = {values}\n")
    uz = [p for p in br.points if p.type == "UZ"]
    for v in values:
        # two distinct equilibria at psi = v straddle the fold (shooting, bracketed by k0_fold)
        lower, upper = shooting.roots_beside_fold(v, P, EPS, k0_fold, 0.5)
        got = sorted(p.ordinates["m0"] for p in uz if abs(p.params["psi"] - v) < 1e-12)
        assert len(got) == 2, (v, got)
        np.testing.assert_allclose(got, [lower, upper], rtol=0, atol=1e-5)


def test_a_branch_never_leaves_its_bounds(tmp_path, the_fold):
    _, psi_fold = the_fold
    upper = 0.815
    assert upper < psi_fold     # the branch must stop at psi = upper before it folds
    br = _run(tmp_path, bounds=("-1", str(upper)))
    psi = np.array([p.params["psi"] for p in br.points])
    assert np.all(psi <= upper + 1e-12), psi.max()
    assert br.end == "EP" and br.points[-1].params["psi"] == pytest.approx(upper, abs=1e-12)


def test_stop_at_the_second_fold(tmp_path, the_fold):
    """stop = ["LP2"] ends the branch at its second fold: the last point is that LP, at the
    mirror image of the first fold translated by one period, psi2 = -psi1 - 2 pi (mirror
    symmetry psi -> -psi and 2 pi periodicity), computed here by shooting."""
    br = _run(tmp_path, bounds=("-4*pi", "4*pi"), extra='stop = ["LP2"]\n')
    assert br.end == "LP" and "LP2" in br.message
    assert [p.type for p in br.points].count("LP") == 2
    last = br.points[-1]
    assert last.type == "LP"
    assert all(p.arclength <= last.arclength for p in br.points)
    assert abs(last.params["psi"] - (-the_fold[1] - 2 * math.pi)) < 1e-8


def test_max_points_ends_with_an_end_point(tmp_path):
    br = _run(tmp_path, bounds=("-4*pi", "4*pi"), extra="[options]\nmax_points = 12\n")
    assert len(br.points) == 12
    assert br.points[-1].type == "EP" and br.end == "EP" and "max_points" in br.message


CIRCLE = """\
\"\"\"u' = 0, u(0)^2 + lam^2 = 1: constant solutions, on the unit circle of (u, lam).\"\"\"
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u",)
PARAMETERS = [Parameter("lam", 0.0, r"\\lambda", "fixed")]
ORDINATES = [Ordinate("u0", "u(0)", lambda s, y, p: y[0, 0], parameter="lam")]


def rhs(s, y, p):
    return np.zeros_like(y)


def bc(ya, yb, p):
    return np.array([ya[0] ** 2 + p["lam"] ** 2 - 1.0])


def exact_start(s, p):
    return np.ones((1, len(s))) if p["lam"] == 0 else None
"""


@pytest.mark.parametrize("direction", ["+", "-"])
@pytest.mark.parametrize("way", ["both", "ahead", "in a step"])
def test_a_closed_loop_ends_where_it_started(tmp_path, monkeypatch, direction, way):
    """The constant solutions u on the unit circle u^2 + lam^2 = 1, from (1, 0): the branch
    goes round once, through its two folds at lam = +-1, and ends (EP) at its own start
    point: not round and round until max_points. Each of the two checks closes it alone:
    the start ahead of the last point within the next step, or passed inside a step."""
    from elastica_auto.branches.loops import Closure
    if way == "ahead":
        monkeypatch.setattr(Closure, "place", lambda self, walk, placement: None)
    elif way == "in a step":
        monkeypatch.setattr(Closure, "ahead", lambda self, walk, ds: None)
    path = tmp_path / "circle.py"
    path.write_text(CIRCLE)
    problem = ea.load_problem(str(path))
    (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", directions=direction, ds=0.1,
                            ds_max=0.3, max_points=500)
    assert br.end == "EP" and br.message.startswith("closed loop"), br.message
    assert br.points[-1].params == br.points[0].params
    lam, u = br.columns["lam"], br.columns["u0"]
    np.testing.assert_allclose(u ** 2 + lam ** 2, 1.0, atol=1e-10)
    turn = np.diff(np.unwrap(np.arctan2(u, lam))) * (1 if direction == "-" else -1)
    assert np.all(turn > 0) and np.sum(turn) == pytest.approx(2 * math.pi, abs=1e-12)
    folds = sorted(p.params["lam"] for p in br.points if p.type == "LP")
    np.testing.assert_allclose(folds, [-1.0, 1.0], atol=1e-9)



#: (f, bracket, closed-form root, simple and smooth: a few evaluations)
_ROOTS = [
    (lambda x: math.cos(x) - x, 0.0, 1.0, 0.7390851332151607, True),    # the Dottie number
    (lambda x: x ** 3 - 2.0, 0.0, 3.0, 2.0 ** (1.0 / 3.0), True),
    (lambda x: math.exp(x) - 10.0, -5.0, 5.0, math.log(10.0), True),
    (lambda x: (x - 1.0 / 3.0) ** 3, 0.0, 1.0, 1.0 / 3.0, False),       # a triple root
    (lambda x: (x - 0.123456) ** 5, -1.0, 2.0, 0.123456, False),
    (lambda x: 1.0 if x > 0.3 else -1.0, 0.0, 1.0, 0.3, False),         # a jump
]


@pytest.mark.parametrize("f, lo, hi, root, simple", _ROOTS)
@pytest.mark.parametrize("xtol", [1e-8, 1e-12])
def test_the_root_finder_of_the_events_brackets_each_root_to_its_tolerance(f, lo, hi, root,
                                                                          simple, xtol):
    """`events.brent` (every located event but folds): within xtol of the closed-form
    root, at an abscissa f was evaluated at; a simple root in a few evaluations, any other
    in no more than four per halving of the bracket (at a multiple root interpolation
    creeps towards it, with a bisection about every fourth step)."""
    from elastica_auto.branches.events import brent
    seen = []

    def counted(x):
        seen.append(x)
        return f(x)

    x = brent(counted, lo, hi, f(lo), f(hi), xtol)
    assert abs(x - root) <= xtol and x in [*seen, lo, hi]
    assert len(seen) <= (10 if simple else 4 * math.ceil(math.log2((hi - lo) / xtol)))


@pytest.mark.parametrize("q0, out", [(0.0, "-"), (12.0, "+")])
def test_a_start_on_a_bound_ends_the_direction_that_leaves_it_at_its_start(q0, out):
    """The straight heavy column (k0 = 0) is a solution at every load q, its branch the
    line along q (t_q = +-1): started on a bound of [0, 12] in both directions, the one that
    leaves the bounds is its start alone, one EP at q0, its message saying it left them; the
    other is the branch computed in that direction alone. No branch has two points at the
    same place (it had: the bound located at the start again, EP3 and EP4 at q = 0)."""
    problem = ea.load_problem("curved_heavy_column")
    params = {"q": q0, "k0": 0.0}
    inward = "+" if out == "-" else "-"
    both = ea.continuation(problem, params, "q", bounds=(0, 12), directions="both")
    (alone,) = ea.continuation(problem, params, "q", bounds=(0, 12), directions=inward)
    (left,) = [b for b in both if b.direction == (1 if out == "+" else -1)]
    (went,) = [b for b in both if b is not left]
    assert [p.type for p in left.points] == ["EP"] and left.end == "EP"
    assert left.points[0].params["q"] == q0
    assert left.message == (f"left the bounds at its start (q = {q0:g} is the "
                            f"{'lower' if q0 == 0 else 'upper'} bound, and this direction "
                            f"{'decreases' if out == '-' else 'increases'} q)")
    assert [(p.type, p.params["q"]) for p in went.points] == \
        [(p.type, p.params["q"]) for p in alone.points]
    assert went.points[-1].params["q"] == 12.0 - q0
    for b in both:
        q = [p.params["q"] for p in b.points]
        assert all(x != y for x, y in zip(q, q[1:]))


LINEAR = '''\
"""u'' + lam = 0, u(0) = u(1) = 0: u = lam s (1 - s) / 2; the module fails past lam = 0.5
(FAIL: "nan", its functions return NaN; "raise", they raise)."""
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u", "du")
PARAMETERS = [Parameter("lam", 0.0, r"\\\\lambda", "ode")]
FAIL = "{fail}"


def _check(p):
    if p["lam"] > 0.5:
        if FAIL == "raise":
            raise ValueError("no solution past lam = 0.5")
        return np.nan
    return 1.0


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.ones_like(y[0]) * _check(p)))


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def guess(s, p):
    return np.vstack((p["lam"] * s * (1 - s) / 2, p["lam"] * (1 - 2 * s) / 2))


ORDINATES = [Ordinate("umid", "$u(1/2)$", lambda s, y, p: y[0, len(s) // 2], None)]
'''


@pytest.mark.parametrize("fail, method", [("nan", "step_failed"), ("raise", "ended_early")])
def test_the_stepper_hands_its_failures_to_the_failure_kind(tmp_path, monkeypatch, fail,
                                                           method):
    """Issue 48: MX is an event (``kinds.Failure``, ``registry.FAILURE``): the stepper hands
    a step rejected down to ``ds_min`` (NaN from the module) and an exception (the module
    raising) to it, and the branch ends as the kind says: at its last accepted point, before
    lam = 0.5 where the module fails, labelled MX, with the kind's message and the failure's
    record as its diagnostics."""
    from elastica_auto.branches import kinds, registry

    calls = []

    class Recording(kinds.Failure):
        def step_failed(self, walk, retry, history):
            calls.append("step_failed")
            super().step_failed(walk, retry, history)

        def ended_early(self, *args, **kwargs):
            calls.append("ended_early")
            super().ended_early(*args, **kwargs)

    monkeypatch.setattr(registry, "FAILURE", Recording())
    path = tmp_path / "linear.py"
    path.write_text(LINEAR.replace("{fail}", fail))
    problem = ea.load_problem(str(path))
    result = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(0, 2), directions="+",
                             ds=0.1, ds_max=0.1, ds_min=1e-4)
    br = result[0]
    assert calls == [method]
    last = br.points[-1]
    assert (br.end, last.type) == ("MX", "MX")
    assert last.params["lam"] <= 0.5 and last.ordinates["umid"] == pytest.approx(
        last.params["lam"] / 8, rel=1e-6)
    if fail == "nan":
        assert br.message.startswith("corrector failed at ds < ds_min = 0.0001")
        assert "(the equation module returned NaN or inf there)" in br.message
        assert br.diagnostics["step"] == len(br.points) and br.diagnostics["history"]
    else:
        assert br.message.startswith("ValueError: no solution past lam = 0.5")
        assert br.diagnostics["exception"] == "ValueError"
        assert br.diagnostics["step"] == len(br.points)
