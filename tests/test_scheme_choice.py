"""The default discretisation, ``ncol = "auto"`` (`numerics.correctors.choose_ncol`,
`gauss_pays`, `branches.stepper.Walk._choose_scheme`): decided by the branch's own solutions,
never by a clock, so these tests check the choice itself, on the two kinds of problem it was
measured on (docs/numerics.md):

* a boundary layer (AUTO's ``kar``, a rotating fluid above a disk on z in [0, 500]): the
  cubic scheme's meshes grow along the branch past GAUSS_PAYS times the fewest nodes and
  Gauss collocation's stay at the floor: the branch turns to Gauss (ncol 4), and its first
  fold agrees with the same fold by the cubic scheme on a mesh refined to ``fold_tol =
  1e-8`` (a second method, the mesh converged: the reference of test_auto_demos);
* the elastica (the shipped runs' kind): every branch stays cubic (its points get a direct
  index count, which needs the cubic scheme's fine meshes), and its points are those of
  ``ncol = 0`` exactly (the same numbers: the choice adds no solve to the branch);
* a user's ``ncol`` (0, or Gauss at 3) always wins;
* a restart from a stored label keeps the scheme that computed it, and says Gauss where it
  is used.
"""

from __future__ import annotations

import dataclasses
import json

import h5py
import numpy as np
import pytest

from elastica_auto.core.options import NCOL_AUTO, ContinuationOptions, OptionsError
from elastica_auto.execution import runfile
from elastica_auto.numerics.correctors import (AUTO_GAUSS, GAUSS_PAYS, choose_ncol,
                                               gauss_pays, may_turn_to_gauss)
from helpers import REPO, ROTATING_ARM, run_cli, run_plan

KAR = REPO / "benchmarks" / "auto" / "kar.toml"


def ncols(result) -> list:
    return [json.loads(br.attrs["options"])["ncol"] for br in result.file.branches]


def kar(out, *overrides):
    return run_plan(runfile.load(KAR, out, ("stop=['LP1']", *overrides)), out)


@pytest.fixture(scope="module")
def kar_auto(tmp_path_factory):
    return kar(tmp_path_factory.mktemp("kar_auto"))


def test_the_default_is_auto_and_an_integer_keeps_its_meaning():
    assert ContinuationOptions().ncol == NCOL_AUTO
    assert ContinuationOptions(ncol=0).ncol == 0
    assert ContinuationOptions(ncol=4).ncol == 4
    # every refusal names what is accepted (a string was refused as "must be a finite
    # number", which hid "auto")
    for bad in ("fast", "AUTO", 1, 8, 4.5, True, None):
        with pytest.raises(OptionsError, match='ncol must be "auto", 0 .* from 2 to 7'):
            ContinuationOptions(ncol=bad)


def test_solve_bvp_refuses_a_gauss_ncol(cli_exe, tmp_path):
    """The solve_bvp corrector solves the cubic scheme only: a Gauss ncol with it is refused
    (it was computed cubic while the branch recorded ncol 4 and its line said "Gauss ncol
    4"), in one line that says what to set; ncol 0 and "auto" stay accepted with it."""
    for ncol in (2, 4, 7):
        with pytest.raises(OptionsError, match='needs corrector = "collocation"'):
            ContinuationOptions(corrector="solve_bvp", ncol=ncol)
    for ncol in (0, NCOL_AUTO):
        assert ContinuationOptions(corrector="solve_bvp", ncol=ncol).ncol == ncol
    proc = run_cli(cli_exe, "run", KAR, "--out", tmp_path, "--set", "ncol=4",
                   "--set", "corrector=solve_bvp")
    assert proc.returncode == 2
    (line,) = proc.stderr.splitlines()
    assert line.startswith("elastica-auto: error: ") and "set ncol = 0" in line
    assert not list(tmp_path.iterdir())


