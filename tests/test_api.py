"""The Python API (`elastica_auto.continuation`, `save`, labels, columns), with no run file.

Numbers are checked against closed forms: the Bratu family u = -2 ln(cosh(z (x - 1/2)) /
cosh(z / 2)), lam = 2 z^2 / cosh^2(z / 2), whose fold is at z tanh(z / 2) = 2; the branch
points of u'' + p u (1 + u^2) = 0, u(0) = u(1) = 0 at p = (k pi)^2. The API and a run file
must give the same branches, number for number.
"""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import elastica_auto as ea
from elastica_auto.execution import runfile
from elastica_auto.branches.branch import EXTRA_COLUMNS, export_names
from helpers import EXAMPLES, elastica_run_file, run_cli, run_plan

BRATU = EXAMPLES / "bratu.py"


def lam_of(z):
    return 2 * z * z / math.cosh(z / 2) ** 2


@pytest.fixture(scope="module")
def bratu():
    return ea.load_problem(str(BRATU))


@pytest.fixture(scope="module")
def bratu_branches(bratu):
    return ea.continuation(bratu, {"lam": 0.0}, "lam", bounds=(-1, 4), uz=[1, 2, 3], ds=0.05,
                           ds_max=0.5, max_points=60)


def test_bratu_fold_and_user_points_by_the_api(bratu_branches):
    (br,) = bratu_branches
    z_c = brentq(lambda z: z * math.tanh(z / 2) - 2, 1.0, 4.0, xtol=1e-15)
    (lp,) = br.folds
    assert lp.name == "LP1" and abs(lp.params["lam"] - lam_of(z_c)) <= 1e-8
    cols = br.columns
    uz = cols["type"] == "UZ"
    np.testing.assert_array_equal(cols["lam"][uz], [1, 2, 3, 3, 2, 1])
    assert list(cols["label"][uz]) == [f"UZ{k}" for k in range(1, 7)]
    # each UZ solution is the closed form's: z from u(1/2) = 2 ln cosh(z / 2)
    for u_half, lam in zip(cols["u_half"][uz], cols["lam"][uz]):
        z = 2 * math.acosh(math.exp(u_half / 2))
        assert abs(lam_of(z) - lam) <= 1e-5


def test_restart_from_a_label_in_memory(bratu, bratu_branches):
    """From UZ5 (lam = 2, upper family) downwards in lam: the upper family, on which u(1/2)
    grows as lam falls; each point on the closed form."""
    start = bratu_branches.label("UZ5")
    assert start.path is None and start.state.params["lam"] == 2.0
    (br,) = ea.continuation(bratu, start, "lam", bounds=(0.5, 4), directions="-",
                            max_points=40)
    assert br.start == "UZ5" and br.end == "EP"
    lam, u_half = br.columns["lam"], br.columns["u_half"]
    assert lam[-1] == pytest.approx(0.5, abs=1e-12) and np.all(np.diff(u_half) > 0)
    for uh, lm in zip(u_half, lam):
        z = 2 * math.acosh(math.exp(uh / 2))
        assert abs(lam_of(z) - lm) <= 1e-5


def test_api_and_run_file_give_the_same_branches(tmp_path, bratu_branches):
    """examples/bratu.toml is the call of the first test: every column, number for number."""
    from_file = run_plan(runfile.load(EXAMPLES / "bratu.toml"), tmp_path).result.branches
    assert len(from_file) == len(bratu_branches) == 1
    a, b = bratu_branches[0].columns, from_file[0].columns
    assert list(a) == list(b)
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_elastica_api_matches_its_run_file(tmp_path):
    """Both directions, a periodic parameter with user points, a parameter grid."""
    path = elastica_run_file(tmp_path / "small.toml", uz=[0, "pi/2"])
    path.write_text(path.read_text().replace("eps = '0.25'", "eps = [0.25, 0.5]"))
    from_file = run_plan(runfile.load(path), tmp_path / "out").result.branches
    problem = ea.load_problem("elastica_lever_arm")
    from_api = ea.continuation(problem, {"P": math.pi ** 2 / 4, "psi": 0, "alpha": 0,
                                         "theta0": 0}, "psi", params={"eps": [0.25, 0.5]},
                               bounds=(-2 * math.pi, 2 * math.pi), directions="both",
                               uz=[0, math.pi / 2], uz_period=2 * math.pi)
    assert [b.direction for b in from_api] == [1, -1, 1, -1]
    assert [b.points[0].params["eps"] for b in from_api] == [0.25, 0.25, 0.5, 0.5]
    uz = np.concatenate([b.columns["psi"][b.columns["type"] == "UZ"] for b in from_api])
    assert np.any(np.abs(uz + 1.5 * math.pi) < 1e-12)        # pi/2 - 2 pi: uz_period applied
    for x, y in zip(from_api, from_file):
        for name, col in x.columns.items():
            np.testing.assert_array_equal(col, y.columns[name], err_msg=name)


