"""Where a snap lands (elastica_auto.analysis.landing and the elastica's gradient_flow hook).

Independent references: the energy of the module's docstring differentiated by central
differences (the flow's force and Jacobian); the BVP's equilibria found by shooting (the
method of lines converges to them at second order, and every landing is one of them); the
mirror symmetry (psi, theta) -> (-psi, -theta) at alpha = theta0 = 0 (a mirrored fold lands on
the mirrored equilibrium); and the dynamics' own law, dE/dt <= 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto.analysis.landing as landing_module
from elastica_auto.analysis.landing import NODES, PUSH, land
from elastica_auto.analysis.equilibria import enumerate_equilibria, snap_lps


P_HIGH = 9 * math.pi ** 2 / 4
DAMPING = 2.0


@pytest.fixture(scope="module")
def arm(elastica, tmp_path_factory):
    """The rotating arm at eps = 0.5, P = 9 pi^2/4 (rotating_arm's last two branches), both
    ways, with where every snap lands, and the damped model's landing at ``c = DAMPING``
    from every fold; saved for the command line."""
    import elastica_auto as ea
    branches = ea.continuation(elastica, {"eps": 0.5, "P": P_HIGH}, "psi", directions="both",
                               bounds=(-6 * math.pi, 6 * math.pi), landing=True,
                               damping=[DAMPING])
    path = ea.save(branches, tmp_path_factory.mktemp("landing") / "arm.h5")
    return branches, path


def _folds(branches, problem, count=None):
    """(point, beyond, equilibria) of the folds ending a stable segment."""
    out = []
    for br in branches:
        for p, side in snap_lps(br):
            k = br.points.index(p)
            nb = br.points[k - 1 if side == "before" else k + 1]
            beyond = int(np.sign(p.params["psi"] - nb.params["psi"]))
            out.append((p, beyond, enumerate_equilibria(problem, p.params)))
    return out[:count]




def test_the_flow_is_the_gradient_of_its_energy(elastica):
    """force = -grad E / mass and its Jacobian, against central differences of the energy."""
    p = {**elastica.defaults(), "P": P_HIGH, "eps": 0.5, "psi": 1.0, "theta0": 0.3}
    s = np.linspace(0.0, 1.0, 41)
    flow = elastica.gradient_flow(p, s)
    rng = np.random.default_rng(1)
    u = 0.3 + rng.normal(size=40)
    d = 1e-6
    grad = np.array([(flow.energy(u + d * e) - flow.energy(u - d * e)) / (2 * d)
                     for e in np.eye(40)])
    np.testing.assert_allclose(-flow.force(u) * flow.mass, grad, atol=1e-6)
    jac = np.array([(flow.force(u + d * e) - flow.force(u - d * e)) / (2 * d)
                    for e in np.eye(40)]).T
    np.testing.assert_allclose(flow.jacobian(u).toarray(), jac, rtol=1e-6, atol=1e-4)


def test_the_method_of_lines_converges_at_second_order(elastica):
    """The discrete equilibrium next to each shooting equilibrium (Newton on force(u) = 0)
    is O(h^2) from it: halving h divides the distance by about 4."""
    from scipy.sparse.linalg import spsolve
    p = {**elastica.defaults(), "P": P_HIGH, "eps": 0.5, "psi": 2.0}
    ratios = []
    for eq in enumerate_equilibria(elastica, p):
        dist = []
        for n in (50, 100, 200):
            s = np.linspace(0.0, 1.0, n + 1)
            flow = elastica.gradient_flow(p, s)
            u = exact = flow.to_u(eq.state(s))
            for _ in range(20):
                u = u - spsolve(flow.jacobian(u), flow.force(u))
            assert np.max(np.abs(flow.force(u))) < 1e-8
            dist.append(np.max(np.abs(u - exact)))
        ratios += [dist[0] / dist[1], dist[1] / dist[2]]
    assert len(ratios) >= 10
    assert 3.5 < min(ratios) and max(ratios) < 4.5, ratios


def test_every_fold_lands_on_a_stable_equilibrium_of_the_table(arm):
    """Each fold of the snap-back table has exactly one target marked landed, with the energy
    released and the transit time; the others have none."""
    rows = arm[0].snaps
    assert len({(r["branch"], r["lp"]) for r in rows}) >= 10
    folds = {(int(r["branch"]), r["lp"]) for r in rows}
    for fold in folds:
        mine = [r for r in rows if (int(r["branch"]), r["lp"]) == fold]
        landed = [r for r in mine if r["landed"] == 1]
        assert len(landed) == 1, fold
        assert landed[0]["index"] == 0
        assert landed[0]["energy_released"] > 0 and landed[0]["transit_time"] > 0
        assert all(math.isnan(r["energy_released"]) for r in mine if r["landed"] == 0)


def test_mirrored_folds_land_on_mirrored_equilibria(arm):
    """At alpha = theta0 = 0 the fold at psi has a mirror image at -psi (theta -> -theta);
    the rod lands from it on the mirror image (k = theta'(0) -> -k) of the first landing."""
    rows = [r for r in arm[0].snaps if r["landed"] == 1]
    assert len(rows) >= 10
    for r in rows:
        assert any(abs(q["value"] + r["value"]) < 1e-6 and abs(q["k"] + r["k"]) < 1e-6
                   for q in rows), (r["lp"], r["value"], r["k"])


def test_the_energy_decreases_and_the_landing_is_robust(arm, elastica):
    """Along the dynamics the energy never increases; halving the push or doubling the
    spatial resolution lands on the same equilibrium. The folds at P = 9 pi^2/4, where each
    fold has three or more stable equilibria to choose from."""
    folds = _folds(arm[0], elastica, count=3)
    assert len(folds) == 3
    problem = elastica
    for p, beyond, eqs in folds:
        assert sum(e.index == 0 for e in eqs) >= 3
        first = land(problem, p.state, p.tangent, eqs, "psi", beyond)
        assert first.target is not None and eqs[first.target].index == 0
        e = first.energies
        assert np.all(np.diff(e) <= 1e-12 * (1 + np.abs(e[:-1]))), p.name
        assert first.energy_released > 1.0
        for change in (dict(push=PUSH / 2), dict(nodes=2 * NODES)):
            again = land(problem, p.state, p.tangent, eqs, "psi", beyond, **change)
            assert again.target == first.target, (p.name, change)


def test_the_damped_model_loses_energy_and_lands(arm, elastica):
    """The damped model's total energy (potential + kinetic) never increases; with strong
    damping it lands where the overdamped flow does."""
    p, beyond, eqs = _folds(arm[0], elastica, count=1)[0]
    problem = elastica
    over = land(problem, p.state, p.tangent, eqs, "psi", beyond)
    strong = land(problem, p.state, p.tangent, eqs, "psi", beyond, damping=50.0)
    assert strong.target == over.target
    e = strong.energies
    assert np.all(np.diff(e) <= 1e-9 * (1 + np.abs(e[:-1])))
    weak = land(problem, p.state, p.tangent, eqs, "psi", beyond, damping=8.0)
    assert weak.target is not None and eqs[weak.target].index == 0


def test_below_the_lowest_saddle_the_damped_well_is_decided(arm, elastica, monkeypatch):
    """The damped model stops once its total energy is below every saddle's (the well can no
    longer change) and the overdamped flow finishes: it lands where integrating on until
    the rod has settled does, and where it does with the integrator's tolerances / 100."""
    folds = _folds(arm[0], elastica)
    # the folds whose start lies above the lowest saddle: there the stop is a real shortcut
    p, beyond, eqs = next(f for f in folds if landing_module.lowest_saddle(
        *_flow_at(elastica, f)) < _start_energy(elastica, f))
    # the lowest saddle against the energy of the module's docstring on the shooting
    # equilibria, by quadrature on a fine grid (the discrete one is O(h^2) away)
    s = np.linspace(0.0, 1.0, 4001)
    q = dict(p.params)
    q["psi"] += beyond * landing_module.BEYOND

    def energy(eq):
        theta, kappa = eq.state(s)[0], eq.state(s)[1]
        density = kappa ** 2 / 2 + q["P"] * np.cos(theta - q["alpha"])
        return (np.sum((density[1:] + density[:-1]) / 2) * (s[1] - s[0])
                + q["eps"] * q["P"] * np.cos(q["psi"] + q["alpha"] - theta[-1]))
    lowest = min(energy(e) for e in eqs
                 if e.index > 0 and np.max(np.abs(e.state(s)[0] - p.state(s)[0])) > 0.2)
    assert landing_module.lowest_saddle(*_flow_at(elastica, (p, beyond, eqs))) == \
        pytest.approx(lowest, abs=1e-3 * (1 + abs(lowest)))
    first = land(elastica, p.state, p.tangent, eqs, "psi", beyond, damping=DAMPING)
    assert first.target is not None
    e = first.energies
    assert np.all(np.diff(e) <= 1e-6 * (1 + np.abs(e[:-1])))
    monkeypatch.setattr(landing_module, "lowest_saddle", lambda *args: -np.inf)
    settled = land(elastica, p.state, p.tangent, eqs, "psi", beyond, damping=DAMPING)
    assert settled.target == first.target
    assert len(settled.times) > len(first.times)
    monkeypatch.undo()
    monkeypatch.setattr(landing_module, "DAMPED_RTOL", landing_module.DAMPED_RTOL / 100)
    monkeypatch.setattr(landing_module, "DAMPED_ATOL", landing_module.DAMPED_ATOL / 100)
    tight = land(elastica, p.state, p.tangent, eqs, "psi", beyond, damping=DAMPING)
    assert tight.target == first.target


def _flow_at(problem, fold):
    """(flow, unstable equilibria's nodal values, the fold's) as `land` has them."""
    p, beyond, eqs = fold
    params = dict(p.params)
    params["psi"] += beyond * landing_module.BEYOND
    s = np.linspace(0.0, 1.0, NODES + 1)
    flow = problem.gradient_flow(params, s)
    return flow, [flow.to_u(e.state(s)) for e in eqs if e.index > 0], flow.to_u(p.state(s))


def _start_energy(problem, fold):
    flow, _, u_fold = _flow_at(problem, fold)
    return flow.energy(u_fold)


def test_the_damped_landings_of_mirrored_folds_are_mirrored(arm):
    """``damping=[c]`` lands from every fold ending a stable branch on a stable target of
    the fold, and mirrored folds (psi -> -psi) on mirrored equilibria (k -> -k)."""
    rows, snaps = arm[0].landings, arm[0].snaps
    assert len(rows) == len({(r["branch"], r["lp"]) for r in snaps}) >= 10
    for r in rows:
        assert r["landed"] == 1 and r["damping"] == DAMPING
        assert any(q["lp"] == r["lp"] and abs(q["k"] - r["k"]) < 1e-9 for q in snaps), r["lp"]
        assert any(abs(q["value"] + r["value"]) < 1e-6 and abs(q["k"] + r["k"]) < 1e-6
                   for q in rows), (r["lp"], r["value"], r["k"])


def test_the_damped_landings_are_the_same_whoever_computes_them(arm, elastica):
    """A default run shares the landings between its own process and its cluster's workers
    (here a stand-in worker thread, `helpers.WorkingBackground`): the damped model's rows,
    and the snap-back table's overdamped landings, are the same, in the same order, as
    computed one after the other."""
    from elastica_auto.analysis.landing import damping_sweep
    from elastica_auto.execution.run import Alongside
    from helpers import WorkingBackground
    branches = arm[0]
    folds = [p.name for p, _ in snap_lps(branches[0])][:2]
    serial = damping_sweep(elastica, branches, [20.0], folds)
    pool = Alongside(None, 1, lambda n, on: WorkingBackground(n, on))
    shared = damping_sweep(elastica, branches, [20.0], folds, mapper=pool.map)
    assert len(serial) == 2 and all(r["landed"] == 1 for r in serial)
    assert pool.background.tasks                          # the worker computed some
    for a, b in zip(serial, shared):
        assert a.keys() == b.keys()
        for k in a:
            assert a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]), (k, a[k], b[k])
    # and the overdamped landings of the snap-back table (the fixture's, one by one)
    from elastica_auto.analysis.snaps import snap_targets
    pool = Alongside(None, 1, lambda n, on: WorkingBackground(n, on))
    rows = snap_targets(elastica, branches[:1], landing=True, mapper=pool.map)
    assert pool.background.tasks
    cols = ("lp", "k", "landed", "energy_released", "transit_time")
    before = [tuple(r[c] for c in cols) for r in arm[0].snaps if r["branch"] == 1]
    assert len(rows) == len(before) > 5
    for got, want in zip((tuple(r[c] for c in cols) for r in rows), before):
        assert got[0] == want[0] and np.array_equal(got[1:], want[1:], equal_nan=True), \
            (got, want)


