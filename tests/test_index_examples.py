"""The stability index of the shipped small examples, each with a ``second_variation`` that is
not today's scalar clamped-free form, against analytic counts and an independent count.

* Bratu (examples/bratu.py): fixed at both ends; index 0 on the lower family and 1 on the
  upper, changing at the fold lam_c = 3.51383 (z tanh(z/2) = 2). The independent count uses the
  closed-form solution, not the engine's.
* the nonlinear eigenvalue problem (examples/nonlinear_eigenvalue.py): on u = 0 the index is
  the number of (k pi)^2 below p; the branch born at the k-th branch point bends to p < (k pi)^2
  (subcritical) and has index k (docstring of the module).
* the clamped-guided column (examples/guided_column.py): critical loads (n pi)^2.
* the column clamped at both ends (examples/clamped_column.py, a constrained form): critical
  loads 4 pi^2, k^2 with tan(k/2) = k/2, 16 pi^2.

Independent counts (tests/form_reference.py): the Morse index theorem (conjugate points of
the Jacobi equation) and a dense Legendre-Galerkin count, on coefficients built here from the
module's energy and the stored profiles (cubic Hermite with the exact slopes).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline
from scipy.optimize import brentq

import elastica_auto as ea
from elastica_auto.execution import runfile
from elastica_auto.numerics import stability
from elastica_auto.branches.branch import PROFILE_GRID
from elastica_auto.core.solution import State
from form_reference import Form, conjugate_count, dense_count
from helpers import EXAMPLES, REFERENCE, run_plan

PI2 = math.pi ** 2
#: Cases whose smallest |eigenvalue| (dense count) is below this are not compared: there the
#: count is decided by the distance to a fold or branch point, not by the method. The stored
#: profiles are good to ~1e-7 (cubic Hermite on 101 points), which moves an eigenvalue by less
#: than 1e-5 for coefficients of size <= 200; the dense count's own error is far smaller.
MU_MIN = 1e-3
#: The roots of tan(k/2) = k/2: the antisymmetric critical loads of the clamped column are k^2.
K_ANTI = brentq(lambda k: math.tan(k / 2) - k / 2, 8.5, 9.3)


def scalar_form(b, fixed=(0, 1), constraint=None):
    """Form (tests/form_reference.py) of int h'^2 + b(s) h^2 on h fixed at the ends listed."""
    g = np.ones((1, 1))
    return Form(k=1, A=lambda s: np.ones((len(s), 1, 1)), B=lambda s: b(s)[:, None, None],
                G0=g if 0 in fixed else None, G1=g if 1 in fixed else None,
                constraints=[] if constraint is None else
                [(lambda s: constraint(s)[:, None], np.zeros(1), np.zeros(1))])


def profile(point, i=0):
    """Component i of a stored profile as a callable, with the exact slopes (component i + 1)."""
    return CubicHermiteSpline(PROFILE_GRID, point.profile[i], point.profile[i + 1])


def counts(form):
    """(dense count, smallest |eigenvalue|, conjugate-point count or None with constraints)."""
    n, mu, _ = dense_count(form)
    return n, mu, (None if form.constraints else conjugate_count(form).index)


def assert_direct_equals_rule(branch):
    """Away from LP and BP rows (and a switched branch's first point, a branch point) the
    direct count equals the fold rule's value, and no point has an index disagreement or a
    warning."""
    assert not branch.warnings, branch.warnings
    for k, p in enumerate(branch.points):
        assert "disagreement" not in p.note and "kernel" not in p.note, p.note
        if p.type not in ("LP", "BP") and p.index_direct >= 0 \
                and not (k == 0 and branch.singular_start):
            assert p.index == p.index_rule == p.index_direct


# ---- Bratu ---------------------------------------------------------------------------------

def bratu_z(du0):
    """z of the closed form with u'(0) = 2 z tanh(z / 2) (examples/bratu.py)."""
    return brentq(lambda z: 2 * z * math.tanh(z / 2) - du0, 0.0, 80.0, xtol=1e-14) \
        if du0 > 0 else 0.0


@pytest.fixture(scope="module")
def bratu(tmp_path_factory):
    return run_plan(runfile.load(EXAMPLES / "bratu.toml"),
                    tmp_path_factory.mktemp("bratu")).result.branches[0]


def test_bratu_index_is_0_below_the_fold_and_1_above(bratu):
    (lp,) = bratu.folds
    z_c = brentq(lambda z: z * math.tanh(z / 2) - 2, 1.0, 5.0, xtol=1e-15)
    assert lp.params["lam"] == pytest.approx(2 * z_c ** 2 / math.cosh(z_c / 2) ** 2, rel=1e-8)
    assert lp.params["lam"] == pytest.approx(3.51383, abs=1e-5)
    k = bratu.points.index(lp)
    assert {p.index for p in bratu.points[:k]} == {0}
    assert {p.index for p in bratu.points[k + 1:]} == {1}
    assert bratu.transition(lp) == "0 -> 1"
    assert_direct_equals_rule(bratu)