def test_a_boundary_layer_turns_to_gauss_and_keeps_its_fold(kar_auto, tmp_path):
    (br,) = kar_auto.file.branches
    assert ncols(kar_auto) == [AUTO_GAUSS]
    nodes = br.columns["nodes"]
    # cubic from the trivial start (51 nodes) until its mesh passed GAUSS_PAYS times the
    # fewest; Gauss's meshes after that are several times smaller
    assert nodes[0] == 51 and nodes.max() > GAUSS_PAYS * 51
    assert nodes[-1] < nodes.max() / 4
    (lp,) = [v for t, v in zip(br.columns["type"], br.columns["gamma"]) if t == "LP"]
    fine = kar(tmp_path, "ncol=0", "fold_tol=1e-8")
    (lp_fine,) = [v for t, v in zip(fine.file.branches[0].columns["type"],
                                    fine.file.branches[0].columns["gamma"]) if t == "LP"]
    assert ncols(fine) == [0]
    assert abs(lp - lp_fine) < 1e-9


def test_the_rule_on_the_states_themselves(kar_auto, tmp_path):
    """`gauss_pays` on kar's fold (a boundary layer, solved by Gauss) says yes, and
    `choose_ncol` under "auto" follows it, a number or a stored scheme winning. On the
    elastica's finest-meshed point of the rotating arm at tol = 1e-9 the node estimate
    says yes too, and the index keeps the cubic scheme."""
    opt = ContinuationOptions()
    plan = runfile.load(KAR)
    layer = kar_auto.file.label("LP1").state
    assert gauss_pays(plan.problem, "gamma", opt, layer)
    assert choose_ncol(plan.problem, "gamma", opt, layer) == AUTO_GAUSS
    assert choose_ncol(plan.problem, "gamma", opt, layer, stored=0) == 0
    assert choose_ncol(plan.problem, "gamma", ContinuationOptions(ncol=0), layer) == 0
    assert choose_ncol(plan.problem, "gamma", ContinuationOptions(ncol=3), layer) == 3
    assert choose_ncol(plan.problem, "gamma",
                       ContinuationOptions(corrector="solve_bvp"), layer) == 0
    arm = _small_arm(tmp_path / "arm", ("tol=1e-9",))
    finest = max((p for br in arm.result.branches for p in br.points if p.state is not None),
                 key=lambda p: len(p.state.s))
    tight = ContinuationOptions(tol=1e-9)
    assert gauss_pays(arm.plan.problem, "psi", tight, finest.state)   # the nodes alone
    assert not may_turn_to_gauss(arm.plan.problem)                    # but an index
    assert choose_ncol(arm.plan.problem, "psi", tight, finest.state) == 0
    assert choose_ncol(arm.plan.problem, "psi", ContinuationOptions(ncol=4),
                       finest.state) == 4


def _small_arm(out, overrides):
    plan = runfile.load(ROTATING_ARM, out, overrides)
    plan.branches = [b for b in plan.branches if abs(b.params["P"] - np.pi ** 2 / 4) < 1e-12
                     and b.params["eps"] == 0.25]
    return run_plan(plan, out)


def test_the_elastica_stays_cubic_with_the_same_numbers(tmp_path):
    """At tol = 1e-9 the cubic meshes pass 8 (ntst + 1) nodes and Gauss's estimate stays at
    the fewest: Gauss would pay by the estimate, but the elastica's points get a direct
    index count, which Gauss's coarse meshes do not resolve (`may_turn_to_gauss`)."""
    auto = _small_arm(tmp_path / "auto", ("tol=1e-9",))
    cubic = _small_arm(tmp_path / "cubic", ("ncol=0", "tol=1e-9"))
    assert max(n for br in cubic.file.branches for n in br.columns["nodes"]) > GAUSS_PAYS * 51
    assert ncols(auto) == ncols(cubic) == [0] * len(auto.file.branches)
    for a, b in zip(auto.file.branches, cubic.file.branches):
        for name in ("psi", "m1", "nodes", "index"):
            assert np.array_equal(a.columns[name], b.columns[name]), name


def test_a_users_ncol_wins_on_the_boundary_layer(tmp_path):
    assert ncols(kar(tmp_path / "a", "ncol=0")) == [0]
    three = kar(tmp_path / "b", "ncol=3")
    assert ncols(three) == [3]
    assert json.loads(three.file.attrs["settings"])["options"]["ncol"] == 3