def test_the_damping_sweep_is_checked_saved_and_listed(arm, elastica, tmp_path, cli_exe):
    """Bad ``damping``/``damping_folds`` are errors naming the argument (a run file's name
    the key); a fold that ends no stable branch is a warning; the landings survive a save
    and ``snaps`` lists them."""
    import elastica_auto as ea
    from elastica_auto.core.errors import PlanError
    from elastica_auto.analysis.landing import damping_sweep
    from elastica_auto.storage.store import BranchFile
    from helpers import run_cli
    start = {"eps": 0.5, "P": P_HIGH}
    for kwargs, key in ((dict(damping=[1.0]), "damping"),          # without landing
                        (dict(landing=True, damping=[0.0]), "damping"),
                        (dict(landing=True, damping=[1.0], damping_folds=["S3"]),
                         "damping_folds"),
                        (dict(landing=True, damping_folds=["LP1"]), "damping_folds")):
        with pytest.raises(PlanError) as err:
            ea.continuation(elastica, start, "psi", **kwargs)
        assert err.value.key == key, kwargs
    toml = tmp_path / "bad.toml"
    toml.write_text('equation = "elastica_lever_arm"\nstart = "trivial"\n[continuation]\n'
                    'parameter = "psi"\nlanding = true\ndamping = [-1]\n')
    proc = run_cli(cli_exe, "run", toml, "--out", tmp_path)
    assert proc.returncode == 2 and "[continuation] damping" in proc.stderr, proc.stderr
    not_a_snap = next(p.name for b in arm[0] for p in b.folds
                      if p.name not in {r["lp"] for r in arm[0].snaps})
    warnings = []
    assert damping_sweep(elastica, arm[0], [DAMPING], [not_a_snap], warnings) == []
    assert warnings == [f"{not_a_snap}: not a fold ending a stable branch; no damping sweep"]
    kept = BranchFile(arm[1]).landings
    assert [(r["lp"], r["k"], r["target_m1"]) for r in kept] == [
        (r["lp"], pytest.approx(r["k"], abs=0), pytest.approx(r["target_m1"], abs=0))
        for r in arm[0].landings]
    proc = run_cli(cli_exe, "snaps", arm[1])
    lines = proc.stdout.splitlines()
    at = next(i for i, ln in enumerate(lines) if ln.startswith("damped model"))
    header, table = lines[at + 1].split(), [ln.split() for ln in lines[at + 2:]]
    assert len(table) == len(kept)
    for cols, r in zip(table, kept):
        assert cols[0] == r["lp"] and float(cols[4]) == DAMPING
        assert float(cols[header.index("m1")]) == pytest.approx(r["target_m1"], rel=1e-5)


