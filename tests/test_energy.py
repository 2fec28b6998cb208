"""Energy-first equation modules (issue 47; elastica_auto/energy, docs/energy.md).

Each derived module is checked against something derived independently of it:

* the hand-written modules the shipped energy-first ones replaced (tests/reference:
  elastica_lever_arm.py, bratu.py, clamped_column.py, guided_column.py): residuals,
  Jacobians, parameter derivatives and second variations at random states and parameters to
  1e-12, and whole runs (every fold and branch point, every point's index, rule and direct
  count); the spatial rod's in tests/test_energy_rod.py, the pinned elastica's in
  tests/test_pinned.py;
* closed forms for models the project never had: the heavy column's buckling load (a zero of
  J_{-1/3}) and the critical loads of a shearable column on an elastic foundation;
* the finite-difference Hessian of an energy discretised here (midpoint rule), not by the
  derived code: a density that is not quadratic in the derivatives (the Legendre transform
  by Newton's method), depends on s and couples two coordinates; an isoperimetric
  constraint whose rate contains theta' (the integration by parts along a solution);
* the energy along a branch: its derivative in the continued parameter, by differences of
  the derived E, is the distinguished ordinate (the reaction, with the opposite sign, for a
  parameter in an essential end value);
* tests with teeth: an ordinate of the wrong sign makes the fold rule disagree with the direct
  count; a wrong natural end condition fails the residual comparison.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import jv

import elastica_auto as ea
from elastica_auto.energy import cache as energy_cache
from elastica_auto.energy.loader import execute
from elastica_auto.execution import runfile
from elastica_auto.model.second_variation import as_second_variation
from helpers import EXAMPLES, REFERENCE, REPO, ROTATING_ARM, central_jacobian, run_plan


@pytest.fixture(autouse=True, scope="module")
def own_cache(tmp_path_factory):
    """The generated code in a folder of this module's own, not the user's cache."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
        mp.delenv(energy_cache.ENV, raising=False)
        yield


def module_file(tmp_path, name, text) -> Path:
    path = tmp_path / f"{name}.py"
    path.write_text(textwrap.dedent(text))
    return path


def random_states(rng, n, m=13):
    s = np.sort(np.r_[0.0, rng.uniform(0, 1, m - 2), 1.0])
    return s, rng.uniform(-2, 2, (n, m))


def assert_same_system(derived, reference, params, rows, rng, trials=40, state_map=None,
                       param_map=None):
    """rhs, rhs_jac, rhs_dp, bc (its rows ``rows`` in the reference's order), bc_jac, bc_dp
    and the second variation of ``derived`` and ``reference`` at random states and
    parameters (``params``: name -> (lo, hi)), to 1e-12; to 1e-8 where the reference has
    no analytic derivative (the engine's central differences stand in for it).
    ``param_map``: the derived parameters' values from the reference's (a sign
    convention)."""
    param_map = param_map or (lambda p: p)
    for _ in range(trials):
        p = {k: rng.uniform(*bounds) for k, bounds in params.items()}
        q = param_map(p)
        s, y = random_states(rng, reference.n)
        ya, yb = y[:, 0], y[:, -1]

        def close(a, b, what, differences=False):
            tol = 1e-8 if differences else 1e-12
            np.testing.assert_allclose(a, b, rtol=0, atol=tol * (1 + np.abs(b).max()),
                                       err_msg=f"{what} at {p}")

        close(derived.rhs(s, y, q), reference.rhs(s, y, p), "rhs")
        close(derived.rhs_jac(s, y, q), reference.rhs_jac(s, y, p), "rhs_jac",
              reference._rhs_jac is None)
        close(derived.bc(ya, yb, q)[rows], reference.bc(ya, yb, p), "bc")
        for mine, theirs in zip(derived.bc_jac(ya, yb, q), reference.bc_jac(ya, yb, p)):
            close(mine[rows], theirs, "bc_jac", reference._bc_jac is None)
        for name in reference.parameters:
            sign = np.sign(param_map({**p, name: 1.0})[name]) if name in q else 1.0
            close(sign * derived.rhs_dp(s, y, q, name), reference.rhs_dp(s, y, p, name),
                  f"rhs_dp {name}", reference._rhs_dp is None)
            close(sign * derived.bc_dp(ya, yb, q, name)[rows],
                  reference.bc_dp(ya, yb, p, name), f"bc_dp {name}", reference._bc_dp is None)
        mine = as_second_variation(derived.second_variation(s, y, q), "derived")
        theirs = as_second_variation(reference.second_variation(s, y, p), "reference")
        for what in ("A", "B", "C"):
            a, b = getattr(mine, what), getattr(theirs, what)
            close(np.broadcast_to(a, np.broadcast_shapes(a.shape, b.shape)),
                  np.broadcast_to(b, np.broadcast_shapes(a.shape, b.shape)), what)
        close(mine.E0, theirs.E0, "E0")
        close(mine.E1, theirs.E1, "E1")
        for what in ("fixed0", "fixed1", "free0", "free1"):
            np.testing.assert_array_equal(getattr(mine, what), getattr(theirs, what))
        assert len(mine.constraints) == len(theirs.constraints)
        for c, d in zip(mine.constraints, theirs.constraints):
            g, h = np.broadcast_arrays(c.g, d.g)
            sign = 1.0 if np.sum(g * h) >= 0 else -1.0      # = 0: the same either way
            close(sign * g, h, "g")
            close(sign * c.d0, d.d0, "d0")
            close(sign * c.d1, d.d1, "d1")