def test_columns_in_memory_on_file_and_in_the_export(tmp_path, bratu_branches, cli_exe):
    path = ea.save(bratu_branches, tmp_path / "bratu.h5")
    stored = ea.BranchFile(path).branches[0]
    mine = bratu_branches[0].columns
    assert list(stored.columns) == list(mine)
    for name, col in mine.items():
        np.testing.assert_array_equal(stored.columns[name], col, err_msg=name)
    assert list(mine) == export_names(["lam"], ["dE_dlam", "E", "du0", "u_half"]) + \
        list(EXTRA_COLUMNS)
    out = tmp_path / "bratu.csv"
    assert run_cli(cli_exe, "export", path, "-o", out).returncode == 0
    with open(out) as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == export_names(["lam"], ["dE_dlam", "E", "du0", "u_half"])
    assert [r[3] for r in rows[1:]] == list(mine["label"])
    np.testing.assert_array_equal([float(r[4]) for r in rows[1:]], mine["lam"])


def test_save_renumbers_a_selection_and_leaves_the_branches_alone(tmp_path, bratu,
                                                                   bratu_branches):
    again = ea.continuation(bratu, {"lam": 0.0}, "lam", bounds=(-1, 4), max_points=60)
    both = [bratu_branches[0], again[0]]      # each has its own LP1
    with pytest.raises(ea.PlanError, match="needs problem="):
        ea.save(both, tmp_path / "two.h5")
    assert ea.save(again + bratu_branches, tmp_path / "sum.h5").name == "sum.h5"
    path = ea.save(both, tmp_path / "two.h5", problem=bratu)
    bf = ea.BranchFile(path)
    assert sorted(n for n in bf.labels if n.startswith("LP")) == ["LP1", "LP2"]
    assert again[0].folds[0].name == "LP1"    # unchanged in memory
    lp2 = bf.label("LP2")
    assert lp2.branch == 2 and lp2.state.params["lam"] == again[0].folds[0].params["lam"]
    with pytest.raises(ea.StoreError, match="<name>.h5"):
        ea.save(both, tmp_path / "two.csv", problem=bratu)


def test_switch_at_a_branch_point_without_a_hook():
    """The trivial branch of u'' + p u (1 + u^2) = 0 has BPs at (k pi)^2; Switch(BP1) gives
    the first mode both ways, mirror images; switch=1 gives the same branches."""
    problem = ea.load_problem(str(EXAMPLES / "nonlinear_eigenvalue.py"))
    trivial = ea.continuation(problem, {"p": 0.0}, "p", bounds=(-1, 12), ds=0.5, ds_max=2.0)
    (bp,) = [p for p in trivial[0].points if p.type == "BP"]
    assert bp.params["p"] == pytest.approx(math.pi ** 2, rel=1e-9)
    up, down = ea.continuation(problem, ea.Switch(trivial.label("BP1")), "p",
                               bounds=(-1, 12), ds=0.5, ds_max=2.0, max_points=30)
    assert up.start == down.start == "switch at BP1"
    np.testing.assert_allclose(up.columns["slope"], -down.columns["slope"], atol=1e-9)
    assert abs(up.columns["slope"][-1]) > 1
    together = ea.continuation(problem, {"p": 0.0}, "p", bounds=(-1, 12), ds=0.5,
                               ds_max=2.0, max_points=30, switch=1)
    assert len(together) == 3
    np.testing.assert_array_equal(together[1].columns["slope"], up.columns["slope"])


def test_ctrl_c_returns_what_was_computed(bratu):
    calls = []

    def progress(k, npts, nfolds, lam):
        calls.append(npts)
        if npts == 10:
            raise KeyboardInterrupt

    with pytest.raises(ea.Interrupted) as info:
        ea.continuation(bratu, {"lam": 0.0}, "lam", bounds=(-1, 4), progress=progress)
    (br,) = info.value.branches
    assert br.interrupted and br.end == "MX" and len(br.points) == 10
    assert br.points[-1].name == "MX1"


