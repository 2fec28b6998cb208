"""Branch points from the determinant alone: u'' + p u (1 + u^2) = 0, u(0) = u(1) = 0
(examples/nonlinear_eigenvalue.py), fixed at both ends.

On u = 0 the linearisation u'' + p u = 0 has a solution sin(k pi x) exactly at p = (k pi)^2: the
branch points. The engine sees them through the sign of the determinant of the bordered
collocation Jacobian, which does not use the module's stability hook. The branches switched
onto there are checked by an independent shooting integration (scipy's DOP853) and by the
symmetry u -> -u.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from elastica_auto.execution import runfile
from helpers import EXAMPLES, run_plan


@pytest.fixture(scope="module")
def eigen_run(tmp_path_factory):
    plan = runfile.load(EXAMPLES / "nonlinear_eigenvalue.toml")
    assert plan.switch_count == 2
    return run_plan(plan, tmp_path_factory.mktemp("eigen"))


def _trivial_branch(tmp_path, **options):
    """The straight branch u = 0 alone (no switching), with ``options`` changed."""
    plan = runfile.load(EXAMPLES / "nonlinear_eigenvalue.toml")
    plan.switch_count = 0
    plan.options = dataclasses.replace(plan.options, **options)
    return run_plan(plan, tmp_path).result.branches[0]


def test_a_sign_change_is_kept_only_where_a_second_mesh_sees_it(tmp_path, monkeypatch):
    """At the default fold_tol each branch point is found again, between solved points, on the
    finer mesh that resolves its kernel: the second mesh, and no halved-mesh check. With
    fold_tol = 1e-3 the step's own mesh is the last one, so a and b are solved again on it
    with every interval halved; a sign change that does not survive that (the check made to
    fail here) is no branch point: the steps are retried shorter, then a warning."""
    from elastica_auto.branches import events
    from elastica_auto.numerics.correctors import CorrectorFailure
    checked = []
    real = events._check_on_finer_mesh

    def spy(corr, step, s):
        checked.append(len(s))
        return real(corr, step, s)

    monkeypatch.setattr(events, "_check_on_finer_mesh", spy)
    bps = [p.params["p"] for p in _trivial_branch(tmp_path / "fine").points if p.type == "BP"]
    np.testing.assert_allclose(bps, [math.pi ** 2, 4 * math.pi ** 2], rtol=1e-9)
    assert checked == []
    coarse = _trivial_branch(tmp_path / "coarse", fold_tol=1e-3)
    assert [p.type for p in coarse.points].count("BP") == 2 and len(checked) == 2

    def fails(corr, step, s):
        raise CorrectorFailure("the determinant's change of sign does not survive")

    monkeypatch.setattr(events, "_check_on_finer_mesh", fails)
    rejected = _trivial_branch(tmp_path / "rejected", fold_tol=1e-3)
    assert "BP" not in [p.type for p in rejected.points]
    assert sum("not located: the determinant's change of sign does not survive" in w
               for w in rejected.warnings) == 2


def _shoot(p, slope):
    """u(1) and the number of sign changes of u in (0, 1) for u(0) = 0, u'(0) = slope."""
    sol = solve_ivp(lambda x, z: [z[1], -p * z[0] * (1 + z[0] ** 2)], (0.0, 1.0), [0.0, slope],
                    method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    u = sol.sol(np.linspace(1e-3, 1 - 1e-3, 2001))[0]
    return sol.y[0, -1], int(np.sum(np.diff(np.sign(u)) != 0))


def test_branch_points_are_at_k_pi_squared(eigen_run):
    trivial = eigen_run.result.branches[0]
    assert trivial.start == "trivial" and trivial.folds == []
    bps = [p for p in trivial.points if p.type == "BP"]
    expected = [(k * math.pi) ** 2 for k in (1, 2, 3, 4, 5) if (k * math.pi) ** 2 < 50]
    got = [p.params["p"] for p in bps]
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=0)
    # the index changes by one at each (tests/test_index_examples.py checks its values)
    assert [trivial.transition(p) for p in bps] == ["0 -> 1", "1 -> 2"]
    assert trivial.warnings == []


def test_switched_branches_solve_the_problem_and_mirror_each_other(eigen_run):
    branches = eigen_run.result.branches[1:]
    assert len(branches) == 4                                 # two BPs, both directions
    for k, (up, down) in enumerate((branches[0:2], branches[2:4]), start=1):
        assert up.start == down.start == f"switch at BP{k}"
        for br in (up, down):
            p0 = br.points[0].params["p"]
            assert p0 == pytest.approx((k * math.pi) ** 2, rel=1e-9)
            # subcritical: the load falls as the amplitude grows
            amp, lam = br.column("amplitude"), br.column("p")
            assert amp[-1] > 1 and lam[-1] < p0
            assert np.all(np.diff(lam[1:]) < 0)
            for pt in br.points[1::10]:
                end, changes = _shoot(pt.params["p"], pt.ordinates["slope"])
                assert abs(end) <= 1e-6 * (1 + pt.ordinates["amplitude"]), (k, pt.params)
                assert changes == k - 1                      # the k-th mode's shape
        # u -> -u: the two directions are mirror images
        np.testing.assert_allclose(up.column("slope"), -down.column("slope"), rtol=1e-9,
                                   atol=1e-9)
        np.testing.assert_allclose(up.column("p"), down.column("p"), rtol=1e-12)