# ---- the planar elastica ----------------------------------------------------------------

ELASTICA_RANGES = {"P": (-20, 20), "eps": (-1, 1), "psi": (-7, 7), "alpha": (-7, 7),
                   "theta0": (-7, 7)}
#: The derived bc's rows (theta(0), the natural end, x(0), y(0)) in the shipped module's order.
ELASTICA_ROWS = [0, 2, 3, 1]


@pytest.fixture(scope="module")
def derived_elastica():
    """The shipped elastica, derived from its energy (equations/elastica_lever_arm.py)."""
    return ea.load_problem("elastica_lever_arm")


@pytest.fixture(scope="module")
def elastica(elastica_reference):
    """Here: the hand-written elastica the shipped module replaced (tests/reference)."""
    return elastica_reference


def test_the_derived_elastica_is_the_hand_written_one(derived_elastica, elastica):
    """Issue 47 items 2, 6: written as its energy with the positions as passive quadratures
    and the load on the arm's end, the shipped elastica derives the hand-written module's
    states, equations, natural end condition, second variation and the paper's `enters`."""
    d = derived_elastica
    assert d.states == elastica.states
    assert {k: q.enters for k, q in d.parameters.items()} == \
        {k: q.enters for k, q in elastica.parameters.items()}
    assert {o.parameter: o.name for o in d.ordinates.values() if o.parameter} == \
        {o.parameter: o.name for o in elastica.ordinates.values() if o.parameter}
    assert_same_system(d, elastica, ELASTICA_RANGES, ELASTICA_ROWS, np.random.default_rng(1))


def test_the_derived_ordinates_are_the_papers(derived_arm, elastica):
    """Each distinguished ordinate, dE/dxi (and -dE/dtheta0), is the shipped module's formula
    on solutions: m1 = kappa(1) through the natural condition, mA = kappa(0) through the
    conserved moment m + r x n; gamma and beta are the same formulas. At every point of the
    rotating arm that keeps its solution."""
    checked = 0
    for br in derived_arm.result.branches:
        for p in (p for p in br.points if p.state is not None):
            s, y = p.state.s, p.state.y
            checked += 1
            for o in elastica.ordinates.values():
                assert p.ordinates[o.name] == pytest.approx(o.fn(s, y, p.params), abs=1e-7)
    assert checked >= 50


def test_the_reduced_energy_derives_the_same_system(tmp_path, elastica):
    """The reduced energy of docs/design.md (positions eliminated, P cos(theta - alpha) in
    the density) derives the same equations: P and alpha then enter the density."""
    path = module_file(tmp_path, "reduced", '''
        def ENERGY():
            import sympy as sp
            from elastica_auto.energy import Energy
            s, P, eps, psi, alpha, theta0 = sp.symbols("s P eps psi alpha theta0", real=True)
            theta, x, y = (sp.Function(n)(s) for n in ("theta", "x", "y"))
            return Energy(density=theta.diff(s)**2 / 2 + P * sp.cos(theta - alpha),
                          end1=eps * P * sp.cos(psi + alpha - theta), s=s, coordinates=[theta],
                          momenta=["kappa"], quadratures={x: -sp.sin(theta), y: sp.cos(theta)},
                          fixed0={theta: theta0, x: 0, y: 0},
                          parameters={P: 2.0, eps: 0.25, psi: 0.0, alpha: 0.0, theta0: 0.0})
        ''')
    d = ea.load_problem(path)
    assert {k: q.enters for k, q in d.parameters.items()} == \
        {"P": "ode", "eps": "free", "psi": "free", "alpha": "ode", "theta0": "fixed"}
    assert_same_system(d, elastica, ELASTICA_RANGES, ELASTICA_ROWS, np.random.default_rng(3))


def test_a_wrong_natural_condition_fails_the_residual_comparison(derived_elastica, elastica):
    """Teeth: the derived module with the natural end condition's end term of the wrong sign
    (m(1) - dB1/dtheta instead of m(1) + dB1/dtheta, a derivation error) is caught by the
    comparison above."""
    import types
    module = types.SimpleNamespace(**vars(derived_elastica.module))

    def flip(row, kappa1):                 # row = m(1) + dB1/dtheta -> m(1) - dB1/dtheta
        return 2 * kappa1 - row

    def bc(ya, yb, p):
        out = derived_elastica.bc(ya, yb, p)
        out[1] = flip(out[1], yb[1])
        return out

    def bc_jac(ya, yb, p):
        da, db = derived_elastica.bc_jac(ya, yb, p)
        db[1] = flip(db[1], np.eye(4)[1])
        return da, db

    def bc_dp(ya, yb, p, name):
        out = derived_elastica.bc_dp(ya, yb, p, name)
        out[1] = -out[1]
        return out

    module.bc, module.bc_jac, module.bc_dp = bc, bc_jac, bc_dp
    broken = ea.Problem(module, "broken")
    assert_same_system(derived_elastica, elastica, ELASTICA_RANGES, ELASTICA_ROWS,
                       np.random.default_rng(1), trials=3)
    with pytest.raises(AssertionError, match="bc"):
        assert_same_system(broken, elastica, ELASTICA_RANGES, ELASTICA_ROWS,
                           np.random.default_rng(1), trials=3)


@pytest.fixture(scope="module")
def derived_arm(rotating_arm):
    """The shipped rotating_arm run (8 branches), on the derived elastica (the shipped
    module)."""
    return rotating_arm