def test_bratu_index_against_conjugate_points_of_the_closed_form(bratu):
    """At every point the index from the Jacobi equation h'' + lam exp(u) h = 0 of the exact
    solution with the same u'(0), and the dense count, equal the engine's."""
    compared = 0
    for p in bratu.points:
        z = bratu_z(p.ordinates["du0"])
        lam = 2 * z * z / math.cosh(z / 2) ** 2
        assert p.params["lam"] == pytest.approx(lam, rel=1e-6, abs=1e-9)

        def b(s, z=z, lam=lam):
            return -lam * (math.cosh(z / 2) / np.cosh(z * (s - 0.5))) ** 2   # -lam exp(u)
        n, mu, conj = counts(scalar_form(b))
        if mu < MU_MIN or p.type in ("LP", "BP"):
            continue
        assert n == conj == p.index_direct == p.index, (p.params, n, conj, p.index_direct)
        compared += 1
    assert compared >= len(bratu.points) - 3


# ---- the nonlinear eigenvalue problem -------------------------------------------------------

@pytest.fixture(scope="module")
def eigen(tmp_path_factory):
    return run_plan(runfile.load(EXAMPLES / "nonlinear_eigenvalue.toml"),
                    tmp_path_factory.mktemp("eigen")).result.branches


def critical_count(p, loads):
    return sum(1 for c in loads if c < p)


def test_trivial_branch_index_counts_the_k_pi_squared_below_p(eigen):
    trivial = eigen[0]
    loads = [(k * math.pi) ** 2 for k in range(1, 4)]
    bps = [p for p in trivial.points if p.type == "BP"]
    assert [p.params["p"] for p in bps] == pytest.approx(loads[:2], rel=1e-9)
    assert [trivial.transition(p) for p in bps] == ["0 -> 1", "1 -> 2"]
    for p in trivial.points:
        if p.type != "BP":
            assert p.index == critical_count(p.params["p"], loads)
    assert_direct_equals_rule(trivial)


def test_branch_born_at_the_kth_branch_point_is_subcritical_with_index_k(eigen):
    """Exchange of stability at a pitchfork: on u = 0 just below p_k = (k pi)^2 the k-th
    eigenvalue is positive (index k - 1); on the branch born there, which lies at p < p_k, it
    is negative, so the index is k. Checked by the dense count and conjugate points of
    h'' + p (1 + 3 u^2) h = 0 on the stored profiles."""
    switched = [br for br in eigen[1:]]
    assert len(switched) == 4
    compared = 0
    for br in switched:
        k = round(math.sqrt(br.points[0].params["p"]) / math.pi)
        assert all(p.params["p"] < (k * math.pi) ** 2 for p in br.points[1:])
        assert {p.index for p in br.points} == {k}
        assert_direct_equals_rule(br)
        for p in br.points[1::10]:
            u, pp = profile(p), p.params["p"]
            n, mu, conj = counts(scalar_form(lambda s: -pp * (1 + 3 * u(s) ** 2)))
            if mu >= MU_MIN:
                assert n == conj == p.index_direct == k
                compared += 1
    assert compared >= 30


def test_kernel_dimension_at_the_branch_points(eigen):
    """One eigenvalue crosses zero at each branch point of u = 0, and the vector form of two
    uncoupled copies has a kernel of dimension 2 at the same loads."""
    problem = ea.load_problem(EXAMPLES / "nonlinear_eigenvalue.py")
    s = np.linspace(0.0, 1.0, 41)
    for k in (1, 2, 3):
        state = State.from_values(problem, s, np.zeros((2, len(s))),
                                              {"p": (k * math.pi) ** 2})
        assert stability.kernel_dimension(problem, state) == 1
        def pair(pts, k=k):
            return ea.SecondVariation(np.eye(2), -(k * math.pi) ** 2 * np.eye(2),
                                      fixed0=[0, 1], fixed1=[0, 1])
        above, below = (stability.count_form(pair, s, shift=d).index for d in (1e-3, -1e-3))
        assert (above, below) == (2 * k, 2 * (k - 1))


# ---- the columns ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def guided(tmp_path_factory):
    return run_plan(runfile.load(EXAMPLES / "guided_column.toml"),
                    tmp_path_factory.mktemp("guided")).result.branches


@pytest.fixture(scope="module")
def clamped(tmp_path_factory):
    return run_plan(runfile.load(EXAMPLES / "clamped_column.toml"),
                    tmp_path_factory.mktemp("clamped")).result.branches


@pytest.mark.parametrize("name, loads", [
    ("guided", [(n * math.pi) ** 2 for n in range(1, 4)]),
    ("clamped", [4 * PI2, K_ANTI ** 2, 16 * PI2]),
])
def test_straight_column_critical_loads_and_index(name, loads, request):
    trivial = request.getfixturevalue(name)[0]
    bps = [p for p in trivial.points if p.type == "BP"]
    assert [p.params["P"] for p in bps] == pytest.approx(loads, rel=1e-8)
    assert [trivial.transition(p) for p in bps] == ["0 -> 1", "1 -> 2", "2 -> 3"]
    for p in trivial.points:
        if p.type != "BP":
            assert p.index == p.index_direct == critical_count(p.params["P"], loads)
    assert_direct_equals_rule(trivial)


