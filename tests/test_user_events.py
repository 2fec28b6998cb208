"""Events a run asks for (``events = [...]``): user points where an ordinate takes a value
(UZ), extrema of an ordinate (XT), each checked against an independent answer; and the
entries' validation.

The Bratu problem ``u'' + lam exp(u) = 0``, ``u(0) = u(1) = 0`` has the closed form

    u(x) = 2 ln( cosh(theta/4) / cosh(theta (x - 1/2) / 2) ),   lam = theta^2 / (2 cosh^2(theta/4)),

(``u'' = -(theta^2/2) sech^2(theta (x - 1/2)/2)`` and ``lam exp(u) = lam cosh^2(theta/4)
sech^2(...)``, equal and opposite exactly when ``theta^2 / 2 = lam cosh^2(theta/4)``), so
that ``u(1/2) = 2 ln cosh(theta/4)``: the point where ``u(1/2) = c`` has
``theta = 4 acosh(exp(c/2))`` and that ``lam``, one point for each c (u(1/2) grows along the
branch from 0, through the fold at theta = 4.80, to infinity).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.branches import kinds, registry
from elastica_auto.core import labels
from helpers import run_cli

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def bratu_lam(c: float) -> float:
    """lam of the Bratu solution with u(1/2) = c (the closed form above)."""
    theta = 4.0 * math.acosh(math.exp(c / 2.0))
    return theta ** 2 / (2.0 * math.cosh(theta / 4.0) ** 2)


def test_a_user_event_on_an_ordinate_is_where_the_closed_form_puts_it():
    """events = ["u_half = c"] on the Bratu branch: a UZ point at each c, on both sides of
    the fold (c = 1 below it, c = 2 and 3 beyond), at the closed form's lam to the points'
    accuracy (tol = 1e-5: about 1e-7 relative), with u(1/2) = c to the corrector's; the
    branch goes on past each (it ends at its stop, far beyond)."""
    problem = ea.load_problem(str(EXAMPLES / "bratu.py"))
    values = (1.0, 2.0, 3.0)
    (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), directions="+",
                            events=[f"u_half = {c:g}" for c in values],
                            stop=["dE_dlam < -50"])
    uz = [p for p in br.points if p.type == "UZ"]
    assert [p.note for p in uz] == [f"u_half = {c:g} (rising)" for c in values]
    for p, c in zip(uz, values):
        assert p.ordinates["u_half"] == pytest.approx(c, abs=1e-9)
        assert p.params["lam"] == pytest.approx(bratu_lam(c), rel=1e-6)
    assert br.end == "EP" and "dE_dlam" in br.message
    assert br.points.index(uz[-1]) < len(br.points) - 5
    # the fold lies between c = 1 and c = 2: u(1/2) at the fold is 2 ln cosh(4.7987 / 4)
    (lp,) = [p for p in br.points if p.type == "LP"]
    assert uz[0].arclength < lp.arclength < uz[1].arclength


def test_a_user_event_on_the_continued_parameter_and_falling_through_a_value():
    """On the straight rod continued in P (eps = 0.5), beta = P cos(psi + alpha - theta(1))
    = P exactly: an event on the ordinate beta and one on P itself land at the same P, the
    value asked for; continued downwards, beta falls through it."""
    problem = ea.load_problem("elastica_lever_arm")
    (br,) = ea.continuation(problem, {"eps": 0.5, "P": 1.0}, "P", bounds=(-3, 3),
                            directions="-", events=["beta = -0.5", "P = -0.5"])
    uz = [p for p in br.points if p.type == "UZ"]
    assert len(uz) == 2
    for p in uz:
        assert p.params["P"] == pytest.approx(-0.5, abs=1e-9)
        assert p.ordinates["beta"] == pytest.approx(-0.5, abs=1e-9)
    assert sorted(p.note for p in uz) == ["P = -0.5 (falling)", "beta = -0.5 (falling)"]


def test_an_extremum_of_an_ordinate_against_a_dense_sampling():
    """events = ["extremum m1"] on the rotating arm's psi-branch (eps = 0.5,
    P = 9 pi^2 / 4): from the straight rod round the fold at psi = 0.93 and back, m1 has a
    maximum near psi = -1.07, labelled XT with the note "maximum of m1". Against the same
    branch sampled every 0.01 of arclength without events: no sample exceeds it (beyond
    the points' accuracy, 1e-7), and the vertex of the parabola through the three largest
    samples agrees, in m1 to 1e-6 (a parabola's vertex through samples h = 0.01 apart is
    off by about h^3 m1''' ) and in psi to 1e-5 (about h^2)."""
    problem = ea.load_problem("elastica_lever_arm")
    params = {"eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    (br,) = ea.continuation(problem, params, "psi", bounds=(-1.3, 2), directions="+",
                            ds_max=0.3, events=["extremum m1"])
    (xt,) = [p for p in br.points if p.type == "XT"]
    assert xt.note == "maximum of m1"
    (dense,) = ea.continuation(problem, params, "psi", bounds=(-1.3, 2), directions="+",
                               ds=0.01, ds_max=0.01, growth=1.0)
    assert not any(p.type == "XT" for p in dense.points)
    m1 = np.array([p.ordinates["m1"] for p in dense.points])
    s = np.array([p.arclength for p in dense.points])
    psi = np.array([p.params["psi"] for p in dense.points])
    assert m1.max() <= xt.ordinates["m1"] + 1e-7
    i = int(np.argmax(m1))
    near = slice(i - 1, i + 2)
    c = np.polyfit(s[near] - s[i], m1[near], 2)
    top = -c[1] / (2 * c[0])
    assert xt.ordinates["m1"] == pytest.approx(np.polyval(c, top), abs=1e-6)
    assert xt.params["psi"] == pytest.approx(
        np.polyval(np.polyfit(s[near] - s[i], psi[near], 2), top), abs=1e-5)


def test_events_are_not_mirrored_and_are_kept_with_the_settings():
    """A run with events computes both directions (an ordinate's value need not be its
    mirror image's), and its settings name the events (a --resume continues the same run
    only); a run without keeps the settings it had."""
    from elastica_auto.branches.mirror import symmetric_course
    from elastica_auto.execution.plan import Request, make_plan
    problem = ea.load_problem("elastica_lever_arm")
    plan = make_plan(problem, {"eps": 0.5, "P": 1.0}, "psi",
                     Request(directions="both", bounds=(-1, 1), events=("m1 = 0.1",)))
    assert plan.settings()["events"] == ["m1 = 0.1"]
    assert not symmetric_course(plan.course)
    plain = make_plan(problem, {"eps": 0.5, "P": 1.0}, "psi",
                      Request(directions="both", bounds=(-1, 1)))
    assert "events" not in plain.settings() and symmetric_course(plain.course)


@pytest.mark.parametrize("entry, words", [
    ('"m1 > 1"', "[continuation] events: 'm1 > 1': expected \"NAME = VALUE\""),
    ('"x1 = 0.5"', "'x1' is not an ordinate, a free parameter or the continued parameter"),
    ('"m1 = twelve"', "[continuation] events: 'm1 = twelve': VALUE"),
    ('"extremum psi2"', "'psi2' is not an ordinate or a free parameter"),
    ("3", "[continuation] events: expected \"NAME = VALUE\""),
])
def test_a_bad_event_entry_is_one_line_and_exit_2(cli_exe, tmp_path, entry, words):
    path = tmp_path / "events.toml"
    path.write_text('equation = "elastica_lever_arm"\n[continuation]\nparameter = "psi"\n'
                    f"events = [{entry}]\n")
    out = run_cli(cli_exe, "run", path, "--out", tmp_path / "o")
    assert out.returncode == 2 and "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("elastica-auto: error: ")
    assert words in lines[0], out.stderr


def test_events_not_a_list_is_refused(cli_exe, tmp_path):
    path = tmp_path / "events.toml"
    path.write_text('equation = "elastica_lever_arm"\n[continuation]\nparameter = "psi"\n'
                    'events = "m1 = 1"\n')
    out = run_cli(cli_exe, "run", path, "--out", tmp_path / "o")
    assert out.returncode == 2
    assert out.stderr.strip() == (f"elastica-auto: error: {path}: [continuation] events: "
                                  "expected a list [\"m0 = 0\"], got \"m1 = 1\"")


def test_the_api_refuses_a_bad_event_and_events_on_fold_curves():
    problem = ea.load_problem("elastica_lever_arm")
    with pytest.raises(ea.PlanError, match="expected a list"):
        ea.continuation(problem, {"eps": 0.5}, "psi", events="m1 = 1")
    with pytest.raises(ea.PlanError, match="'nope' is not an ordinate"):
        ea.continuation(problem, {"eps": 0.5}, "psi", events=["extremum nope"])


def test_events_on_a_free_parameter_against_the_closed_form():
    """examples/bratu_mean.py, the Bratu problem continued in its mean M with lam solved for
    (free): along the family ``u = -2 ln(cosh(z (x - 1/2)) / cosh(z/2))``,
    ``lam = 2 z^2 / cosh^2(z/2)`` rises, then falls. Its maximum (XT, "extremum lam") is the
    Bratu fold: ``w tanh w = 1`` with w = z/2 (d lam / dz = 0), lam_c = 3.5138..., where
    ``u'(0) = 2 z tanh(z/2) = 4`` exactly; "lam = 2" is met twice, rising and falling, at the
    two roots z of ``2 z^2 / cosh^2(z/2) = 2``. M at each is the closed form's mean, by
    quadrature. Tolerances: the points' accuracy (tol = 1e-5: about 1e-7 relative); M at the
    extremum, where lam is stationary, is as accurate (its error is the derivative's error
    over the curvature, not a square root)."""
    from scipy.integrate import quad
    from scipy.optimize import brentq

    def mean(z):
        return quad(lambda x: -2 * math.log(math.cosh(z * (x - 0.5)) / math.cosh(z / 2)),
                    0, 1, epsabs=1e-12, epsrel=1e-12)[0]

    problem = ea.load_problem(str(EXAMPLES / "bratu_mean.py"))
    (br,) = ea.continuation(problem, {"M": 0.0}, "M", bounds=(-1, 3), directions="+",
                            events=["extremum lam", "lam = 2"], max_points=200)
    labelled = [p for p in br.points if p.type in ("UZ", "XT")]
    assert [(p.type, p.note) for p in labelled] == [
        ("UZ", "lam = 2 (rising)"), ("XT", "maximum of lam"), ("UZ", "lam = 2 (falling)")]
    w = brentq(lambda w: w * math.tanh(w) - 1, 0.5, 2.0, xtol=1e-15)
    top = labelled[1]
    assert top.params["lam"] == pytest.approx(8 * w ** 2 / math.cosh(w) ** 2, rel=1e-7)
    assert top.params["M"] == pytest.approx(mean(2 * w), abs=1e-6)
    assert top.ordinates["du0"] == pytest.approx(4.0, rel=1e-7)
    for p, (lo, hi) in zip((labelled[0], labelled[2]), ((0.01, 2 * w), (2 * w, 20.0))):
        z = brentq(lambda z: 2 * z * z / math.cosh(z / 2) ** 2 - 2, lo, hi, xtol=1e-15)
        assert p.params["lam"] == pytest.approx(2.0, abs=1e-9)
        assert p.params["M"] == pytest.approx(mean(z), abs=1e-7)


class ToyFold(kinds.Event):
    """A turn kind written in a test module: LP where the tangent's parameter component
    changes sign, located by the events' generic locator (`Event.find`: Brent's method along
    the secant on that component) instead of the fold system."""

    label = labels.LP

    def test(self, walk, sol):
        return sol.tangent.lam

    def note(self, walk, sol, rising):
        return "toy fold"

    def crosses(self, walk, scan):
        step = scan.step
        return (not scan.skip and scan.on[labels.LP]
                and step.a.tangent.lam * step.b.tangent.lam < 0)

    def detect(self, walk, scan):
        if scan.crossed[labels.LP]:
            scan.found.extend(self.find(walk, scan.step))


def test_a_turn_kind_registered_from_a_test_module_is_driven_by_the_stepper(monkeypatch):
    """A kind of turn is its class and its place in `registry.DETECTION`, nothing in the
    stepper: the shipped fold replaced there by `ToyFold` (above), the Bratu branch's one
    fold is the toy's LP, at the closed form's fold: lam = theta^2 / (2 cosh^2(theta/4)) is
    stationary where ``theta tanh(theta/4) = 4``, and u(1/2) = 2 ln cosh(theta/4) there.
    Tolerances: the points' accuracy (tol = 1e-5: about 1e-7 relative), in lam and in
    u(1/2) alike: the locator places the point where the tangent's component vanishes, so
    that u(1/2) is not read off a stationary lam."""
    from scipy.optimize import brentq
    turns = tuple(ToyFold() if e is registry.FOLD else e for e in registry.DETECTION)
    assert turns != registry.DETECTION
    monkeypatch.setattr(registry, "DETECTION", turns)
    problem = ea.load_problem(str(EXAMPLES / "bratu.py"))
    (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), directions="+",
                            max_points=60)
    (lp,) = [p for p in br.points if p.type == labels.LP]
    assert lp.note == "toy fold"
    theta = brentq(lambda t: t * math.tanh(t / 4) - 4, 3.0, 6.0, xtol=1e-15)
    assert lp.params["lam"] == pytest.approx(theta ** 2 / (2 * math.cosh(theta / 4) ** 2),
                                             rel=1e-7)
    assert lp.ordinates["u_half"] == pytest.approx(2 * math.log(math.cosh(theta / 4)),
                                                   abs=1e-6)


class ToyOrdinateValue(kinds.Event):
    """A placed kind written in a test module: UZ where the ordinate u_half takes ``value``,
    placed by the default `Event.place` (its `Event.find`: Brent's method along the secant on
    the test function ``u_half - value``); with ``ends``, EP there instead, the branch ending
    (`Placement.end_at`: the points past it dropped)."""

    def __init__(self, value, ends=False):
        self.value, self.ends = value, ends
        self.label, self.action = (labels.EP, kinds.END) if ends else (labels.UZ, kinds.CONTINUE)

    def test(self, walk, sol):
        return kinds.quantity(walk.problem, "u_half", sol.state) - self.value

    def note(self, walk, sol, rising):
        return f"toy u_half = {self.value:g}"

    def place(self, walk, placement):
        hits = self.find(walk, placement.step)
        if not self.ends:
            placement.points.extend(hits)
            return
        for hit in hits:
            hit.message = f"toy stop at u_half = {self.value:g}"
            placement.end_at(self, hit)


def test_a_placed_kind_registered_from_a_test_module_is_driven_by_the_stepper(monkeypatch):
    """A placed kind is its class and its place in `registry.PLACEMENT`, nothing in the
    stepper: two toy kinds (above) appended there, a UZ where u(1/2) = 2 (past the fold) and
    an EP where u(1/2) = 3, on the Bratu branch: each where the closed form puts it (u(1/2)
    = c at lam = theta^2 / (2 cosh^2(theta/4)), theta = 4 acosh(exp(c/2))), to the points'
    accuracy (tol = 1e-5: about 1e-7 relative) in lam and the corrector's in u(1/2); the
    branch ends at the EP, whose message is the toy's."""
    toys = (ToyOrdinateValue(2.0), ToyOrdinateValue(3.0, ends=True))
    monkeypatch.setattr(registry, "PLACEMENT", registry.PLACEMENT + toys)
    problem = ea.load_problem(str(EXAMPLES / "bratu.py"))
    (br,) = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), directions="+",
                            max_points=200)
    (uz,) = [p for p in br.points if p.type == labels.UZ]
    end = br.points[-1]
    assert uz.note == "toy u_half = 2" and end.type == labels.EP
    assert br.end == labels.EP and br.message == "toy stop at u_half = 3"
    for p, c in ((uz, 2.0), (end, 3.0)):
        assert p.ordinates["u_half"] == pytest.approx(c, abs=1e-9)
        assert p.params["lam"] == pytest.approx(bratu_lam(c), rel=1e-6)
    (lp,) = [p for p in br.points if p.type == labels.LP]
    assert lp.arclength < uz.arclength < end.arclength


def test_an_extremum_at_a_fold_is_the_fold():
    """Along equilibria dE/dpsi = m1 (the energy's derivative in the load's angle is its
    conjugate moment), so dE/ds = m1 dpsi/ds vanishes at every fold: "extremum E" on the
    lever arm's psi-branch (eps = 0.25, P = pi^2/4) is the fold itself. It adds no point: the
    branch's labels, folds and indices are those of the run without events (a second,
    independent run), the fold's note says it is also E's maximum, and no point disagrees
    with the fold rule; the extremum of m1 (at psi = 0.166, not at a fold) is still its own
    XT, where the run asking for it alone puts it."""
    problem = ea.load_problem("elastica_lever_arm")
    params = {"eps": 0.25, "P": math.pi ** 2 / 4}

    def run(events):
        return ea.continuation(problem, params, "psi", bounds=(-math.pi, math.pi),
                               events=events)

    plain, alone = run([]), run(["extremum m1"])
    both = run(["extremum E", "extremum m1"])
    for p0, p1, p2 in zip(plain, alone, both):
        labelled = [(p.type, p.index) for p in p1.points if p.type != "XT"]
        assert labelled == [(p.type, p.index) for p in p0.points]
        assert [(p.type, p.index) for p in p2.points] == [(p.type, p.index) for p in p1.points]
        assert not p2.disagreements
        (lp,) = p2.folds
        assert lp.note == "also the maximum of E"
        xt1 = [(p.note, p.ordinates["m1"]) for p in p1.points if p.type == "XT"]
        assert len(xt1) == 1 and "of m1" in xt1[0][0]
        assert [(p.note, p.ordinates["m1"]) for p in p2.points if p.type == "XT"] == xt1


@pytest.mark.parametrize("uz", [{"uz": [0.5]},
                                {"uz": [0.5 - 2 * math.pi], "uz_period": 2 * math.pi}])
def test_an_event_on_the_continued_parameter_at_a_uz_value_is_one_point(uz):
    """events = ["psi = 0.5"] with uz = [0.5] (or a translate of 0.5 by uz_period) ask for
    the same points: each crossing of psi = 0.5 is labelled once, UZ at 0.5, as uz alone
    labels it. The crossings are counted independently, as the sign changes of psi - 0.5
    between the consecutive points of the run without labels."""
    problem = ea.load_problem("elastica_lever_arm")
    params = {"eps": 0.25, "P": math.pi ** 2 / 4}

    def run(**kw):
        return ea.continuation(problem, params, "psi", bounds=(-math.pi, math.pi), **kw)

    plain, alone, both = run(), run(**uz), run(events=["psi = 0.5"], **uz)
    for p0, p1, p2 in zip(plain, alone, both):
        psi = np.array([p.params["psi"] for p in p0.points]) - 0.5
        crossings = int(np.sum(psi[:-1] * psi[1:] < 0))
        uz2 = [p for p in p2.points if p.type == "UZ"]
        assert crossings >= 1 and len(uz2) == crossings
        assert all(p.params["psi"] == pytest.approx(0.5, abs=1e-9) for p in uz2)
        assert [(p.type, p.params["psi"]) for p in p2.points] == \
            [(p.type, p.params["psi"]) for p in p1.points]