def test_the_choice_survives_a_restart_and_is_said(kar_auto, cli_exe, tmp_path):
    """From kar's fold computed by Gauss under "auto", a restart keeps Gauss at 4 from its
    start on (its first point is the label's own solution, on the label's mesh), and the
    summary says so. From the same fold computed by the cubic scheme (ncol = 0), where
    the start alone would choose Gauss, the restart keeps the cubic scheme throughout."""
    text = KAR.read_text().replace('start = "trivial"', 'start = "kar.h5:LP1"')
    text = text.replace('equation = "kar.py"', f'equation = "{KAR.parent / "kar.py"}"')
    text = text.replace("max_points = 500", "max_points = 6")
    # the label's parameters, not the run file's (gamma = 1 would be continued back to)
    text = text.replace("[parameters]\ngamma = 1\nfm = 0\n", "")
    restart = tmp_path / "again.toml"
    restart.write_text(text)
    cubic = kar(tmp_path / "cubic", "ncol=0")
    assert ncols(cubic) == [0]
    for source in (kar_auto.file, cubic.file):
        out = tmp_path / f"from{ncols_of(source)}"
        out.mkdir()
        (out / "kar.h5").write_bytes(source.path.read_bytes())
        proc = run_cli(cli_exe, "run", restart, "--out", out, "-q", "-j", "1")
        assert proc.returncode == 0, proc.stderr
        ncol = ncols_of(source)
        line = next(x for x in proc.stdout.splitlines() if x.startswith("branch 1/"))
        assert ("Gauss ncol 4" in line) == (ncol == AUTO_GAUSS), line
        assert [json.loads(a)["ncol"] for a in _branch_options(out / "again.h5")] == [ncol]
        assert json.loads(_settings(out / "again.h5"))["options"]["ncol"] == NCOL_AUTO
        label = source.label("LP1").state
        with h5py.File(out / "again.h5") as h:
            (br,) = h["branches"].values()
            nodes = list(br["columns"]["nodes"][()])
        assert nodes[0] == len(label.s)
        if ncol:
            assert max(nodes) < GAUSS_PAYS * 51
        else:
            assert min(nodes) > GAUSS_PAYS * 51


def ncols_of(file) -> int:
    return json.loads(file.branches[0].attrs["options"])["ncol"]


def _branch_options(path):
    with h5py.File(path) as h:
        return [br.attrs["options"] for br in h["branches"].values()]


def _settings(path):
    with h5py.File(path) as h:
        return h.attrs["settings"]


def test_auto_in_a_run_file(tmp_path):
    text = KAR.read_text()
    good = tmp_path / "good.toml"
    good.write_text(text.replace("[options]\n", '[options]\nncol = "auto"\n')
                    .replace('"kar.py"', f'"{KAR.parent / "kar.py"}"'))
    assert runfile.load(good).options.ncol == NCOL_AUTO
    bad = tmp_path / "bad.toml"
    bad.write_text(good.read_text().replace('ncol = "auto"', 'ncol = "fast"'))
    with pytest.raises(Exception, match='ncol.*"auto"'):
        runfile.load(bad)
    assert dataclasses.replace(ContinuationOptions(), ncol=5).ncol == 5


LAYERS = '''"""u'' = lam^2 sinh(u), u(0) = 1, u(1) = -1: layers of width 1/lam at both ends."""
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u", "v")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode", doc="inverse layer width")]


def rhs(s, y, p):
    return np.vstack((y[1], p["lam"] ** 2 * np.sinh(y[0])))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = p["lam"] ** 2 * np.cosh(y[0])
    return jac


def bc(ya, yb, p):
    return np.array((ya[0] - 1, yb[0] + 1))


def exact_start(s, p):
    if p["lam"] != 0:
        return None
    return np.vstack((1 - 2 * s, np.full(len(s), -2.0)))


ORDINATES = [Ordinate("v0", "u'(0)", lambda s, y, p: y[1, 0], None, "u' at 0")]
'''


