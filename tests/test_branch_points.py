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
    real = events.check_on_finer_mesh

    def spy(corr, step, s):
        checked.append(len(s))
        return real(corr, step, s)

    monkeypatch.setattr(events, "check_on_finer_mesh", spy)
    bps = [p.params["p"] for p in _trivial_branch(tmp_path / "fine").points if p.type == "BP"]
    np.testing.assert_allclose(bps, [math.pi ** 2, 4 * math.pi ** 2], rtol=1e-9)
    assert checked == []
    coarse = _trivial_branch(tmp_path / "coarse", fold_tol=1e-3)
    assert [p.type for p in coarse.points].count("BP") == 2 and len(checked) == 2

    def fails(corr, step, s):
        raise CorrectorFailure("the determinant's change of sign does not survive")

    monkeypatch.setattr(events, "check_on_finer_mesh", fails)
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


def _two_modes(depth, **keywords):
    import elastica_auto as ea
    problem = ea.load_problem(str(EXAMPLES / "two_modes.py"))
    return ea.continuation(problem, {"lam": -0.5}, "lam", bounds=(-1, 3), switch=2,
                           switch_depth=depth, **keywords)


def test_a_second_level_of_switching_reaches_the_mixed_mode():
    """examples/two_modes.py (its docstring): u = v = 0 has branch points at lam = 0 and 1,
    the pure u-mode one at lam = d / (1 - a) = 2, where the mixed mode u^2 = (2 lam + 2) / 3,
    v^2 = (2 lam - 4) / 3 is born. One level of switching gives the pure modes only, two give
    the four mixed branches (each sign of u and of v), a third finds nothing more."""
    one, three = _two_modes(1), _two_modes(3)
    assert len(one) == 5 and len(three) == 9
    for br in one[1:]:
        u, v = br.columns["u0"], br.columns["v0"]
        assert np.all(np.abs(u) < 1e-12) or np.all(np.abs(v) < 1e-12)
    signs = set()
    for br in three[5:]:
        lam, u, v = br.columns["lam"], br.columns["u0"], br.columns["v0"]
        assert lam[0] == pytest.approx(2.0, abs=1e-8) and lam[-1] == 3.0
        # after the start (the branch point, located to ~1e-8 in lam, where v = 0)
        np.testing.assert_allclose(u[1:] ** 2, (2 * lam[1:] + 2) / 3, atol=1e-9)
        np.testing.assert_allclose(v[1:] ** 2, (2 * lam[1:] - 4) / 3, atol=1e-9)
        signs.add((np.sign(u[-1]), np.sign(v[-1])))
    assert signs == {(1, 1), (1, -1), (-1, 1), (-1, -1)}
    assert [br.start for br in three[:5]] == [br.start for br in one]
    assert [br.start for br in three[1:]] == [f"switch at BP{k}" for k in (1, 1, 2, 2, 3, 3, 4, 4)]


def test_the_run_file_s_switch_depth(tmp_path):
    """examples/two_modes.toml asks for two levels; --from a label drops switching."""
    plan = runfile.load(EXAMPLES / "two_modes.toml")
    assert (plan.switch_count, plan.switch_depth) == (2, 2)
    out = run_plan(plan, tmp_path).result
    assert len(out.branches) == 9
    restart = runfile.load(EXAMPLES / "two_modes.toml", tmp_path,
                           restart=f"{out.path}:BP3")
    assert (restart.switch_count, restart.switch_depth) == (0, 1)


RING = """\
\"\"\"u'' + u (1 - lam^2 - u^2) = 0, u'(0) = u'(1) = 0: u = 0, and the circle u^2 + lam^2 = 1
of constant solutions, a closed loop through its branch points at lam = -1 and 1.\"\"\"
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u", "du")
PARAMETERS = [Parameter("lam", 0.0, r"\\lambda", "ode")]


def rhs(s, y, p):
    return np.vstack((y[1], -y[0] * (1 - p["lam"] ** 2 - y[0] ** 2)))


def bc(ya, yb, p):
    return np.array((ya[1], yb[1]))


def exact_start(s, p):
    return np.zeros((2, len(s)))


ORDINATES = [Ordinate("u0", "$u(0)$", lambda s, y, p: y[0, 0], "lam")]
"""


def test_a_closed_loop_is_switched_onto_once(tmp_path):
    """The circle u^2 + lam^2 = 1 leaves u = 0 at lam = -1 and comes back at lam = 1: the
    branch switched at lam = -1 goes round it once, meets the other branch point of u = 0
    (labelled BP where lam turns) and ends back at its start (a closed loop). The other
    orientation at lam = -1 and both at lam = 1 are that loop: not computed again, in this
    process or on a cluster (where they are computed and left out, so that the file is the
    same). Its other branch at lam = 1 is u = 0, so a second level adds nothing."""
    import elastica_auto as ea
    path = tmp_path / "ring.py"
    path.write_text(RING)
    problem = ea.load_problem(str(path))
    one, two, cluster = (ea.continuation(problem, {"lam": -1.5}, "lam", bounds=(-2, 2),
                                         switch=2, switch_depth=depth, ds_max=0.2, jobs=jobs)
                         for depth, jobs in ((1, 1), (2, 1), (1, 2)))
    assert len(one) == len(two) == len(cluster) == 2 and not (two.warnings or cluster.warnings)
    assert [p.type for p in one[0].points].count("BP") == 2
    loop = one[1]
    lam, u = loop.columns["lam"], loop.columns["u0"]
    assert loop.message.startswith("closed loop") and loop.start == "switch at BP1"
    np.testing.assert_allclose(u ** 2 + lam ** 2, 1, atol=1e-8)
    assert lam.min() == pytest.approx(-1, abs=1e-6) and lam.max() == pytest.approx(1, abs=1e-3)
    (bp,) = [p for p in loop.points if p.type == "BP"]
    assert bp.params["lam"] == pytest.approx(-loop.points[0].params["lam"], abs=1e-3)
    for other in (two, cluster):
        for a, b in zip(one, other):
            assert a.start == b.start and a.direction == b.direction
            np.testing.assert_array_equal(a.columns["lam"], b.columns["lam"])
            np.testing.assert_array_equal(a.columns["u0"], b.columns["u0"])


