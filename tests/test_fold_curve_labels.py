"""Cusps and branch points among the folds of fold curves, decided from the curve itself and
not from thresholds fitted to the elastica (issue 45 item 5): the same on a module whose
states are scaled by 1e3 and by 1e-3.

`CUSP`: the constant solutions of lam + mu u - u^3 = 0; the folds in lam lie on the curve
(lam, mu) = (-2 u^3, 3 u^2), whose fold in mu at u = 0 is a cusp (lam and mu both
stationary: lam ~ s^3, mu ~ s^2 along it). `ISOLA`: for mu > 0 the constant solutions form
the circle (u - 2 lam)^2 + (lam - 1)^2 = mu, whose folds in lam lie on the curve
mu = (lam - 1)^2, u = 2 lam; its fold in mu, at (lam, mu) = (1, 0) where the isola is born, is
no cusp: lam moves through it.
"""

from __future__ import annotations

import pytest

import elastica_auto as ea
from helpers import scaled_module

CUSP = '''\
"""u'' + lam + mu u - u^3 = 0, u'(0) = u'(1) = 0: constant solutions on the cusp surface."""
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u", "du")
PARAMETERS = [Parameter("lam", 0.0, r"\\lambda", "ode"), Parameter("mu", 1.0, r"\\mu", "ode")]


def rhs(s, y, p):
    u = y[0]
    return np.vstack((y[1], -(p["lam"] + p["mu"] * u - u ** 3)))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -(p["mu"] - 3 * y[0] ** 2)
    return jac


def rhs_dp(s, y, p, name):
    out = np.zeros_like(y)
    out[1] = -1.0 if name == "lam" else -y[0]
    return out


def bc(ya, yb, p):
    return np.array((ya[1], yb[1]))


def guess(s, p):
    roots = np.roots([-1.0, 0.0, p["mu"], p["lam"]])
    u = max(r.real for r in roots if abs(r.imag) < 1e-9)
    return np.vstack((np.full(len(s), u), np.zeros(len(s))))


ORDINATES = [Ordinate("u0", "$u$", lambda s, y, p: y[0, 0], None)]
'''

ISOLA = '''\
"""u'' + mu - (u - 2 lam)^2 - (lam - 1)^2 = 0, u'(0) = u'(1) = 0: for mu > 0 a circle of
constant solutions in (lam, u - 2 lam), born at mu = 0 (an isola)."""
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u", "du")
PARAMETERS = [Parameter("lam", 1.0, r"\\lambda", "ode"), Parameter("mu", 1.0, r"\\mu", "ode")]


def rhs(s, y, p):
    u, lam = y[0], p["lam"]
    return np.vstack((y[1], -(p["mu"] - (u - 2 * lam) ** 2 - (lam - 1) ** 2)))


def rhs_jac(s, y, p):
    jac = np.zeros((2, 2, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = 2 * (y[0] - 2 * p["lam"])
    return jac


def rhs_dp(s, y, p, name):
    out = np.zeros_like(y)
    u, lam = y[0], p["lam"]
    out[1] = -1.0 if name == "mu" else -(4 * (u - 2 * lam) - 2 * (lam - 1))
    return out


def bc(ya, yb, p):
    return np.array((ya[1], yb[1]))


def guess(s, p):
    u = 2 * p["lam"] + np.sqrt(max(p["mu"] - (p["lam"] - 1) ** 2, 0.0))
    return np.vstack((np.full(len(s), u), np.zeros(len(s))))


ORDINATES = [Ordinate("u0", "$u$", lambda s, y, p: y[0, 0], None)]
'''


def _fold_curve_labels(tmp_path, text, start, bounds, scale):
    """The CP/BP/LP labels (type, lam, mu) of the fold curves through the first fold of the
    one-parameter branch from ``start``, continued in mu both ways; steps and ds_min in the
    units of the scale."""
    path = tmp_path / "module.py"
    path.write_text(text)
    if scale != 1.0:
        path = scaled_module(path, scale, tmp_path)
    problem = ea.load_problem(str(path))
    unit = max(scale, 1.0)
    options = dict(ds=0.05 * unit, ds_max=0.2 * unit, ds_min=1e-6 * min(scale, 1.0) ** 2)
    one = ea.continuation(problem, start, "lam", bounds=bounds, directions="+", **options)
    curves = ea.continuation(problem, one.label("LP1"), ["lam", "mu"], bounds=(-0.5, 2),
                             directions="both", **options)
    return [(p.type, p.params["lam"], p.params["mu"]) for br in curves for p in br.points
            if p.type in ("LP", "CP", "BP")]