@pytest.fixture(scope="module")
def reference_arm(tmp_path_factory):
    """The shipped rotating_arm run on the hand-written reference."""
    out = tmp_path_factory.mktemp("arm")
    path = out / "rotating_arm.toml"
    path.write_text(ROTATING_ARM.read_text().replace(
        'equation = "elastica_lever_arm"',
        f'equation = "{REFERENCE / "elastica_lever_arm.py"}"'))
    return run_plan(runfile.load(path), out, jobs=1)


def test_rotating_arm_on_the_derived_elastica(derived_arm, reference_arm):
    """Every fold of rotating_arm to 1e-9 and index, index_rule and index_direct equal at
    every point, against the hand-written module's run."""
    mine, theirs = derived_arm.result.branches, reference_arm.result.branches
    assert len(mine) == len(theirs) == 8
    folds = 0
    for a, b in zip(mine, theirs):
        assert len(a.points) == len(b.points)
        for p, q in zip(a.points, b.points):
            assert p.type == q.type
            assert (p.index, p.index_rule, p.index_direct) == \
                (q.index, q.index_rule, q.index_direct)
            if p.type in ("LP", "BP"):
                folds += 1
                for name in ("psi", "P", "eps"):
                    assert p.params[name] == pytest.approx(q.params[name], abs=1e-9)
                np.testing.assert_allclose(p.state.y, q.state.y, atol=1e-9)
    assert folds >= 40


@pytest.mark.parametrize("name, ordinate, start", [
    ("psi", "m1", {"psi": 0.0}), ("eps", "beta", {"psi": 0.5}), ("P", "gamma", {"psi": 0.5}),
    ("alpha", "mA", {"psi": 0.5}), ("theta0", "m0", {"psi": 0.5})])
def test_the_slope_of_the_derived_energy_is_the_distinguished_ordinate(derived_elastica, name,
                                                                     ordinate, start):
    """Along a branch in each parameter, dE/dxi by differences of the derived energy E is
    the distinguished ordinate, and minus it (the reaction) for theta0, in an essential end
    value: the total derivative along the equilibria, with its sign."""
    params = {"eps": 0.25, "P": 2.0, **start}
    if start["psi"]:        # a bent rod: continued in psi from the straight one first
        first = ea.continuation(derived_elastica, {**params, "psi": 0.0}, "psi",
                                bounds=(-1, start["psi"]), directions="+", mirror=False)
        start_point = first.label(first[0].points[-1].name)
    else:
        start_point = params
    (br,) = ea.continuation(derived_elastica, start_point, name, directions="+",
                            bounds=(-10, 10), ds=0.01, ds_max=0.01, max_points=40, mirror=False)
    xi = np.array([p.params[name] for p in br.points])
    e = np.array([p.ordinates["E"] for p in br.points])
    sign = -1 if name == "theta0" else 1
    _assert_slope(xi, e, sign * np.array([p.ordinates[ordinate] for p in br.points]))


def _assert_slope(xi, e, ordinate):
    """The second-order difference of E in xi equals ``ordinate`` where xi moves steadily
    (away from folds), to 1e-4 of its scale (the steps are about 0.01)."""
    checked = 0
    for j in range(1, len(xi) - 1):
        d1, d2 = xi[j] - xi[j - 1], xi[j + 1] - xi[j]
        if d1 * d2 <= 0 or min(abs(d1), abs(d2)) < 0.5 * max(abs(d1), abs(d2)):
            continue
        slope = (d1 ** 2 * (e[j + 1] - e[j]) + d2 ** 2 * (e[j] - e[j - 1])) \
            / (d1 * d2 * (d1 + d2))
        assert slope == pytest.approx(ordinate[j], abs=1e-4 * (1 + abs(ordinate[j])))
        checked += 1
    assert checked >= 10


BOTH_ENDS = """
import numpy as np


def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy
    s, b = sp.symbols("s b", real=True)
    theta = sp.Function("theta")(s)
    return Energy(density=theta.diff(s)**2 / 2 + theta**2 / 2 + s * theta, s=s,
                  coordinates=[theta], end0=b * (theta - 1)**2 / 2,
                  end1=b * (theta + 1)**2 / 2 + b**2 * theta, parameters={b: 0.0})


def exact_start(s, p):
    if p["b"] != 0:
        return None
    # theta'' = theta + s with theta'(0) = theta'(1) = 0
    c = np.array([[np.sinh(0.0), np.cosh(0.0)], [np.sinh(1.0), np.cosh(1.0)]])
    a, d = np.linalg.solve(c, [1.0, 1.0])
    return np.vstack((a * np.cosh(s) + d * np.sinh(s) - s, a * np.sinh(s) + d * np.cosh(s) - 1))
"""


def test_the_ordinate_of_a_parameter_in_both_end_terms(tmp_path):
    """b in B0 (at theta(0)) and in B1 (at theta(1)): dE/db takes each end term at its own
    end, as the slope of E along the branch in b shows."""
    problem = ea.load_problem(module_file(tmp_path, "ends", BOTH_ENDS))
    assert problem.parameters["b"].enters == "free"
    (br,) = ea.continuation(problem, {"b": 0.0}, "b", bounds=(-1, 2), directions="+", ds=0.01,
                            ds_max=0.01, max_points=60)
    _assert_slope(np.array([p.params["b"] for p in br.points]),
                  np.array([p.ordinates["E"] for p in br.points]),
                  np.array([p.ordinates["dE_db"] for p in br.points]))