def column_form(p, constrained):
    """The column's second variation at a stored point (module docstrings)."""
    theta, P, Q = profile(p), p.params["P"], p.params.get("Q", 0.0)
    return scalar_form(lambda s: -P * np.cos(theta(s)) - Q * np.sin(theta(s)),
                       constraint=(lambda s: np.cos(theta(s))) if constrained else None)


@pytest.mark.parametrize("name", ["guided", "clamped"])
def test_buckled_columns_against_independent_counts(name, request):
    """Every branch of the run, every fifth point: the engine's index equals the dense count
    (and, without the constraint, the conjugate-point count) on the stored profile."""
    compared = 0
    for br in request.getfixturevalue(name):
        assert_direct_equals_rule(br)
        for p in br.points[::5]:
            n, mu, conj = counts(column_form(p, name == "clamped"))
            if mu < MU_MIN or p.type in ("LP", "BP"):
                continue
            assert n == p.index_direct == p.index and conj in (None, n), (p.params, n, conj)
            compared += 1
    assert compared >= 40


def test_guided_buckled_branches_are_supercritical_and_mode_n_has_index_n_minus_1(guided):
    for br in guided[1:]:
        n = round(math.sqrt(br.points[0].params["P"]) / math.pi)
        assert all(p.params["P"] > (n * math.pi) ** 2 for p in br.points[1:])
        assert {p.index for p in br.points} == {n - 1}


# ---- the fold rule for an essential end value, with and without a constraint -------------------

@pytest.mark.parametrize("module, P", [("guided_column.py", 2 * PI2),
                                       ("clamped_column.py", 6 * PI2)])
def test_fold_rule_for_the_clamp_rotation(module, P):
    """theta0 enters an essential end condition: the rule reads m0 = -dE/dtheta0 with the
    opposite sign. From the straight column between the first two critical loads (index 1)
    the theta0-branch runs to folds where it turns into the buckled states; at each the index
    changes by one, the rule and the direct count agree on every point, and the dense count
    agrees with both."""
    problem = ea.load_problem(EXAMPLES / module)
    branches = ea.continuation(problem, {"P": P}, "theta0", directions="both",
                               bounds=(-1.0, 1.0), ds=0.02, ds_max=0.05, max_points=300)
    folds = [p for br in branches for p in br.folds]
    assert len(folds) >= 2
    for br in branches:
        assert br.points[0].index == 1
        assert_direct_equals_rule(br)
        assert all(br.transition(p) in ("1 -> 0", "0 -> 1") for p in br.folds)
        for p in br.points[::4]:
            n, mu, _ = counts(column_form(p, "clamped" in module))
            if mu >= MU_MIN and p.type not in ("LP", "BP"):
                assert n == p.index


def test_a_branch_point_whose_index_change_is_not_its_kernel_is_flagged(monkeypatch):
    """The branch point kind compares the index change across it with the dimension of the
    kernel there (`kinds.kernel_check`); made to disagree (a kernel of dimension 2
    reported), the BP says so in its note and the branch keeps a warning."""
    from elastica_auto.branches import kinds
    monkeypatch.setattr(kinds, "kernel_dimension", lambda problem, state: 2)
    problem = ea.load_problem(EXAMPLES / "nonlinear_eigenvalue.py")
    (br,) = ea.continuation(problem, {"p": 0.0}, "p", bounds=(-1, 12), ds=0.5, ds_max=2.0)
    (bp,) = [p for p in br.points if p.type == "BP"]
    assert "index 0 -> 1 across the branch point, whose kernel has dimension 2" in bp.note
    assert any("kernel has dimension 2" in w for w in br.warnings)


def test_where_the_legendre_condition_fails_the_point_says_so_and_the_branch_goes_on(tmp_path):
    """A form whose A = 1 - lam/2 stops being positive definite at lam = 2 (and B = 1, so
    the index is 0 while A > 0) has no index past it: those points get -1 and the one-line
    reason, the others their count, and the branch goes on to its bound (a step that only
    tries such a point did end it MX)."""
    old = 'return SecondVariation(1.0, -p["lam"] * np.exp(y[0]),'
    source = (REFERENCE / "bratu.py").read_text()      # written by hand: its functions
    assert old in source
    source = source.replace(old, 'return SecondVariation(1 - p["lam"] / 2, 1.0,')
    (tmp_path / "soft.py").write_text(source)
    problem = ea.load_problem(tmp_path / "soft.py")
    (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 3), ds=0.1, ds_max=0.2)
    assert br.end == "EP" and br.points[-1].params["lam"] == pytest.approx(3)
    for p in br.points:
        if p.params["lam"] < 1.99:
            assert p.index == p.index_direct == 0
        elif p.params["lam"] > 2.01:
            assert p.index == p.index_direct == -1
            assert "A is not positive definite at s = 0 (smallest eigenvalue" in p.note
            assert "the Legendre condition fails there" in p.note
    with pytest.raises(ea.ProblemError, match="Legendre"):
        stability.count_form(lambda pts: ea.SecondVariation(-1.0, 0.0), np.linspace(0, 1, 5))