def test_a_gauss_label_restarts_under_solve_bvp(tmp_path):
    """Layers of width 1/lam at both ends of u'' = lam^2 sinh(u), u(0) = 1, u(1) = -1: under
    "auto" the branch from lam = 0 turns to Gauss (its label at lam = 300 sits on a few
    dozen nodes). Restarted from that label with the solve_bvp corrector (the cubic scheme,
    which needs ten times the nodes there), the branch goes on, and u'(0) is the closed
    form of separated layers, -2 lam sinh(1/2) (the first integral u'^2 / 2 = lam^2
    (cosh u - 1) with u -> 0 away from the ends; exponentially small corrections at lam
    = 300). It ended MX at its first step: solve_bvp started on the label's mesh, at most
    three times its nodes per step."""
    import elastica_auto as ea
    (tmp_path / "layers.py").write_text(LAYERS)
    problem = ea.load_problem(str(tmp_path / "layers.py"))
    (up,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 300), ds=0.1,
                            ds_max=50)
    assert up.options["ncol"] == AUTO_GAUSS and up.end == "EP"
    label = up.label("EP2")
    assert label.state.params["lam"] == 300 and len(label.state.s) < 100
    (on,) = ea.continuation(problem, label, "lam", bounds=(0, 301), corrector="solve_bvp",
                            max_points=8)
    assert on.options["ncol"] == 0 and on.end == "EP", on.message
    c = on.columns
    assert len(c["lam"]) == 8 and c["lam"][-1] > 300
    closed = -2 * c["lam"][1:] * np.sinh(0.5)
    assert np.max(np.abs(c["v0"][1:] / closed - 1)) < 1e-7


LAYER_AT_ZERO = '''"""eps u'' + u' + lam exp(u) = 0, u(0) = u(1) = 0: a layer of width eps at 0."""
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u", "v")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode", doc="load"),
              Parameter("eps", 0.1, "eps", "ode", doc="layer width")]


def rhs(s, y, p):
    return np.vstack((y[1], -(y[1] + p["lam"] * np.exp(y[0])) / p["eps"]))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["lam"] * np.exp(y[0]) / p["eps"]
    jac[1, 1] = -1.0 / p["eps"]
    return jac


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def exact_start(s, p):
    return np.zeros((2, len(s))) if p["lam"] == 0 else None


ORDINATES = [Ordinate("v0", "u'(0)", lambda s, y, p: y[1, 0], None, "u' at 0")]
'''


def test_gauss_continues_a_thinning_layer_across_a_regrid(tmp_path):
    """eps u'' + u' + lam e^u = 0, u(0) = u(1) = 0 at lam = 0.3, continued by Gauss at 4
    points in eps from 0.1 down to 1e-3: the layer at s = 0 thins across the 50 intervals
    until the mesh is equidistributed (same node count, nodes moved into the layer). There
    the trapezoid norm of the last tangent, moved onto the new nodes, was 0.8, and the turn
    test read 36 degrees at every ds: the branch ended MX at eps = 0.015. It now reaches
    1e-3, and u'(0) there agrees with scipy's solve_bvp at tol 1e-9 (a second method)."""
    import elastica_auto as ea
    from scipy.integrate import solve_bvp
    (tmp_path / "layer.py").write_text(LAYER_AT_ZERO)
    problem = ea.load_problem(str(tmp_path / "layer.py"))
    (up,) = ea.continuation(problem, {"lam": 0.0, "eps": 0.1}, "lam", bounds=(-1, 0.3),
                            ds=0.01, ds_max=0.05)
    (down,) = ea.continuation(problem, up.label("EP2"), "eps", directions="-",
                              bounds=(1e-3, 1), ds=0.01, ds_max=0.05, max_points=500, ncol=4)
    assert down.end == "EP" and down.columns["eps"][-1] == 1e-3, down.message

    def f(s, y):
        return np.vstack((y[1], -(y[1] + 0.3 * np.exp(y[0])) / 1e-3))

    s = np.linspace(0, 1, 4001)
    ref = solve_bvp(f, lambda a, b: np.array([a[0], b[0]]), s, np.zeros((2, s.size)),
                    tol=1e-9, max_nodes=500000)
    assert ref.status == 0
    assert abs(down.columns["v0"][-1] / ref.y[1, 0] - 1) < 1e-8