CONSTRAINT_VALUE = """
import numpy as np


def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy
    s, P, Q, c = sp.symbols("s P Q c", real=True)
    theta, x, y = (sp.Function(n)(s) for n in ("theta", "x", "y"))
    return Energy(density=theta.diff(s)**2 / 2, end1=P * y, s=s, coordinates=[theta],
                  quadratures={x: -sp.sin(theta), y: sp.cos(theta)},
                  fixed0={theta: 0, x: 0, y: 0}, fixed1={x: c}, multipliers={x: Q},
                  parameters={P: 1.0, Q: 0.0, c: 0.0})


def exact_start(s, p):
    return np.vstack((np.zeros((3, len(s))), s)) if p["c"] == 0 else None
"""


def test_the_ordinate_of_a_constraint_s_value(tmp_path):
    """The tip of a column held at x(1) = c by the multiplier Q (E + Q (x(1) - c)): c enters
    the constraint's value only (``"free"``), dE/dc = -Q, as the slope of E along the
    branch in c shows."""
    problem = ea.load_problem(module_file(tmp_path, "value", CONSTRAINT_VALUE))
    assert problem.parameters["c"].enters == "free" and problem.free == ("Q",)
    (br,) = ea.continuation(problem, {"c": 0.0, "P": 1.0}, "c", bounds=(-1, 0.5),
                            directions="+", ds=0.01, ds_max=0.01, max_points=50)
    dE_dc = np.array([p.ordinates["dE_dc"] for p in br.points])
    np.testing.assert_allclose(dE_dc, [-p.params["Q"] for p in br.points], atol=1e-12)
    assert abs(dE_dc).max() > 0.1
    _assert_slope(np.array([p.params["c"] for p in br.points]),
                  np.array([p.ordinates["E"] for p in br.points]), dE_dc)


def test_a_flipped_ordinate_makes_the_rule_disagree():
    """Teeth: the derived m1 with its sign flipped, on a branch from an index-1 start (the
    straight rod at P = 6 > pi^2/4, eps = 0.5), makes the fold rule disagree with the direct count;
    with the derived sign they agree at every point."""
    import re
    derived = ea.load_problem("elastica_lever_arm")
    params = {"eps": 0.5, "P": 6.0}
    options = dict(bounds=(-2 * math.pi, 2 * math.pi), directions="+", mirror=False)
    (right,) = ea.continuation(derived, params, "psi", **options)
    assert right.points[0].index_direct == 1 and len(right.folds) >= 1
    assert not [p for p in right.points if "disagreement" in p.note]
    code = derived.generated
    (k,) = re.findall(r"Ordinate\('m1', .*?_derived_ordinate(\d+), 'psi'", code)
    head = code.index(f"def _derived_ordinate{k}(")
    end = code.index("    return float(value)", head)
    flipped = execute(code[:end] + "    return -float(value)" + code[end + 23:], "flipped")
    flipped.exact_start = derived.module.exact_start
    (wrong,) = ea.continuation(ea.Problem(flipped, "flipped"), params, "psi", **options)
    assert len([p for p in wrong.points if "disagreement" in p.note]) >= 10


# ---- Bratu, the clamped column ----------------------------------------------------------

def test_the_derived_bratu_is_the_hand_written_one():
    d = ea.load_problem(EXAMPLES / "bratu.py")
    h = ea.load_problem(REFERENCE / "bratu.py")
    assert d.states == h.states
    assert_same_system(d, h, {"lam": (-5, 5)}, [0, 1], np.random.default_rng(4))
    s, y = random_states(np.random.default_rng(5), 2, 40)
    y[0], y[1] = np.sin(3 * s), 3 * np.cos(3 * s)       # dE/dlam = -int exp(u), to 4th order
    assert d.ordinates["dE_dlam"].fn(s, y, {"lam": 1.0}) == \
        pytest.approx(h.ordinates["dE_dlam"].fn(s, y, {"lam": 1.0}), rel=1e-12)


def _run_example(toml, equation, out):
    """The example's run file ``toml`` with the module at the path ``equation``."""
    out.mkdir()
    path = out / Path(toml).name
    text = (EXAMPLES / toml).read_text()
    original = next(line for line in text.splitlines() if line.startswith("equation"))
    path.write_text(text.replace(original, f'equation = "{equation}"'))
    return run_plan(runfile.load(path), out / "out").result.branches


def assert_same_runs(mine, theirs, names):
    """The same points, labels and index columns; folds and branch points to 1e-9 of
    their value (the references' Jacobians are partly the engine's central differences)."""
    assert len(mine) == len(theirs)
    for a, b in zip(mine, theirs):
        assert [p.type for p in a.points] == [p.type for p in b.points]
        for p, q in zip(a.points, b.points):
            assert (p.index, p.index_rule, p.index_direct) == \
                (q.index, q.index_rule, q.index_direct)
            if p.type in ("LP", "BP"):
                for name in names:
                    assert p.params[name] == pytest.approx(q.params[name], rel=1e-9, abs=1e-9)


def test_bratu_run_on_the_derived_module(tmp_path):
    mine = _run_example("bratu.toml", EXAMPLES / "bratu.py", tmp_path / "d")
    theirs = _run_example("bratu.toml", REFERENCE / "bratu.py", tmp_path / "h")
    assert_same_runs(mine, theirs, ["lam"])
    (lp,) = mine[0].folds
    assert lp.ordinates["du0"] == pytest.approx(4.0, abs=1e-8)