class _FirstOfEachLevel:
    """A default run's background cluster (`execution.cluster.Background`), up at once
    with one worker, that computes the first branch of each run of branches it is handed
    (the job of index 0 of its level) and holds every other, never answering, until
    ``release`` answers them all. Where the level has other jobs, it answers its first once
    ``taken`` is set (this process has started computing one of them): the worker's next
    job is then the one after that, whichever thread runs first."""

    def __init__(self, workers, on_result, taken):
        import threading
        self.workers, self.on_result, self.ready = 1, on_result, threading.Event()
        self.ready.set()
        self.tasks, self.held, self.released, self.taken = [], [], False, taken

    def _answer(self, tag, function, args):
        import threading
        value = (function(*args), "stand-in")
        others = self.on_result.__self__.back >= 1     # the run's `Alongside`, this level

        def answer():
            if tag[1][1] == 0 and others:
                self.taken.wait(60)
            self.on_result(tag, True, value)

        threading.Thread(target=answer).start()

    def submit(self, tag, function, args):
        self.tasks.append(tag)
        if tag[1][1] == 0:
            self._answer(tag, function, args)
        else:
            self.held.append((tag, function, args))
        return True

    def release(self):
        self.released = True
        for task in self.held:
            self._answer(*task)

    def finish(self):
        self.ready.clear()

    def close(self, wait=0.0):
        self.ready.clear()


def test_a_loop_s_other_jobs_are_left_out_as_soon_as_the_loop_is_done(tmp_path, monkeypatch):
    """The ring of `test_a_closed_loop_is_switched_onto_once` in a default run, its cluster
    a stand-in (`_FirstOfEachLevel`): of the four switches (lam = -1 and 1, both ways), the
    worker computes the loop (job 0) while this process computes its other orientation (job
    1); the worker, then handed job 2, holds it. Once the loop is in, jobs 1 to 3 are left
    out at once: the run waits neither for the held job nor computes job 3, and its file is
    jobs = 1's."""
    import threading
    import elastica_auto as ea
    from elastica_auto.execution import cluster
    from elastica_auto.execution.jobs import Callbacks
    from elastica_auto.execution.plan import Request, make_plan
    from elastica_auto.execution.run import (RunResult, Workers, compute, number_labels,
                                             start_job)
    path = tmp_path / "ring.py"
    path.write_text(RING)
    problem = ea.load_problem(str(path))
    kw = dict(bounds=(-2, 2), switch=2, ds_max=0.2)
    one = ea.continuation(problem, {"lam": -1.5}, "lam", **kw)
    from elastica_auto.execution import run as run_module
    stand_in, taken = [], threading.Event()
    compute_here = run_module.compute_branch

    def computed_here(*args, **kwargs):
        # this process's own jobs come with its progress and stop (the cluster's tasks,
        # which the stand-in computes with this same function, with three arguments)
        if len(args) + len(kwargs) > 3:
            taken.set()
        return compute_here(*args, **kwargs)

    monkeypatch.setattr(run_module, "compute_branch", computed_here)
    monkeypatch.setattr(run_module, "CLUSTER_PAYS", 0.0)     # the stand-in up at once
    monkeypatch.setattr(cluster, "Background",
                        lambda n, on: stand_in.append(_FirstOfEachLevel(n, on, taken))
                        or stand_in[-1])
    monkeypatch.setattr(run_module, "usable_cores", lambda: 2)
    plan = make_plan(problem, {"lam": -1.5}, "lam",
                     Request(bounds=(-2, 2), switch=2), {"ds_max": 0.2})
    result = RunResult(None, [], 0.0)
    # were the run to wait for the held job, this answers it after a while (and the test fails)
    watchdog = threading.Timer(60, lambda: stand_in[0].release())
    watchdog.start()
    try:
        compute(plan, [start_job(plan, spec) for spec in plan.branches], result,
                lambda: number_labels(result.branches), Callbacks(), Workers(jobs=0))
    finally:
        watchdog.cancel()
    (background,) = stand_in
    assert not background.released
    assert background.tasks == [("branch", (1, 0)), ("branch", (2, 0)), ("branch", (2, 2))]
    assert [b.worker for b in result.branches] == ["stand-in", "stand-in"]
    assert len(result.branches) == len(one) == 2
    for a, b in zip(one, result.branches):
        assert a.start == b.start and a.direction == b.direction
        np.testing.assert_array_equal(a.columns["lam"], b.column("lam"))


@pytest.mark.parametrize("keywords, words", [
    ({"switch": 2, "switch_depth": 0}, "count >= 1 of levels"),
    ({"switch": 2, "switch_depth": True}, "count >= 1 of levels"),
    ({"switch_depth": 2}, "need switch = N > 0"),
])
def test_switch_depth_is_checked(keywords, words):
    import elastica_auto as ea
    problem = ea.load_problem(str(EXAMPLES / "two_modes.py"))
    with pytest.raises(ea.PlanError, match=words) as exc_info:
        ea.continuation(problem, {"lam": -0.5}, "lam", **keywords)
    assert exc_info.value.key == "switch_depth"
