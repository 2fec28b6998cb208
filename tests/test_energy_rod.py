"""The spatial rod derived from its energy (equations/kirchhoff_lever_arm.py; issue 47 items 1,
2 and 6; docs/energy.md, "Rotation coordinates") against what is independent of its
derivation:

* the hand-written module it replaced (tests/reference/kirchhoff_lever_arm.py): rhs, rhs_jac,
  bc, bc_jac, the parameter derivatives and the second variation (its parts, the isotropic
  rod's zero mode) at random states with |q| != 1 and random parameters, to 1e-12; the
  shipped run rotating_arm_3d (b2 = 1 and 2: the isotropic rod's symmetric branch points
  included) on both: the same points and labels, every fold and branch point to 1e-9,
  index, index_rule, index_direct, index_in and index_out equal at every point;
* the finite-difference Hessian of an independently discretised rod (tests/rod_hessian.py)
  along random rotation fields, at random frame fields that are no equilibria, with |q| != 1:
  the derived second variation in spatial turns is the second derivative of the energy;
* the slope of the derived energy E along branches: each distinguished ordinate, the clamp's
  reactions (-dE/dtheta0 = m(0).e_z, -dE/dphi0 = m(0).d3(0)) with their sign, and the
  intrinsic curvatures' dE/du_i, which the hand-written module did not have.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto as ea
import reference.kirchhoff_lever_arm as ref
from elastica_auto.execution import runfile
from elastica_auto.model.second_variation import as_second_variation
from helpers import REFERENCE, REPO, run_plan
from rod_hessian import hessian
from test_energy import _assert_slope, assert_same_system

K3 = "kirchhoff_lever_arm"
#: The derived bc's rows (the clamp q(0) - q_c, the tip's natural condition, r(0)) in the
#: hand-written module's order (r(0), q(0) - q_c, m(1) - a x F).
ROWS = [7, 8, 9, 0, 1, 2, 3, 4, 5, 6]
RANGES = {"P": (-20, 20), "eps": (-1, 1), "psi": (-7, 7), "alpha": (-7, 7), "theta0": (-7, 7),
          "chi": (-7, 7), "beta": (-7, 7), "phi0": (-7, 7), "b2": (0.5, 3), "c": (0.3, 2),
          "u1": (-2, 2), "u2": (-2, 2), "u3": (-2, 2)}


@pytest.fixture(scope="module")
def rods():
    return ea.load_problem(K3), ea.load_problem(REFERENCE / "kirchhoff_lever_arm.py")


def test_the_derived_rod_is_the_hand_written_one(rods):
    """Issue 47 items 1, 2, 6: the states, where each parameter enters and the paper's
    distinguished ordinates' names; rhs, rhs_jac, bc, bc_jac, their parameter derivatives
    (the reference's by central differences, to 1e-8) and the second variation (A = R K R^T,
    C = -[m]_x / 2, B, E1, w(0) = 0, the parts) at random states, |q| != 1 (uniform in
    [-2, 2]), and random parameters."""
    derived, hand = rods
    assert derived.states == hand.states
    assert {k: q.enters for k, q in derived.parameters.items()} == \
        {k: q.enters for k, q in hand.parameters.items()}
    assert {k: (q.period, q.period_flip) for k, q in derived.parameters.items()} == \
        {k: (q.period, q.period_flip) for k, q in hand.parameters.items()}
    mine = {o.parameter: o.name for o in derived.ordinates.values() if o.parameter}
    theirs = {o.parameter: o.name for o in hand.ordinates.values() if o.parameter}
    assert {k: v for k, v in mine.items() if k in theirs} == theirs
    assert set(mine) - set(theirs) == {"u1", "u2", "u3"}         # dE/du_i: new
    assert_same_system(derived, hand, RANGES, ROWS, np.random.default_rng(11), trials=25)


def test_the_isotropic_rod_s_zero_mode(rods):
    """At symmetric parameters (b2 = 1, u1 = u2 = 0, the load along the clamp's axis, the arm
    along the tip tangent) the module's symmetry hook makes the derived second variation
    carry the zero mode w = e - d3 (L2-normalised, as the hand-written one), at random
    states; at a state the group fixes (the straight rod: w = 0) neither has it."""
    derived, hand = rods
    rng = np.random.default_rng(12)
    for trial in range(8):
        p = {**derived.defaults(), "P": rng.uniform(-10, 10), "eps": rng.uniform(-1, 1),
             "psi": math.pi * rng.integers(-2, 3), "theta0": 0.3, "alpha": 0.3,
             "c": rng.uniform(0.3, 2), "u3": rng.uniform(-2, 2), "phi0": rng.uniform(-3, 3)}
        s = np.sort(np.r_[0.0, rng.uniform(0, 1, 11), 1.0])
        y = rng.uniform(-2, 2, (10, len(s)))
        mine = as_second_variation(derived.second_variation(s, y, p), "derived")
        theirs = as_second_variation(hand.second_variation(s, y, p), "reference")
        (a,), (b,) = mine.constraints, theirs.constraints
        assert a.kernel and b.kernel
        np.testing.assert_allclose(a.g, b.g, atol=1e-12)
    straight = derived.exact_start(s, p)
    assert not as_second_variation(derived.second_variation(s, straight, p), "d").constraints
    assert not as_second_variation(hand.second_variation(s, straight, p), "h").constraints


def _run(name, equation, out):
    """The shipped run ``name`` with ``equation`` (its restarts from the same folder)."""
    out.mkdir(exist_ok=True)
    text = (REPO / "runs" / f"{name}.toml").read_text()
    path = out / f"{name}.toml"
    path.write_text(text.replace('equation = "kirchhoff_lever_arm"', f'equation = "{equation}"'))
    return run_plan(runfile.load(path), out).file


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """rotating_arm_3d on the derived module and on the reference (about 15 s each; its
    restarts rotating_base_3d and rotating_load_3d are compared the same way in the
    measurements of docs/energy.md, not here: a minute more)."""
    return {key: _run("rotating_arm_3d", equation, tmp_path_factory.mktemp(key))
            for key, equation in (("derived", K3),
                                  ("reference", REFERENCE / "kirchhoff_lever_arm.py"))}


INDICES = ("index", "index_rule", "index_direct", "index_in", "index_out")


def test_rotating_arm_3d_on_the_derived_rod_is_the_reference_s(runs):
    """The same branches, points, types and labels; every fold and branch point to 1e-9 in
    every parameter (the other points to 1e-7: rounding differences in the corrector move
    them along the branch, 3e-9 seen); the five index columns equal at every point, the
    isotropic rod's branch points placed at its symmetric points (b2 = 1) included; the
    ordinates both modules compute alike to 1e-7 (Eb2 and Ec: the derived by Simpson's rule
    on the Hermite cubics, the reference by the trapezoidal rule, to 1e-4)."""
    mine, theirs = runs["derived"], runs["reference"]
    assert sorted(mine.labels) == sorted(theirs.labels)
    assert len(mine.branches) == len(theirs.branches) == 16
    params = list(theirs.parameters)
    folds = symmetric = 0
    for a, b in zip(mine.branches, theirs.branches):
        ca, cb = a.columns, b.columns
        assert list(ca["type"]) == list(cb["type"]) and list(ca["label"]) == list(cb["label"])
        for key in INDICES:
            np.testing.assert_array_equal(ca[key], cb[key], err_msg=f"{key} of {a.number}")
        types = np.asarray(ca["type"])
        special = np.isin(types, ("LP", "BP"))
        for key in params:
            x, y = np.asarray(ca[key]), np.asarray(cb[key])
            np.testing.assert_allclose(x[special], y[special], rtol=0, atol=1e-9, err_msg=key)
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-7, err_msg=key)
        for key in ("gamma", "beps", "m1", "mA", "m0", "mchi", "mB", "mphi", "z1", "mz1"):
            np.testing.assert_allclose(ca[key], cb[key], rtol=0, atol=1e-7, err_msg=key)
        for key in ("Eb2", "Ec"):
            np.testing.assert_allclose(ca[key], cb[key], rtol=1e-4, atol=1e-8, err_msg=key)
        folds += int(special.sum())
        symmetric += int(np.sum((types == "BP") & (np.asarray(ca["b2"]) == 1.0)))
    assert folds >= 200 and symmetric >= 30


def test_a_located_branch_points_count_is_its_states_not_its_module_s(rods):
    """rotating_base_3d (b2 = 2), BP72 as the derived and the reference module located it
    (tests/data/rotating_base_3d_bp72.npz): the same theta0 to the last bit, on meshes that
    the runs' rounding made differ (the states 9e-9 apart). Its direct count was -1 in the
    derived run and 4 in the reference's (docs/kirchhoff.md). At each state the two modules'
    second variations give the same count, and the form shifted by -+1e-6 times the L2
    product has index 4 and 5 at both states with both modules: one eigenvalue is zero to
    the count's threshold, its sign at the located point decided by the mesh's rounding
    (-1 says so); away from it the counts agree."""
    from elastica_auto.core.solution import State
    from elastica_auto.numerics.stability import count_form
    data = np.load(REPO / "tests" / "data" / "rotating_base_3d_bp72.npz")
    names = [str(x) for x in data["names"]]
    for which in ("derived", "reference"):
        s, y = data[f"s_{which}"], data[f"y_{which}"]
        p = dict(zip(names, data[f"p_{which}"].tolist()))
        counts = []
        for problem in rods:
            state = State(s, y, problem.rhs(s, y, p), p)
            counts.append([count_form(lambda pts: problem.second_variation(pts, state(pts), p),
                                      s, shift=shift).index for shift in (0.0, -1e-6, 1e-6)])
        assert counts[0] == counts[1], which
        assert counts[0][1:] == [4, 5] and counts[0][0] in (-1, 4, 5), which


# ---- the second variation against an independent discretisation ---------------------------

def _frame_field(rng):
    """A smooth random frame field (not an equilibrium) as the rod's states on s: q(s) = a
    quadratic in s normalised, times 1 + 0.3 sin(2 s) (|q| != 1), the curvature u =
    2 Im(conj(q) (x) q') of the unit quaternion (q' by complex step in s), the moment
    m = R K (u - u_hat) that the Legendre map gives it, r = 0."""
    c = rng.normal(size=(3, 4))

    def unit(s):
        q = c[0][:, None] + c[1][:, None] * s + c[2][:, None] * s ** 2
        return q / np.sqrt(np.sum(q * q, axis=0))

    def state(s, p):
        s = np.asarray(s, dtype=float)
        q = unit(s)
        dq = unit(s + 1e-30j).imag / 1e-30
        u = 2 * ref.qmul(np.vstack((q[0], -q[1:])), dq)[1:]
        rot = ref.rotation(q)
        mb = ref.stiffness(p)[:, None] * (u - np.array((p["u1"], p["u2"], p["u3"]))[:, None])
        m = np.einsum("ijm,jm->im", rot, mb)
        return np.vstack((np.zeros((3, len(s))), q * (1 + 0.3 * np.sin(2 * s)), m))
    return state


def test_the_second_variation_is_the_hessian_of_a_discretised_rod(rods):
    """d2E[w] of the derived second variation, int (w'.A w' + 2 w'.C w + w.B w) ds +
    w(1).E1 w(1) by Gauss-Legendre quadrature, for random rotation fields w (w(0) = 0) at
    random frame fields and parameters, against w.H w with H the Hessian by central
    differences of the rod discretised by tests/rod_hessian.py (frames at s_j, curvatures
    log(R_j^T R_(j+1)) / h, midpoint rules; nothing of the derivation), extrapolated from
    N = 100 and 200 intervals (second order): they agree to a tenth of the discretisation's
    change, and to 1e-4 relative."""
    derived, _ = rods
    rng = np.random.default_rng(13)
    x, weights = np.polynomial.legendre.leggauss(60)
    gauss, weights = 0.5 * (x + 1), 0.5 * weights
    for trial in range(4):
        p = {k: rng.uniform(*v) for k, v in RANGES.items()}
        p["P"] = rng.uniform(-5, 5)
        state = _frame_field(rng)
        a, b, c = rng.normal(size=(3, 3))

        def w(s):
            return np.outer(a, s) + np.outer(b, s ** 2) + np.outer(c, np.sin(3 * s))

        def dw(s):
            return np.outer(a, np.ones_like(s)) + np.outer(b, 2 * s) + \
                np.outer(c, 3 * np.cos(3 * s))
        form = as_second_variation(derived.second_variation(gauss, state(gauss, p), p), "d")
        ends = as_second_variation(derived.second_variation(np.linspace(0, 1, 5),
                                                            state(np.linspace(0, 1, 5), p), p),
                                   "d")
        wg, dg = w(gauss), dw(gauss)
        integrand = (np.einsum("im,mij,jm->m", dg, form.A, dg)
                     + 2 * np.einsum("im,mij,jm->m", dg, form.C, wg)
                     + np.einsum("im,mij,jm->m", wg, form.B, wg))
        w1 = w(np.array([1.0]))[:, 0]
        exact = float(weights @ integrand + w1 @ ends.E1 @ w1)
        discrete = []
        for n in (100, 200):
            st = type("State", (), {"params": p, "__call__": lambda self, s: state(s, p)})()
            grid = np.linspace(0, 1, n + 1)[1:]
            wn = w(grid).T.ravel()
            discrete.append(float(wn @ hessian(ref, st, n) @ wn))
        change = abs(discrete[1] - discrete[0])
        extrapolated = discrete[1] + (discrete[1] - discrete[0]) / 3
        assert abs(exact - extrapolated) <= 0.1 * change + 1e-7 * (1 + abs(exact))
        assert abs(exact - discrete[1]) <= 1e-4 * (1 + abs(exact))
    assert form.fixed0.shape[1] == 3                      # w(0) = 0, the clamp


# ---- the derived ordinates along branches -------------------------------------------------

@pytest.fixture(scope="module")
def tilted(rods):
    """A buckled, non-planar state: the rotating arm (b2 = 2) at psi = 0.5, its arm tilted
    by chi = 0.3, the load by beta = 0.1, intrinsic curvatures u = (0.2, -0.1, 0.3)."""
    derived, _ = rods
    start = {"P": math.pi ** 2 / 4, "eps": 0.25, "b2": 2.0}
    (br,) = ea.continuation(derived, start, "psi", bounds=(-1, 0.5), directions="+")
    label = br.label(br.points[-1].name)
    for name, value in (("chi", 0.3), ("beta", 0.1), ("u1", 0.2), ("u2", -0.1), ("u3", 0.3)):
        (br,) = ea.continuation(derived, label, name, bounds=sorted((value, -value)),
                                directions="+" if value > 0 else "-", mirror=False)
        label = br.label(br.points[-1].name)
    assert abs(label.state.y[2, -1]) > 1e-3
    return label


@pytest.mark.parametrize("name, ordinate, sign", [
    ("psi", "m1", 1), ("eps", "beps", 1), ("P", "gamma", 1), ("alpha", "mA", 1),
    ("chi", "mchi", 1), ("beta", "mB", 1), ("theta0", "m0", -1), ("phi0", "mphi", -1),
    ("b2", "Eb2", 1), ("c", "Ec", 1), ("u1", "dE_du1", 1), ("u3", "dE_du3", 1)])
def test_the_slope_of_the_rod_s_energy_is_its_ordinate(rods, tilted, name, ordinate, sign):
    """Along a branch in each parameter from the tilted state, the second-order difference of
    the derived energy E is the distinguished ordinate, and minus it (the reaction) for the
    clamp's angles theta0 and phi0 (a clamp turned by w changes E by -m(0).w)."""
    derived, _ = rods
    (br,) = ea.continuation(derived, tilted, name, directions="+", bounds=(-50, 50), ds=0.01,
                            ds_max=0.01, max_points=30, mirror=False)
    xi = np.array([p.params[name] for p in br.points])
    e = np.array([p.ordinates["E"] for p in br.points])
    _assert_slope(xi, e, sign * np.array([p.ordinates[ordinate] for p in br.points]))


# ---- a rod written from its energy alone --------------------------------------------------

def test_the_spatial_column_buckles_at_euler_s_loads_about_both_axes():
    """examples/spatial_column.py, the docs' tutorial: a clamped-free column in space, bending
    stiffnesses 1 and b2 = 2, written as its energy only. Continued in P from the straight
    column its branch points are the clamped-free Euler loads B ((2 n - 1) pi / 2)^2 for
    B = 1 and 2 (a closed form, not the derivation), in order, to 1e-8 relative, and the
    index counts the loads below P at every other point."""
    from helpers import EXAMPLES
    problem = ea.load_problem(EXAMPLES / "spatial_column.py")
    assert problem.states == ("R_q0", "R_q1", "R_q2", "R_q3", "m_R1", "m_R2", "m_R3", "x", "y",
                              "z")
    (br,) = ea.continuation(problem, {"P": 0.0, "b2": 2.0}, "P", bounds=(-1, 25),
                            directions="+", ds=0.2, ds_max=1.0)
    loads = sorted(b * ((2 * n - 1) * math.pi / 2) ** 2 for b in (1.0, 2.0) for n in (1, 2))
    loads = [x for x in loads if x < 25]
    bps = [p.params["P"] for p in br.points if p.type == "BP"]
    np.testing.assert_allclose(bps, loads, rtol=1e-8)
    for p in br.points:
        if p.type != "BP":
            assert p.index == p.index_direct == sum(x < p.params["P"] for x in loads)