def test_the_derived_clamped_column_is_the_hand_written_one(tmp_path):
    """The isoperimetric constraint x(1) = 0 by a multiplier: the same equations, extra
    boundary row, free parameter and constrained second variation; the multiplier given as
    minus Q (E - Q x(1)) is the hand-written module's lateral reaction Q."""
    d = ea.load_problem(EXAMPLES / "clamped_column.py")
    h = ea.load_problem(REFERENCE / "clamped_column.py")
    assert d.states == h.states and d.free == h.free == ("Q",) and d.nbc == h.nbc == 5
    assert_same_system(d, h, {"P": (-50, 50), "Q": (-5, 5), "theta0": (-3, 3)},
                       [0, 1, 2, 3, 4], np.random.default_rng(6))
    mine = _run_example("clamped_column.toml", EXAMPLES / "clamped_column.py", tmp_path / "d")
    theirs = _run_example("clamped_column.toml", REFERENCE / "clamped_column.py",
                          tmp_path / "h")
    assert_same_runs(mine, theirs, ["P"])
    for p in (p for br in mine for p in br.points if p.state is not None):
        s, y = p.state.s, p.state.y
        for name in ("y1", "m0"):           # the ordinates the two share, on one solution
            assert p.ordinates[name] == pytest.approx(h.ordinates[name].fn(s, y[:4], p.params),
                                                      abs=1e-12)


def test_the_derived_guided_column_is_the_hand_written_one(tmp_path):
    """The clamped-guided column: an essential end at each end, the load on a quadrature's
    end value; the same system, and the same run (its branch points at (n pi)^2)."""
    d = ea.load_problem(EXAMPLES / "guided_column.py")
    h = ea.load_problem(REFERENCE / "guided_column.py")
    assert d.states == h.states
    assert_same_system(d, h, {"P": (-50, 50), "theta0": (-3, 3)}, [0, 1, 2, 3],
                       np.random.default_rng(7))
    mine = _run_example("guided_column.toml", EXAMPLES / "guided_column.py", tmp_path / "d")
    theirs = _run_example("guided_column.toml", REFERENCE / "guided_column.py",
                          tmp_path / "h")
    assert_same_runs(mine, theirs, ["P"])


# ---- models the project never had -------------------------------------------------------

#: The issue's minimal form, which users' files rely on: examples/heavy_column.py holds it
#: as written.
MINIMAL = '''
def ENERGY():                      # called only when the cache misses
    import sympy as sp
    from elastica_auto.energy import Energy
    s, q = sp.symbols("s q", real=True)
    theta = sp.Function("theta")(s)
    return Energy(density=theta.diff(s)**2 / 2 + q * (1 - s) * sp.cos(theta),
                  s=s, coordinates=[theta], parameters={q: 0.0},
                  fixed0={theta: 0})   # essential at s = 0; every other end natural
'''


def test_the_minimal_form_buckles_the_heavy_column_at_greenhills_load():
    """The heavy column written in the issue's minimal form: its branch point is Greenhill's
    load (3 j / 2)^2, j the first zero of J_{-1/3}, and the index goes 0 -> 1 there."""
    assert MINIMAL in (EXAMPLES / "heavy_column.py").read_text()
    problem = ea.load_problem(EXAMPLES / "heavy_column.py")
    assert problem.states == ("theta", "m_theta")
    assert problem.parameters["q"].enters == "ode"
    (br,) = ea.continuation(problem, {"q": 0.0}, "q", bounds=(-1, 20), directions="+")
    (bp,) = [p for p in br.points if p.type == "BP"]
    j = brentq(lambda x: jv(-1 / 3, x), 1.0, 2.5, xtol=1e-15)
    assert bp.params["q"] == pytest.approx((1.5 * j) ** 2, rel=1e-8)
    assert br.transition(bp) == "0 -> 1"


def foundation_loads(k, G, count):
    c = np.pi * np.arange(1, count + 1)
    return np.sort(k / c ** 2 + G * c ** 2 / (c ** 2 + G))


def test_the_foundation_column_buckles_at_the_closed_form_loads(tmp_path):
    """examples/foundation_column.py, written from its energy alone (the tutorial): the branch
    points of the straight column are P_n = k/c^2 + G c^2/(c^2 + G), c = n pi, in their
    order (a stiff foundation buckles it in the second mode first), and the index counts
    the P_n below P."""
    (br,) = run_plan(runfile.load(EXAMPLES / "foundation_column.toml"), tmp_path).result.branches
    bps = [p for p in br.points if p.type == "BP"]
    loads = foundation_loads(400.0, 100.0, 6)
    loads = loads[loads < 60]
    assert [p.params["P"] for p in bps] == pytest.approx(list(loads), rel=1e-8)
    assert loads[0] == pytest.approx(foundation_loads(400.0, 100.0, 2)[0])   # mode 2 first
    for p in br.points:
        if p.type not in ("LP", "BP"):
            assert p.index_direct == p.index == int(np.sum(loads < p.params["P"]))


# ---- the second variation against an independently discretised energy ------------------

def discrete_energy(density, end0, end1, nodes):
    """E_h(z) = sum_j h L(s_mid, z_mid, (z_{j+1} - z_j) / h) + B0(z_0) + B1(z_N)."""
    h = np.diff(nodes)
    sm = 0.5 * (nodes[:-1] + nodes[1:])

    def energy(z):
        zm, vm = 0.5 * (z[:, :-1] + z[:, 1:]), np.diff(z, axis=1) / h
        return float(np.sum(h * density(sm, zm, vm)) + end0(z[:, 0]) + end1(z[:, -1]))
    return energy