def test_a_progress_callback_that_raises_is_the_callers_error_not_an_internal_one(bratu):
    """What the caller's ``progress`` raises ends the branch there (MX, the points so far
    kept) as the caller's failure: diagnostics of kind "caller" naming the callback's own
    line, no "internal error" (it was one, which reads as a bug of the engine); Ctrl-C from
    it stays an interruption (the test above)."""
    def progress(k, npts, nfolds, lam):
        if npts == 6:
            raise ValueError("my callback broke")

    (up,) = ea.continuation(bratu, {"lam": 0.0}, "lam", bounds=(-1, 4), progress=progress)
    assert up.end == "MX" and len(up.points) == 6 and up.points[-1].type == "MX"
    assert up.diagnostics["kind"] == "caller" and "text" not in up.diagnostics
    assert up.diagnostics["exception"] == "ValueError"
    assert up.diagnostics["where"].startswith("test_api.py:")
    assert up.diagnostics["where"].endswith("in progress, the progress callback")
    assert up.message.startswith("ValueError: my callback broke (test_api.py:")
    assert "internal error" not in up.message


def test_a_lost_cluster_returns_what_was_computed(bratu, monkeypatch):
    """hostile H5, from Python: a cluster that had no worker for ``worker_timeout`` raises
    ``ea.ClusterLost``, whose ``branches`` hold the branches computed so far and those not
    computed (here a stand-in for the cluster's run: one branch, then the cluster lost)."""
    import elastica_auto.api as api_module
    compute = api_module.compute

    def lost(plan, first, result, save, callbacks, workers):
        assert workers.worker_timeout == 5.0
        compute(plan, first, result, save, callbacks)        # in this process
        raise ea.ClusterLost("the Dask scheduler at tcp://x:1 has had no worker for 5 s")

    monkeypatch.setattr(api_module, "compute", lost)
    with pytest.raises(ea.ClusterLost, match="no worker for 5 s") as info:
        ea.continuation(bratu, {"lam": 0.0}, "lam", bounds=(-1, 4), worker_timeout=5.0)
    (br,) = info.value.branches
    assert len(br.points) > 10 and br.points[0].params["lam"] == 0.0


@pytest.mark.parametrize("kwargs, key, words", [
    ({"parameter": "mu"}, "parameter", "unknown parameter 'mu'"),
    ({"bounds": (4, -1)}, "bounds", "lower < upper"),
    ({"bounds": (0, math.inf)}, "bounds", "finite"),
    ({"directions": "up"}, "directions", "'both'"),
    ({"stop": "LP1"}, "stop", "list"),
    ({"stop": ["LP0"]}, "stop", "LP4"),
    ({"uz_period": 1.0}, "uz_period", "without uz"),
    ({"ds_maxx": 0.1}, "options", "unknown option 'ds_maxx'"),
    ({"ds": 2.0}, "options", "ds_max"),
    ({"corrector": "newton"}, "options", "collocation"),
    ({"params": {"mu": 1}}, "params.mu", "unknown parameter"),
    ({"params": {"lam": 0.5}}, "params", "given both"),
    ({"jobs": 0}, "jobs", "positive"),
    ({"worker_timeout": 0}, "worker_timeout", "positive number of seconds"),
    ({"worker_timeout": math.nan}, "worker_timeout", "positive number of seconds"),
    ({"worker_timeout": "60"}, "worker_timeout", "positive number of seconds"),
    ({"switch": -1}, "switch", "count"),
    ({"start": "trivial"}, "start", "a dict"),
    ({"start": []}, "start", "empty"),
])
def test_bad_arguments_name_themselves(bratu, kwargs, key, words):
    args = {"start": {"lam": 0.0}, "parameter": "lam", **kwargs}
    with pytest.raises(ea.PlanError) as info:
        ea.continuation(bratu, args.pop("start"), args.pop("parameter"), **args)
    assert info.value.key == key and words in str(info.value), str(info.value)


def test_a_request_reads_each_iterable_once_into_tuples():
    """Request keeps what it checked: one-shot iterators are read once (the check does not
    empty them), and the values are tuples of floats and names, frozen."""
    from elastica_auto.execution.plan import Request
    r = Request(uz=(x for x in [1, 2]), uz_period=3, free=iter(["p"]), stop=iter(["LP2"]),
                bounds=[0, 1], landing=True, damping=iter([0.5]), damping_folds=iter(["LP1"]))
    assert (r.uz, r.uz_period, r.free, r.stop) == ((1.0, 2.0), 3.0, ("p",), ("LP2",))
    assert (r.bounds, r.damping, r.damping_folds) == ((0.0, 1.0), (0.5,), ("LP1",))
    assert Request().limits == (-math.inf, math.inf)
    with pytest.raises(AttributeError):
        r.switch = 1