def test_landing_is_asked_for_and_needs_the_hook(arm, elastica, tmp_path):
    """The landing columns come with ``landing`` and the hook: without either the table is
    as before; asking a module without the hook is an error naming the argument."""
    import elastica_auto as ea
    from elastica_auto.core.errors import PlanError
    from elastica_auto.model.problem import load_problem
    from elastica_auto.analysis.snaps import snap_targets
    from helpers import REPO
    source = (REPO / "tests" / "reference" / "elastica_lever_arm.py").read_text()
    (tmp_path / "no_flow.py").write_text(source.replace("def gradient_flow(",
                                                        "def _gradient_flow("))
    problem = load_problem(tmp_path / "no_flow.py")
    assert not problem.has_gradient_flow
    branches = arm[0][:1]
    rows = snap_targets(problem, branches, landing=True)
    assert rows and not any("landed" in r for r in rows)
    rows = snap_targets(elastica, branches)
    assert rows and not any("landed" in r for r in rows)
    with pytest.raises(PlanError) as err:
        ea.continuation(problem, {"P": P_HIGH}, "psi", landing=True)
    assert err.value.key == "landing"


def test_the_snaps_command_marks_the_landing(arm, cli_exe):
    """One row marked ``<-`` per fold, with its energy and time; the legend last."""
    from helpers import run_cli
    proc = run_cli(cli_exe, "snaps", arm[1])
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    rows = arm[0].snaps
    lines = lines[:lines.index("")] if "" in lines else lines   # the damped model's after
    assert len(lines) == 2 + len(rows)                 # the header, a row each, the legend
    marked = [ln.split() for ln in lines[1:-1] if ln.split()[-3] == "<-"]
    assert len(marked) == sum(r["landed"] for r in rows)
    landed = [r for r in rows if r["landed"] == 1]
    for cols, r in zip(marked, landed):
        assert cols[0] == r["lp"]
        assert float(cols[-2]) == pytest.approx(r["energy_released"], rel=1e-4)
    assert lines[-1].startswith("landed: ")