def fd_bilinear(energy, z, h1, h2, e=1e-4):
    return (energy(z + e * h1 + e * h2) - energy(z + e * h1 - e * h2)
            - energy(z - e * h1 + e * h2) + energy(z - e * h1 - e * h2)) / (4 * e * e)


def form_bilinear(form, s, h1, dh1, h2, dh2):
    """The derived form's bilinear value by Simpson's rule on the points s (nodes and
    midpoints of a uniform grid)."""
    a, b, c, _ = form.fields(len(s))
    f = (np.einsum("ik,kij,jk->k", dh1, a, dh2) + np.einsum("ik,kij,jk->k", dh1, c, h2)
         + np.einsum("ik,kij,jk->k", dh2, c, h1) + np.einsum("ik,kij,jk->k", h1, b, h2))
    w = np.zeros(len(s))
    w[0:-1:2] += 1
    w[2::2] += 1
    w[1::2] += 4
    integral = np.sum(w * f) * (s[2] - s[0]) / 6
    return integral + h1[:, 0] @ form.E0 @ h2[:, 0] + h1[:, -1] @ form.E1 @ h2[:, -1]


TWO_COORDINATES = '''
def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy
    s, q, k, r, b0, e1 = sp.symbols("s q k r b0 e1", real=True)
    u, w = sp.Function("u")(s), sp.Function("w")(s)
    du, dw = u.diff(s), w.diff(s)
    density = ((1 + s / 2) * (du**2 / 2 + du**4 / 4) + sp.cosh(dw) - 1 + du * dw / 4
               + 0.7 * du * w + sp.sin(u) * dw + q * (1 - s) * sp.cos(u) + k * w**2 / 2
               + r * u * w)
    return Energy(density=density, end0=b0 * sp.cos(u), end1=e1 * u**2 * w + sp.sin(w), s=s,
                  coordinates=[u, w], fixed0={w: 0.1},
                  parameters={q: 1.0, k: 2.0, r: 0.5, b0: 0.3, e1: 0.4})
'''


def _two_coordinates(s, z, v, p):
    """The density of TWO_COORDINATES in numpy, with its momenta (written here, not
    derived)."""
    u, w, du, dw = z[0], z[1], v[0], v[1]
    value = ((1 + s / 2) * (du ** 2 / 2 + du ** 4 / 4) + np.cosh(dw) - 1 + du * dw / 4
             + 0.7 * du * w + np.sin(u) * dw + p["q"] * (1 - s) * np.cos(u)
             + p["k"] * w ** 2 / 2 + p["r"] * u * w)
    m = np.array([(1 + s / 2) * (du + du ** 3) + dw / 4 + 0.7 * w,
                  np.sinh(dw) + du / 4 + np.sin(u)])
    return value, m


def test_the_second_variation_is_the_hessian_of_the_discretised_energy(tmp_path):
    """Two coordinates, a density not quadratic in the derivatives (the Legendre transform
    by Newton's method) that depends on s and couples u', w' and u, w; end terms at both
    ends; w essential at s = 0. At random smooth states, the derived A, B, C, E0, E1 give
    the finite-difference Hessian of the midpoint-rule energy in random perturbations."""
    problem = ea.load_problem(module_file(tmp_path, "two", TWO_COORDINATES))
    assert "Newton" in problem.generated
    sv = as_second_variation(problem.second_variation(
        np.linspace(0, 1, 3), np.full((4, 3), 0.1), problem.defaults()), "")
    np.testing.assert_array_equal(sv.fixed0, [[0.0], [1.0]])
    assert sv.fixed1.shape == (2, 0)
    rng = np.random.default_rng(7)
    n = 4000
    nodes = np.linspace(0, 1, n + 1)
    pts = np.linspace(0, 1, 2 * 400 + 1)
    for _ in range(3):
        p = {name: rng.uniform(-1, 1) for name in problem.parameters}
        a = rng.uniform(-0.6, 0.6, (2, 3))

        def state(s, nu=0):
            terms = [(s, 1.0), (np.sin(2 * s), 2 * np.cos(2 * s)),
                     (np.cos(3 * s), -3 * np.sin(3 * s))]
            return sum(a[:, i:i + 1] * t[nu] for i, t in enumerate(terms))

        energy = discrete_energy(lambda s, z, v: _two_coordinates(s, z, v, p)[0],
                                 lambda z: p["b0"] * np.cos(z[0]),
                                 lambda z: p["e1"] * z[0] ** 2 * z[1] + np.sin(z[1]), nodes)
        z, dz = state(pts), state(pts, 1)
        y = np.vstack((z, _two_coordinates(pts, z, dz, p)[1]))
        form = as_second_variation(problem.second_variation(pts, y, p), "")
        for _ in range(3):
            b1, b2 = rng.normal(size=(2, 2, 3))

            def pert(b, s, nu=0):
                h = np.array([b[0, 0] + b[0, 1] * np.sin(3 * s) + b[0, 2] * s ** 2,
                              b[1, 0] * s + b[1, 1] * np.sin(2 * s) + b[1, 2] * s ** 3])
                if nu:
                    h = np.array([3 * b[0, 1] * np.cos(3 * s) + 2 * b[0, 2] * s,
                                  b[1, 0] + 2 * b[1, 1] * np.cos(2 * s) + 3 * b[1, 2] * s ** 2])
                return h

            expected = fd_bilinear(energy, state(nodes), pert(b1, nodes), pert(b2, nodes))
            got = form_bilinear(form, pts, pert(b1, pts), pert(b1, pts, 1), pert(b2, pts),
                                pert(b2, pts, 1))
            assert got == pytest.approx(expected, rel=2e-5, abs=2e-5)