@pytest.mark.parametrize("scale", [1.0, 1e3, 1e-3])
def test_a_cusp_is_a_cusp_at_any_scale(tmp_path, scale):
    labels = _fold_curve_labels(tmp_path, CUSP, {"lam": -2.0, "mu": 1.0}, (-2, 2), scale)
    assert [t for t, _, _ in labels] == ["CP"]
    assert labels[0][1:] == pytest.approx((0.0, 0.0), abs=1e-9)


@pytest.mark.parametrize("scale", [1.0, 1e3, 1e-3])
def test_an_isola_s_birth_is_no_cusp_at_any_scale(tmp_path, scale):
    """The isola's birth: LP. Before, a cusp was a fold of the fold curve whose lam component
    was below 1e-3 of the whole tangent: with the states 1e3 times larger the tangent is
    mostly u's (u = 2 lam moves with lam), and the component was 5e-4 of it: a CP."""
    labels = _fold_curve_labels(tmp_path, ISOLA, {"lam": 1.0, "mu": 1.0}, (-2, 4), scale)
    assert [t for t, _, _ in labels] == ["LP"]
    assert labels[0][1:] == pytest.approx((1.0, 0.0), abs=1e-9)


def test_the_diagram_and_the_map_group_a_file_s_branches_alike(tmp_path):
    """Issue 45 item 5: the diagram's panels (1e-9 relative to 1 + |value|) and the stability
    maps' planes (1e-12 relative or absolute) grouped the branches of one file by different
    rules, so values 1e-11 apart were one panel and two maps. Both use
    `core.values.same_value` now: ISOLA's branches at mu = 1, 1 + 1e-11 and 1.5 are two groups
    for both."""
    from elastica_auto.analysis.maps import plane_groups
    from elastica_auto.plots.diagram import panel_groups
    path = tmp_path / "isola.py"
    path.write_text(ISOLA)
    problem = ea.load_problem(str(path))
    run = ea.continuation(problem, {"lam": 1.0}, "lam", bounds=(-2, 4), directions="+",
                          params={"mu": [1.0, 1.0 + 1e-11, 1.5]})
    ea.save(run, tmp_path / "isola.h5")
    bf = ea.BranchFile(tmp_path / "isola.h5")
    _, panels = panel_groups(bf, "lam")
    planes = plane_groups(bf.branches, bf.parameters, "lam", "u0")
    groups = [sorted(b.number for b in members) for _, members in panels]
    assert groups == [sorted(b.number for b in members) for _, members in planes]
    assert groups == [[1, 2], [3]]


@pytest.mark.parametrize("a, b, period, same", [
    (1e-12, 2e-12, None, False), (1e12, 1e12 + 1, None, True), (0.0, -0.0, None, True),
    (0.0, 1e-300, None, False), (0.1, 0.1 + 2 * 3.141592653589793, 2 * 3.141592653589793, True),
    (2.4674011002723395, 9.869604401089358 / 4, None, True), (0.25, 0.25000001, None, False),
])
def test_one_rule_for_the_same_value(a, b, period, same):
    from elastica_auto.core.values import same_value
    assert same_value(a, b, period) is same


def test_a_fold_stop_on_a_fold_curve_ends_at_its_cusp_as_the_walk_passes_it(tmp_path):
    """Issue 48: a fold curve's cusp is an event of the walk (``codim2.FoldCurvePoint``, the
    last placed kind of each step), not a relabelling of the finished branch. The CUSP curve
    from the fold at u < 0 has one fold in mu, the cusp at the closed form's (lam, mu) =
    (0, 0); ``stop = ["LP1"]`` ends the branch there: the fold stop counts the fold, the
    placed kind after it labels it CP, and the branch ends with the label of its last point
    (before, a relabelling after the walk left ``end`` LP on a branch ending in a CP). The
    other direction meets no fold and reaches the bound."""
    path = tmp_path / "module.py"
    path.write_text(CUSP)
    problem = ea.load_problem(str(path))
    options = dict(ds=0.05, ds_max=0.2, ds_min=1e-6)
    one = ea.continuation(problem, {"lam": -2.0, "mu": 1.0}, "lam", bounds=(-2, 2),
                          directions="+", **options)
    curves = ea.continuation(problem, one.label("LP1"), ["lam", "mu"], bounds=(-0.5, 2),
                             directions="both", stop=["LP1"], **options)
    stopped = [br for br in curves if br.message.startswith("stopped at fold")]
    assert len(stopped) == 1 and len(curves) == 2
    last = stopped[0].points[-1]
    assert (stopped[0].end, last.type) == ("CP", "CP")
    assert (last.params["lam"], last.params["mu"]) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert stopped[0].message == "stopped at fold 1 (stop = LP1)"
    other = next(br for br in curves if br is not stopped[0])
    assert other.end == "EP" and not [p for p in other.points if p.type in ("LP", "CP")]
