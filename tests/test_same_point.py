"""Branch points are merged for switching only where they are the same point: within the
accuracy of their location, with the same kernel (issue 45 item 4); the switching test and
the merge decided alike on a module whose states are scaled by 1e3 and by 1e-3 (item 5).

`TWO_PITCHFORKS` has closed-form branches: u = v = 0 for every lam, with branch points at
lam = 0 (kernel u = const) and lam = 1 (kernel v = const); the pure modes u^2 = lam (v = 0)
and v^2 = lam - 1 (u = 0); on the pure u-mode a branch point at lam = 1 (u = +-1), where
the mixed mode u^2 = lam, v^2 = lam - 1 is born.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import elastica_auto as ea
from helpers import scaled_module

TWO_PITCHFORKS = '''\
"""u'' + lam u - u^3 = 0, v'' + (lam - 1) v - v^3 = 0, u' = v' = 0 at both ends."""
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("u", "du", "v", "dv")
PARAMETERS = [Parameter("lam", 0.0, r"\\lambda", "ode")]


def rhs(s, y, p):
    u, du, v, dv = y
    lam = p["lam"]
    return np.vstack((du, -lam * u + u ** 3, dv, -(lam - 1) * v + v ** 3))


def rhs_jac(s, y, p):
    u, du, v, dv = y
    lam = p["lam"]
    jac = np.zeros((4, 4, y.shape[1]))
    jac[0, 1] = jac[2, 3] = 1.0
    jac[1, 0] = -lam + 3 * u ** 2
    jac[3, 2] = -(lam - 1) + 3 * v ** 2
    return jac


def rhs_dp(s, y, p, name):
    out = np.zeros_like(y)
    out[1], out[3] = -y[0], -y[2]
    return out


def bc(ya, yb, p):
    return np.array((ya[1], yb[1], ya[3], yb[3]))


def exact_start(s, p):
    return np.zeros((4, len(s)))


ORDINATES = [Ordinate("u0", "$u(0)$", lambda s, y, p: y[0, 0], "lam"),
             Ordinate("v0", "$v(0)$", lambda s, y, p: y[2, 0], None)]
'''


def _problem(tmp_path, scale=1.0):
    path = tmp_path / "two_pitchforks.py"
    path.write_text(TWO_PITCHFORKS)
    if scale != 1.0:
        path = scaled_module(path, scale, tmp_path)
    return ea.load_problem(str(path))


def _run(problem, depth, scale=1.0):
    """u = v = 0 from lam = -0.5 in steps of 0.7 and then 1.1 (so that each branch point's
    neighbouring steps are longer than the unit between them), switched at the first two
    BPs of each branch, to ``depth`` levels; steps and ds_min in the units of the scale (a
    step is a distance in the states; the pitchforks of the 1e-3 module turn within 1e-6)."""
    return ea.continuation(problem, {"lam": -0.5}, "lam", bounds=(-1, 3), switch=2,
                           switch_depth=depth, ds=0.7, ds_max=min(1.1 * max(scale, 1.0), 1e3),
                           growth=2, ds_min=1e-6 * min(scale, 1.0) ** 2, jobs=1)


def _assert_on(br, u2, v2, atol=1e-8):
    """The branch solves u^2 = u2(lam), v^2 = v2(lam) (closed forms) past its start."""
    lam, u, v = br.columns["lam"][1:], br.columns["u0"][1:], br.columns["v0"][1:]
    np.testing.assert_allclose(u ** 2, u2(lam), atol=atol)
    np.testing.assert_allclose(v ** 2, v2(lam), atol=atol)


def test_two_branch_points_one_unit_apart_are_both_switched_at(tmp_path):
    """Issue 45 item 4: the branch points at lam = 0 and 1 of u = v = 0, both located exactly,
    lie within the larger step next to them (1.1): they were merged as one point, and the
    switch at lam = 1 (the v-mode) was dropped without a word. Now both are switched at, and
    the branches are the closed forms."""
    run = _run(_problem(tmp_path), depth=1)
    bps = [p.params["lam"] for p in run[0].points if p.type == "BP"]
    np.testing.assert_allclose(bps, [0.0, 1.0], atol=1e-12)
    assert max(p.ds for p in run[0].points) > 1.0
    assert [br.start for br in run] == ["trivial"] + ["switch at BP1"] * 2 + \
        ["switch at BP2"] * 2 and not run.warnings
    for br in run[1:3]:
        _assert_on(br, lambda lam: lam, lambda lam: 0 * lam)
    for br in run[3:5]:
        _assert_on(br, lambda lam: 0 * lam, lambda lam: lam - 1)


@pytest.mark.parametrize("scale", [1.0, 1e3, 1e-3])
def test_the_switch_decisions_do_not_depend_on_the_states_scale(tmp_path, scale):
    """Issue 45 item 5's check: with the states multiplied by 1, 1e3 or 1e-3 the same branch
    points are found (lam = 0 and 1 exactly), every switch direction passes the kernel test
    (switching.KERNEL_RTOL, relative to the linearisation's terms), and the same points are
    switched at (SAME_POINT_RELATIVE, SAME_KERNEL): at the second
    level, the pure u-mode's branch points at lam = 1 (u = +-1), at the parameter value of
    u = v = 0's second one but not the same point, give the four mixed branches. (The states
    are solved to the corrector's accuracy, 1e-8 absolute where they are small: u = y / scale
    to 1e-8 / scale.)"""
    run = _run(_problem(tmp_path, scale), depth=2, scale=scale)
    atol = 1e-8 / min(scale, 1.0)
    np.testing.assert_allclose([p.params["lam"] for p in run[0].points if p.type == "BP"],
                               [0.0, 1.0], atol=1e-12)
    assert not run.warnings
    assert [br.start for br in run] == ["trivial"] + [
        f"switch at BP{k}" for k in (1, 1, 2, 2, 3, 3, 4, 4)]
    second = [p for br in run[1:3] for p in br.points if p.type == "BP"]
    np.testing.assert_allclose([p.params["lam"] for p in second], [1.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(sorted(p.ordinates["u0"] for p in second), [-1.0, 1.0],
                               atol=atol)
    for br in run[5:]:
        _assert_on(br, lambda lam: lam, lambda lam: lam - 1, 10 * atol)


def test_a_branch_point_near_another_with_another_kernel_is_not_the_same(tmp_path):
    """The kernel decides where the places cannot: a branch point known only to its step
    (labelled at a turning point, TURNING) whose step reaches another branch point is the
    same point only if its tangent lies in that one's kernel. Here u = v = 0's BP at lam = 1,
    given a step of 2 and the v-mode's direction as its tangent, against the BP at lam = 0
    (kernel: lam and u): within reach, another kernel, two points; with the u-mode's
    direction instead, one."""
    from elastica_auto.branches.switching import switch_direction
    from elastica_auto.execution import plan as plans, run as runs
    problem = _problem(tmp_path)
    plan = plans.make_plan(problem, {"lam": -0.5}, "lam", plans.Request(bounds=(-1, 3)),
                           {"ds": 0.7, "ds_max": 1.1, "growth": 2})
    trivial = ea.continuation(problem, {"lam": -0.5}, "lam", bounds=(-1, 3), ds=0.7,
                              ds_max=1.1, growth=2)[0]
    first, second = runs.branch_points(plan, trivial)
    assert not runs.same_point(plan, first, second)      # both located: 1 apart
    v_mode = switch_direction(problem, second.point.state, second.point.tangent, "lam",
                              plan.options)
    u_mode = switch_direction(problem, first.point.state, first.point.tangent, "lam",
                              plan.options)
    for direction, same in ((v_mode, False), (u_mode, True)):
        turning = runs.Site(dataclasses.replace(second.point, note=runs.TURNING,
                                                 tangent=direction), 2.0, False)
        assert runs.same_point(plan, first, turning) is same