def test_a_label_of_another_module_is_refused(bratu, bratu_branches):
    problem = ea.load_problem(str(EXAMPLES / "nonlinear_eigenvalue.py"))
    with pytest.raises(ea.PlanError, match="computed with"):
        ea.continuation(problem, bratu_branches.label("LP1"), "p")
    with pytest.raises(ea.PlanError, match="needs a BP label"):
        ea.continuation(bratu, ea.Switch(bratu_branches.label("LP1")), "lam")
    with pytest.raises(KeyError, match="no label 'BP1'"):
        bratu_branches.label("BP1")


def test_no_exact_start_is_a_start_error(bratu):
    with pytest.raises(ea.StartError, match="no exact start"):
        ea.continuation(bratu, {"lam": 1.0}, "lam")


def test_the_worked_example_prints_what_the_docs_say(tmp_path, monkeypatch):
    """docs/python-api.md: its script runs and prints its output block (a docs check; the
    numbers themselves are checked against shooting in test_folds.py)."""
    import contextlib
    import io
    import re
    text = (EXAMPLES.parent / "docs" / "python-api.md").read_text()
    code, printed = re.findall(r"```(?:python)?\n(.*?)```", text, re.S)[:2]
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "python-api.md", "exec"), {})
    assert out.getvalue() == printed
    assert ea.BranchFile(tmp_path / "out" / "arm.h5").label("LP2").branch == 2


def test_elastica_critical_loads_by_the_api():
    """The straight rod continued in P through the API alone: its branch points are the
    critical loads cot(sqrt P) = eps sqrt(P), and the index (fold rule and direct count
    agreeing away from them: at a BP the second variation is singular) goes 0, 1, 2 through
    them."""
    eps = 0.5
    problem = ea.load_problem("elastica_lever_arm")
    (br,) = ea.continuation(problem, {"P": 1.0, "eps": eps}, "P", bounds=(0.5, 30))
    cols = br.columns
    bp = cols["type"] == "BP"
    roots = [brentq(lambda w: math.cos(w) - eps * w * math.sin(w), k * math.pi + 1e-9,
                    (k + 1) * math.pi - 1e-9, xtol=1e-15) ** 2 for k in range(2)]
    np.testing.assert_allclose(cols["P"][bp], roots, rtol=0, atol=1e-8)
    assert np.all(cols["index"] == cols["index_rule"])
    assert np.all(cols["index_rule"][~bp] == cols["index_direct"][~bp])
    for P, k in zip(cols["P"], cols["index"]):
        if min(abs(P - r) for r in roots) > 1e-6:
            assert k == sum(P > r for r in roots)


def test_the_readme_example_runs(tmp_path, monkeypatch):
    """README.md's Python example runs as written and writes its file; its two folds are
    the mirror images of each other (psi -> -psi, index change the same)."""
    import re
    text = (EXAMPLES.parent / "README.md").read_text()
    (code,) = re.findall(r"```python\n(.*?)```", text, re.S)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out").mkdir()
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    arm = scope["arm"]
    lp1, lp2 = (p for br in arm for p in br.folds)
    assert lp1.params["psi"] == pytest.approx(-lp2.params["psi"], abs=1e-9)
    uz1 = ea.BranchFile(tmp_path / "out" / "arm.h5").label("UZ1")
    assert uz1.state.params["psi"] == pytest.approx(math.pi / 2, abs=1e-12)


def test_load_problem_takes_a_path_and_refuses_other_types():
    assert ea.load_problem(BRATU).parameter_names == ["lam"]
    with pytest.raises(ea.ProblemError, match="expected a module name or a path"):
        ea.load_problem(3)


def test_every_public_name_is_the_object_of_that_name():
    """The package's lazy table of public names (``ea.__all__``): each resolves, to the class
    or function defined under that name (a wrong module in the table raises or gives another
    object), and the names a module is written from are among them."""
    for name in ea.__all__:
        value = getattr(ea, name)
        assert getattr(value, "__name__", name) == name, name
    assert {"Parameter", "Ordinate", "SecondVariation", "Constraint", "Symmetry", "Flow",
            "simpson", "hermite", "trapezoid_weights"} <= set(ea.__all__)