def test_the_newton_legendre_inverse_and_its_jacobians(tmp_path):
    """zeta' from the momenta by Newton's method inverts the momenta written here, and the
    Jacobians by the implicit function theorem are the finite differences of rhs and bc."""
    problem = ea.load_problem(module_file(tmp_path, "two", TWO_COORDINATES))
    rng = np.random.default_rng(8)
    p = problem.defaults()
    s = np.linspace(0, 1, 9)
    z, v = rng.uniform(-1, 1, (2, 9)), rng.uniform(-1.5, 1.5, (2, 9))
    y = np.vstack((z, _two_coordinates(s, z, v, p)[1]))
    np.testing.assert_allclose(problem.rhs(s, y, p)[:2], v, atol=1e-12)
    for j in range(9):
        jac = central_jacobian(lambda x: problem.rhs(s[j:j + 1], x[:, None], p)[:, 0], y[:, j])
        np.testing.assert_allclose(problem.rhs_jac(s, y, p)[:, :, j], jac, atol=1e-7)
    for name in p:
        d = 1e-6
        fd = (problem.rhs(s, y, {**p, name: p[name] + d})
              - problem.rhs(s, y, {**p, name: p[name] - d})) / (2 * d)
        np.testing.assert_allclose(problem.rhs_dp(s, y, p, name), fd, atol=1e-7)
    ya, yb = y[:, 0], y[:, -1]
    da, db = problem.bc_jac(ya, yb, p)
    np.testing.assert_allclose(da, central_jacobian(lambda x: problem.bc(x, yb, p), ya),
                               atol=1e-7)
    np.testing.assert_allclose(db, central_jacobian(lambda x: problem.bc(ya, x, p), yb),
                               atol=1e-7)


CONSTRAINED = '''
def ENERGY():
    import sympy as sp
    from elastica_auto.energy import Energy, Param
    s, P, Q, b, theta0 = sp.symbols("s P Q b theta0", real=True)
    theta, x, y = (sp.Function(n)(s) for n in ("theta", "x", "y"))
    t = theta.diff(s)
    return Energy(density=t**2 / 2 {quartic}, end1=P * y, s=s, coordinates=[theta],
                  quadratures={{x: -sp.sin(theta) + b * t**2 / 2, y: sp.cos(theta)}},
                  fixed0={{theta: theta0, x: 0, y: 0}}, fixed1={{x: 0}}, multipliers={{x: Q}},
                  parameters={{P: 3.0, Q: 0.0, b: 0.5, theta0: Param(0.0, ordinate="m0")}})


import numpy as np


def exact_start(s, p):
    return np.vstack((np.zeros((3, len(s))), s)) if p["theta0"] == 0 else None
'''


@pytest.mark.parametrize("quartic", ["", "+ t**4 / 8"])
def test_a_constraint_whose_rate_contains_theta_prime(tmp_path, quartic):
    """x(1) = 0 with x' = -sin(theta) + b theta'^2 / 2 (its multiplier Q solved for), theta
    natural at s = 1, on solutions continued in theta0 (quadratic density: symbolic
    Legendre inverse; with a quartic term: Newton's). The derived Constraint (integrated by
    parts along the solution) is the finite-difference first variation of the discretised
    int g ds, for perturbations free at both ends; the form is the Hessian of the
    discretised E + Q int g; and dE/dtheta0 by differences of E along the branch is minus
    the reaction m0."""
    problem = ea.load_problem(module_file(tmp_path, "constrained",
                                          CONSTRAINED.format(quartic=quartic)))
    assert ("Newton" in problem.generated) == bool(quartic)
    assert problem.free == ("Q",) and problem.parameters["theta0"].enters == "fixed"
    (br,) = ea.continuation(problem, {"theta0": 0.0}, "theta0", bounds=(-1, 0.6),
                            directions="+", ds=0.01, ds_max=0.01)
    e = np.array([p.ordinates["E"] for p in br.points])
    th0 = np.array([p.params["theta0"] for p in br.points])
    _assert_slope(th0, e, -np.array([p.ordinates["m0"] for p in br.points]))
    point = br.points[-1]
    p = point.params
    assert abs(p["Q"]) > 0.05 and abs(point.state.y[1]).max() > 0.5      # a bent rod
    c4 = 1.0 if quartic else 0.0
    n = 4000
    nodes = np.linspace(0, 1, n + 1)
    pts = np.linspace(0, 1, 2 * 400 + 1)

    def rate(s, z, v):
        return -np.sin(z[0]) + p["b"] * v[0] ** 2 / 2

    constraint = discrete_energy(rate, lambda z: 0.0, lambda z: 0.0, nodes)
    energy = discrete_energy(lambda s, z, v: v[0] ** 2 / 2 + c4 * v[0] ** 4 / 8
                             + p["P"] * np.cos(z[0]) + p["Q"] * rate(s, z, v),
                             lambda z: 0.0, lambda z: 0.0, nodes)
    z = point.state(nodes)[:1]
    form = as_second_variation(problem.second_variation(pts, point.state(pts), p), "")
    (con,) = form.constraints
    g = np.broadcast_to(con.g, (1, len(pts)))
    rng = np.random.default_rng(9)
    w = np.zeros(len(pts))
    w[0:-1:2] += 1
    w[2::2] += 1
    w[1::2] += 4
    for _ in range(4):
        b1, b2 = rng.normal(size=(2, 3))

        def pert(b, s, nu=0):
            return np.array([b[0] + b[1] * np.sin(2 * s) + b[2] * s ** 2]) if not nu else \
                np.array([2 * b[1] * np.cos(2 * s) + 2 * b[2] * s])

        d = 1e-6
        first = (constraint(z + d * pert(b1, nodes))
                 - constraint(z - d * pert(b1, nodes))) / (2 * d)
        h = pert(b1, pts)
        mine = (np.sum(w * g[0] * h[0]) * (pts[2] - pts[0]) / 6 + con.d0 @ h[:, 0]
                + con.d1 @ h[:, -1])
        assert mine == pytest.approx(first, rel=1e-5, abs=1e-6)
        expected = fd_bilinear(energy, z, pert(b1, nodes), pert(b2, nodes))
        got = form_bilinear(form, pts, pert(b1, pts), pert(b1, pts, 1), pert(b2, pts),
                            pert(b2, pts, 1))
        assert got == pytest.approx(expected, rel=2e-5, abs=2e-5)


# ---- the pinned elastica: two isoperimetric constraints -----------------------------------

def test_the_derived_pinned_elastica_is_the_hand_written_one():
    """Issue 47 item 6: the pin as two isoperimetric constraints x(1) + a_x(theta(1)) = X,
    y(1) + a_y(theta(1)) = Y whose multipliers are the reaction (E - n.(r(1) + a - R)): the
    hand-written module's equations with n its two constant states, its six end conditions
    (the arm's moment balance the natural condition), its constrained second variation
    (the constraints' end parts da/dtheta(1)) and its ordinates, at random states and
    parameters to 1e-12."""
    d = ea.load_problem("elastica_pinned")
    h = ea.load_problem(REFERENCE / "elastica_pinned.py")
    assert d.states == h.states[:4] and d.free == ("nx", "ny") and d.nbc == 6
    rng = np.random.default_rng(8)
    for _ in range(20):
        p = {k: rng.uniform(-3, 3) for k in d.parameters}
        s, y = random_states(rng, 4)
        y6 = np.vstack((y, np.full(y.shape[1], p["nx"]), np.full(y.shape[1], p["ny"])))
        q = {k: p[k] for k in h.parameters}
        close = dict(rtol=0, atol=1e-12 * (1 + abs(p["nx"]) + abs(p["ny"])))
        np.testing.assert_allclose(d.rhs(s, y, p), h.rhs(s, y6, q)[:4], **close)
        np.testing.assert_allclose(d.rhs_jac(s, y, p), h.rhs_jac(s, y6, q)[:4, :4], **close)
        rows = [0, 2, 3, 4, 5, 1]      # the derived rows in the hand-written order
        np.testing.assert_allclose(d.bc(y[:, 0], y[:, -1], p)[rows],
                                   h.bc(y6[:, 0], y6[:, -1], q), **close)
        mine = as_second_variation(d.second_variation(s, y, p), "d")
        theirs = as_second_variation(h.second_variation(s, y6, q), "h")
        for what in ("A", "B", "C", "E0", "E1"):
            a, b = np.broadcast_arrays(getattr(mine, what), getattr(theirs, what))
            np.testing.assert_allclose(a, b, err_msg=what, **close)
        for c, e in zip(mine.constraints, theirs.constraints):
            for what in ("g", "d0", "d1"):
                a, b = np.broadcast_arrays(getattr(c, what), getattr(e, what))
                np.testing.assert_allclose(a, b, err_msg=what, **close)
        for name in ("m0", "n_x", "n_y", "n_abs"):     # m1 = kappa(1) on solutions only
            assert d.ordinates[name].fn(s, y, p) == pytest.approx(
                h.ordinates[name].fn(s, y6, q), abs=1e-12)


@pytest.mark.parametrize("name", ["pinned_arm", "pinned_clamp"])
def test_the_pinned_runs_on_the_derived_module(tmp_path, name):
    """The shipped pinned runs (the start solved from the shooting guess, with its reaction
    as the free parameters' values) on the derived and the hand-written module: the same
    points and labels, every fold to 1e-9, the index, rule and direct count at every point,
    the reaction and m1 (kappa(1) = dE/dpsi on solutions) alike."""
    runs = {}
    for key, equation in (("d", "elastica_pinned"), ("h", REFERENCE / "elastica_pinned.py")):
        out = tmp_path / key
        out.mkdir()
        path = out / f"{name}.toml"
        path.write_text((REPO / "runs" / f"{name}.toml").read_text().replace(
            'equation = "elastica_pinned"', f'equation = "{equation}"'))
        runs[key] = run_plan(runfile.load(path), out).result.branches
    assert_same_runs(runs["d"], runs["h"], ["psi", "theta0"])
    for a, b in zip(runs["d"], runs["h"]):
        for p, q in zip(a.points, b.points):
            assert (p.params["nx"], p.params["ny"]) == pytest.approx(
                (q.ordinates["n_x"], q.ordinates["n_y"]), abs=1e-9)
            for key in ("m1", "m0", "n_abs"):
                assert p.ordinates[key] == pytest.approx(q.ordinates[key], abs=1e-7)
