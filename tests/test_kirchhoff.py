"""The spatial Kirchhoff rod with a lever arm (equations/kirchhoff_lever_arm.py) against
oracles that do not use its own derivation (docs/kirchhoff.md, "Checks"):

* the planar module: with chi = beta = phi0 = 0 the 3D branches are the planar ones (angle,
  tip moment, centreline, folds), the out-of-plane components vanish, and the e_z block of the
  3D second variation is the planar module's form, with the same index;
* exact symmetries: a rigid rotation about the load line (the clamp turned by phi0 with the
  load along its axis), 2 pi periods of psi, alpha, theta0, chi, beta and phi0 (q -> -q for
  the clamp's angles), the mirror images z -> -z and x -> -x of states with every angle and
  intrinsic curvature away from zero, and of whole continuations through folds;
* |q| = 1 along every branch;
* the index against an independent count: the Hessian, by finite differences, of the energy of
  a discretised rod (rigid frames at the nodes, curvature from the relative rotations), at the
  continuation's equilibria (tests/rod_hessian.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.numerics import stability
from elastica_auto.model.problem import SecondVariation, load_problem
import jacobi

K3 = "kirchhoff_lever_arm"
PSI_UZ = (-0.5, 0.3, 0.6)
#: eps = 0.25, P = pi^2/4: the rotating arm; b2 = 2 so that no buckled state has the
#: rotational zero mode of the isotropic rod (issue 20, item 4).
#: |q| is conserved by the ODE exactly but not by the 4th-order Lobatto IIIA collocation: its
#: drift is a discretisation error, of the order of the continuation's error tolerance (1e-5)
#: times the small size of q's fourth derivative; seen: 1.5e-10.
QNORM_TOL = 1e-8
BASE = {"P": math.pi ** 2 / 4, "eps": 0.25, "b2": 2.0}


@pytest.fixture(scope="module")
def modules():
    """The planar and the spatial rod as shipped (derived from their energies), and the
    hand-written spatial rod (tests/reference) for the checks that stand apart from the
    derivation (its helpers, complex-step Jacobians, shooting)."""
    import reference.kirchhoff_lever_arm as mod
    return load_problem("elastica_lever_arm"), load_problem(K3), mod


@pytest.fixture(scope="module")
def rotating(modules):
    planar, rod, _ = modules
    kw = dict(bounds=(-1.0, 1.0), directions="both", uz=PSI_UZ, max_points=200)
    return (ea.continuation(planar, {"P": BASE["P"], "eps": BASE["eps"]}, "psi", **kw),
            ea.continuation(rod, BASE, "psi", **kw))


def labelled(branches, kind):
    return [(br, p) for br in branches for p in br.points if p.type == kind]


def theta_of(mod, y):
    """The tangent angle from the vertical, from d3 = (-sin theta, cos theta, 0)."""
    d3 = mod.rotation(y[3:7])[:, 2]
    return np.unwrap(np.arctan2(-d3[0], d3[1]))


def test_planar_branches_are_the_planar_module_s(modules, rotating):
    _, _, mod = modules
    planar, rod = rotating
    uz2, uz3 = labelled(planar, "UZ"), labelled(rod, "UZ")
    assert len(uz2) == len(uz3) >= 4
    grid = np.linspace(0, 1, 41)
    worst = 0.0
    for (b2, p2), (b3, p3) in zip(uz2, uz3):
        assert p2.params["psi"] == pytest.approx(p3.params["psi"], abs=1e-12)
        y2, y3 = b2.label(p2.name).state(grid), b3.label(p3.name).state(grid)
        gaps = (theta_of(mod, y3) - y2[0], y3[9] - y2[1], y3[0] - y2[2], y3[1] - y2[3])
        worst = max(worst, *(np.max(np.abs(g)) for g in gaps))
        assert np.max(np.abs(y3[[2, 7, 8]])) < 1e-10        # z, m_x, m_y: out of the plane
        half = 0.5 * y2[0]                                   # q = q_z(theta) (x) Q_REF
        q_planar = mod.qmul(np.vstack((np.cos(half), 0 * half, 0 * half, np.sin(half))),
                            mod.Q_REF[:, None])
        worst = max(worst, np.max(np.abs(y3[3:7] - q_planar)))
        assert p3.ordinates["m1"] == pytest.approx(p2.ordinates["m1"], abs=1e-7)
        assert p3.ordinates["mz1"] == pytest.approx(p2.ordinates["m1"], abs=1e-7)
        for name in ("gamma", "mA", "m0"):
            assert p3.ordinates[name] == pytest.approx(p2.ordinates[name], abs=1e-7)
        assert p3.ordinates["beps"] == pytest.approx(p2.ordinates["beta"], abs=1e-7)
        assert p3.ordinates["index_in"] == p2.index >= 0
    print(f"planar embedding: largest difference {worst:.2e}")
    assert worst < 1e-7, worst
    folds2 = sorted(p.params["psi"] for _, p in labelled(planar, "LP"))
    folds3 = sorted(p.params["psi"] for _, p in labelled(rod, "LP"))
    assert len(folds2) == len(folds3) >= 1
    # the split columns: in-plane plus out-of-plane is the index at every planar point
    for br in rod:
        for p in br.points:
            if p.type not in ("LP", "BP"):
                assert p.ordinates["index_in"] + p.ordinates["index_out"] == p.index >= 0
    print(f"folds {folds3}: largest difference {np.max(np.abs(np.subtract(folds2, folds3))):.2e}")
    assert np.max(np.abs(np.subtract(folds2, folds3))) < 1e-6


def in_plane(form: SecondVariation) -> SecondVariation:
    """The e_z block of a 3D form (components (x, y, z) of omega)."""
    return SecondVariation(form.A[:, 2:, 2:].transpose(1, 2, 0),
                           form.B[:, 2:, 2:].transpose(1, 2, 0),
                           form.C[:, 2:, 2:].transpose(1, 2, 0),
                           E1=form.E1[2:, 2:], fixed0=[0])


def test_in_plane_block_is_the_planar_second_variation(modules, rotating):
    planar_problem, rod_problem, mod = modules
    planar, rod = rotating
    compared = 0
    for (b2, p2), (b3, p3) in zip(labelled(planar, "UZ"), labelled(rod, "UZ")):
        st2, st3 = b2.label(p2.name).state, b3.label(p3.name).state
        pts = np.linspace(0, 1, 33)
        form = mod.second_variation(pts, st3(pts), st3.params)
        a, b, c = jacobi.scalar_form(planar_problem.second_variation(pts, st2(pts),
                                                                    st2.params))
        # decoupled: no coefficient couples e_z to the plane's directions
        for m in (form.A, form.B, form.C):
            assert np.max(np.abs(m[:, 2, :2])) < 1e-10 and np.max(np.abs(m[:, :2, 2])) < 1e-10
        assert np.max(np.abs(form.A[:, 2, 2] - a)) < 1e-10
        assert np.max(np.abs(form.C[:, 2, 2])) < 1e-12
        assert np.max(np.abs(form.B[:, 2, 2] - b)) < 1e-6
        assert form.E1[2, 2] == pytest.approx(c, abs=1e-6)

        def evaluate(x, st=st3):
            return in_plane(mod.second_variation(x, st(x), st.params))
        n_in = stability.count_form(evaluate, st3.s).index
        assert n_in == stability.index(planar_problem, st2) >= 0
        # the whole 3D index is the in-plane one plus the out-of-plane block's
        assert stability.index(rod_problem, st3) >= n_in
        compared += 1
    assert compared >= 4


def rotate_state(mod, y, qrot):
    """The state turned rigidly by the unit quaternion ``qrot``."""
    rot = mod.rotation(qrot)
    return np.vstack((rot @ y[0:3], mod.qmul(qrot[:, None], y[3:7]), rot @ y[7:10]))


def test_clamp_twist_about_the_load_line_rotates_the_solution(modules):
    """The load along the clamp axis (alpha = theta0 = beta = 0): turning the clamp by phi0
    about its axis d3(0) = e_y turns the whole solution rigidly about the load line (the
    energy is invariant under rotations about F's line through the clamp)."""
    _, rod, mod = modules
    start = ea.continuation(rod, {**BASE, "b2": 1.0}, "psi", bounds=(-1.0, 0.7), uz=[0.6],
                            max_points=60)
    (br,) = ea.continuation(rod, start.label("UZ1"), "phi0", bounds=(-0.1, 2.5),
                            uz=[1.0, 2.0], max_points=80)
    y0 = start.label("UZ1").state
    grid = np.linspace(0, 1, 41)
    got = [p for p in br.points if p.type == "UZ"]
    assert len(got) == 2
    for p in got:
        phi = p.params["phi0"]
        want = rotate_state(mod, y0(grid), mod.qaxis((0, 1, 0), phi))
        assert np.max(np.abs(br.label(p.name).state(grid) - want)) < 1e-7
        assert p.ordinates["z1"] == pytest.approx(-math.sin(phi) * y0.y[0, -1], abs=1e-8)
    for p in br.points:
        assert p.ordinates["qnorm"] < QNORM_TOL


def test_periods_of_psi_and_theta0(modules, rotating):
    """psi enters only through sin and cos; theta0 + 2 pi turns the clamp's quaternion into
    -q(0), and -q is a solution with the same frame (the ODE is linear in q, R(-q) = R(q))."""
    _, rod_problem, mod = modules
    _, rod = rotating
    for br, p in labelled(rod, "UZ"):
        st = br.label(p.name).state
        ya, yb = st.y[:, 0], st.y[:, -1]
        for k in (1, -2):
            shifted = {**st.params, "psi": st.params["psi"] + 2 * math.pi * k}
            assert np.max(np.abs(mod.bc(ya, yb, shifted) - mod.bc(ya, yb, st.params))) < 1e-12
            assert stability.index(rod_problem, st.__class__(st.s, st.y, st.yp, shifted)) \
                == stability.index(rod_problem, st)
        flipped = st.y.copy()
        flipped[3:7] *= -1
        turned = {**st.params, "theta0": st.params["theta0"] + 2 * math.pi}
        assert np.max(np.abs(mod.bc(flipped[:, 0], flipped[:, -1], turned))) < 1e-9
        rhs = mod.rhs(st.s, flipped, turned)
        assert np.max(np.abs(rhs[3:7] + mod.rhs(st.s, st.y, st.params)[3:7])) < 1e-12
        assert np.allclose(np.delete(rhs, np.s_[3:7], 0),
                           np.delete(mod.rhs(st.s, st.y, st.params), np.s_[3:7], 0),
                           atol=1e-12)


def test_quaternion_norm_stays_one(rotating):
    _, rod = rotating
    for br in rod:
        assert br.end == "EP", br.message
        assert max(p.ordinates["qnorm"] for p in br.points) < QNORM_TOL


def test_isotropic_rod_arm_tilt_is_a_rotation_about_the_load_line(modules, rotating):
    """b2 = 1, u_hat = 0, load along the clamp axis: R -> Q R Rb3(-chi), Q the rotation by chi
    about e_y = d3(0), keeps the clamp (Q R_c = R_c Rb3(chi)), the bending energy (isotropic)
    and the load potential, and R Rb3(-chi) a_b(chi) = R a_b(0): so the chi family is the planar
    state turned rigidly by Q (r, m), with the same index and dE/dchi = 0."""
    _, rod, mod = modules
    start = ea.continuation(rod, {**BASE, "b2": 1.0}, "psi", bounds=(-1.0, 0.7), uz=[0.6],
                            max_points=60)
    (br,) = ea.continuation(rod, start.label("UZ1"), "chi", bounds=(-0.1, 2.0), uz=[1.5],
                            max_points=60)
    y0 = start.label("UZ1").state
    grid = np.linspace(0, 1, 41)
    (p,) = [p for p in br.points if p.type == "UZ"]
    st = br.label(p.name).state
    rot = mod.rotation(mod.qaxis((0, 1, 0), p.params["chi"]))
    y1 = st(grid)
    assert np.max(np.abs(y1[0:3] - rot @ y0(grid)[0:3])) < 1e-7
    assert np.max(np.abs(y1[7:10] - rot @ y0(grid)[7:10])) < 1e-7
    assert stability.index(rod, st) == stability.index(rod, y0) == 2
    assert max(abs(q.ordinates["mchi"]) for q in br.points) < 1e-8   # dE/dchi = 0


# ---- the index against the finite-difference Hessian of a discretised rod -------------------

#: Intervals of the discrete rod; its eigenvalues' error is estimated from n/2 (about 0.01-0.02
#: for the lowest eight at n = 120 on these states).
N_FD = 120
#: A state is compared only if its smallest |eigenvalue| exceeds this many error estimates.
SAFETY = 5.0


def fd_compare(mod, problem, state):
    """The engine against the discrete rod (tests/rod_hessian.py) at ``state``: (engine's
    index, discrete count), or None where the discrete count is not decisive (the smallest
    |eigenvalue| within SAFETY error estimates of zero, the estimate a third of the change of
    the lowest eight eigenvalues from N_FD / 2 to N_FD intervals: second order); and the
    numbers of eigenvalues below shifts mid-gap between the discrete rod's lowest eigenvalues
    (below 25, gaps of at least 2 SAFETY errors), (engine, discrete). The engine counts the
    form less shift times the L2 product; the discrete rod's eigenvalues are taken with the
    same (lumped) mass. The spectral counts see what the index alone may not: the sign of C,
    for instance, moves eigenvalues without changing the index of these states."""
    from rod_hessian import eigenvalues
    fine, coarse = eigenvalues(mod, state, N_FD), eigenvalues(mod, state, N_FD // 2)
    err = np.max(np.abs(fine[:8] - coarse[:8])) / 3
    index = None
    if np.min(np.abs(fine[:8])) > SAFETY * err:
        index = (stability.index(problem, state), int(np.sum(fine < 0)))
    low = fine[fine < 25]
    gaps = [(x + y) / 2 for x, y in zip(low[:-1], low[1:]) if y - x > 2 * SAFETY * err]
    evaluate = stability.form_on_state(problem, state)
    engine = [stability.count_form(evaluate, state.s, shift=mu).index for mu in gaps]
    return index, (engine, [int(np.sum(fine < mu)) for mu in gaps])


def conjugate_index(mod, state):
    """The index of the module's form at ``state`` by the Morse index theorem: focal points of
    the 3 x 3 Jacobi system (tests/form_reference.py), the coefficients from the state's
    interpolant."""
    from form_reference import Form, conjugate_count

    def field(name):
        return lambda s: getattr(mod.second_variation(s, state(s), state.params), name)
    end = mod.second_variation(state.s, state.y, state.params).E1
    return conjugate_count(Form(k=3, A=field("A"), B=field("B"), C=field("C"), E1=end,
                                G0=np.eye(3))).index


def straight(mod, problem, **params):
    from elastica_auto.core.solution import State
    p = {par.name: par.default for par in mod.PARAMETERS}
    p.update(params)
    s = np.linspace(0, 1, 41)
    return State.from_values(problem, s, mod.exact_start(s, p), p)


@pytest.mark.parametrize("b2, P, want", [(1.0, 1.0, 0), (1.0, 5.0, 2), (1.0, 20.0, 4),
                                         (2.0, 2.5, 1), (2.0, 20.0, 3)])
def test_straight_rod_index_against_the_discrete_hessian(modules, b2, P, want):
    """The straight rod (eps = 0.25): critical loads B_i k^2 with eps k tan k = 1 (1.599192,
    15.485497, ...) for B_1 = 1 (in-plane) and B_2 = b2 (out of plane)."""
    _, rod, mod = modules
    index, (engine, discrete) = fd_compare(mod, rod, straight(mod, rod, P=P, b2=b2))
    assert index == (want, want)
    assert len(engine) >= 3 and engine == discrete


def test_buckled_index_against_the_discrete_hessian(modules, rotating):
    """Buckled states of the rotating arm (b2 = 2) on both sides of the folds, and a
    non-planar one (the arm tilted by chi = 1.5)."""
    _, rod, mod = modules
    _, branches = rotating
    uz = [br.label(p.name).state for br, p in labelled(branches, "UZ")]
    states = [uz[0], uz[2], uz[5], uz[-1]]       # psi = 0.3, 0.6 past the fold, -0.5, 0.6
    tilted = ea.continuation(rod, branches.label("UZ2"), "chi", bounds=(-0.1, 2.0), uz=[1.5],
                             max_points=60)
    states.append(tilted.label("UZ1").state)
    assert abs(states[-1].y[2, -1]) > 0.1                 # out of the plane
    results = [fd_compare(mod, rod, st) for st in states]
    compared = [index for index, _ in results if index is not None]
    print("engine vs discrete Hessian:", results)
    assert len(compared) >= 4 and {r[0] for r in compared} == {0, 1}
    for engine, discrete in compared:
        assert engine == discrete
    for _, (engine, discrete) in results:
        assert len(engine) >= 3 and engine == discrete
    for st in states:
        assert conjugate_index(mod, st) == stability.index(rod, st)


@pytest.fixture(scope="module")
def generic(modules):
    """A state with every parameter away from its planar value: intrinsic curvature in all
    three directions, the load out of the plane, a turned clamp, b2 and c not 1, the arm not
    along the tangent: from the twisted straight rod, u1, beta, psi, u2 continued in turn."""
    _, rod, _ = modules
    label = {"P": 1.0, "eps": 0.3, "b2": 1.5, "c": 0.9, "u3": 0.5, "theta0": 0.2,
             "alpha": 0.2}
    for name, value in (("u1", 1.0), ("beta", 0.4), ("psi", 0.8), ("u2", 0.7)):
        br = ea.continuation(rod, label, name, bounds=(-0.1, value + 0.1), uz=[value],
                             max_points=60)
        label = br.label("UZ1")
    return label.state


def test_conserved_quantities(modules, generic):
    """n = F (by construction), m + r x F, m.F, the Hamiltonian (1/2) m_b.K^-1 m_b +
    m_b.u_hat + F.d3 and |q| are constant along the rod (docs/kirchhoff.md, "Model")."""
    _, rod, mod = modules
    y, p = generic.y, generic.params
    assert abs(y[2, -1]) > 0.05 and abs(y[7, 0]) > 0.05        # not planar
    f = mod.load(p)
    rot = mod.rotation(y[3:7])
    mb = np.einsum("ji...,j...->i...", rot, y[7:10])
    u_hat = np.array((p["u1"], p["u2"], p["u3"]))
    ham = 0.5 * np.sum(mb * mb / mod.stiffness(p)[:, None], 0) + u_hat @ mb + f @ rot[:, 2]
    assert np.ptp(ham) < 1e-7
    assert np.max(np.ptp(y[7:10] + np.cross(y[0:3], f, axis=0), axis=1)) < 1e-12
    assert np.ptp(f @ y[7:10]) < 1e-12
    assert np.max(np.abs(np.linalg.norm(y[3:7], axis=0) - 1)) < QNORM_TOL
    ordinates = rod.ordinate_values(generic.s, y, p)
    assert ordinates["index_in"] == ordinates["index_out"] == -1      # not planar


def test_generic_state_against_the_discrete_hessian(modules, generic):
    _, rod, mod = modules
    index, (engine, discrete) = fd_compare(mod, rod, generic)
    assert index == (0, 0)
    assert len(engine) >= 3 and engine == discrete
    assert conjugate_index(mod, generic) == 0


# ---- mirror images and periods at states away from the plane ---------------------------------
#
# A reflection M of space maps the rod to a rod: r -> M r, the frame R -> M R N with N the
# reflection of the body frame that keeps M R N a rotation, the moment (a pseudovector) m ->
# -M m, the load F -> M F, the arm a -> M a. Written as rotations, M = -Rot(a, pi) and N =
# -Rot(b, pi), so q -> q_a (x) q (x) q_b (q_a, q_b the unit quaternions of a, b): linear in q.
# The parameters move with the reflection (docs/kirchhoff.md, "Mirror images"):
#
# * z -> -z (out of the plane): M = diag(1, 1, -1), N = diag(-1, 1, 1) (the body axis d1,
#   e_z at planar states): chi, beta, phi0, u2 and u3 change sign;
# * x -> -x (the planar mirror): M = diag(-1, 1, 1), N = diag(1, -1, 1): psi, alpha, theta0,
#   chi, phi0, u1 and u3 change sign.
#
# The energy is the same at mirror images, so the ordinate dE/dxi of a parameter xi changes
# sign exactly where xi does; of the others, z1 = r(1).e_z changes sign under z -> -z, mz1 =
# m(1).e_z under x -> -x, and the twist and m(1).d3(1) under both.
MIRRORS = {
    "z -> -z": ((1.0, 1.0, -1.0), (0, 0, 0, 1), (0, 1, 0, 0),
                ("chi", "beta", "phi0", "u2", "u3"), ("z1", "twist", "m3")),
    "x -> -x": ((-1.0, 1.0, 1.0), (0, 1, 0, 0), (0, 0, 1, 0),
                ("psi", "alpha", "theta0", "chi", "phi0", "u1", "u3"), ("mz1", "twist", "m3")),
}


def mirrored(mod, state, mirror):
    """The mirror image of ``state`` and its parameters (MIRRORS), with the image of the
    right-hand side at ``state`` as its slopes; q's sign is the clamp's."""
    from elastica_auto.core.solution import State
    m, left, right, flipped, _ = MIRRORS[mirror]
    m = np.array(m)[:, None]
    left, right = (np.array(x, float)[:, None] for x in (left, right))

    def image(y):
        return np.vstack((m * y[0:3], mod.qmul(mod.qmul(left, y[3:7]), right), -m * y[7:10]))

    params = {k: -v if k in flipped else v for k, v in state.params.items()}
    y, yp = image(state.y), image(mod.rhs(state.s, state.y, state.params))
    if np.dot(y[3:7, 0], mod.clamp_quaternion(params)) < 0:      # -q: the same frame
        y[3:7], yp[3:7] = -y[3:7], -yp[3:7]
    return State(state.s, y, yp, params)


def expected_signs(rod, mirror) -> dict:
    """Ordinate -> its sign at the mirror image (the comment above MIRRORS)."""
    *_, flipped, others = MIRRORS[mirror]
    return {name: -1 if (o.parameter in flipped or name in others) else 1
            for name, o in rod.ordinates.items()}


@pytest.fixture(scope="module")
def tilted(modules, generic):
    """The generic state with the arm's plane tilted and the clamp twisted too: every angle
    and every intrinsic curvature away from zero."""
    from elastica_auto.branches.branch import StoredLabel
    _, rod, _ = modules
    label = StoredLabel("UZ", 1, 0, generic, None, None)
    for name, value in (("chi", 0.5), ("phi0", 0.3)):
        (br,) = ea.continuation(rod, label, name, bounds=(-0.1, value + 0.1), uz=[value],
                                max_points=60)
        label = br.label("UZ1")
    return label.state


def spectrum_counts(rod, state, shifts=(2.0, 10.0, 30.0, 60.0)):
    """The numbers of eigenvalues of the second variation below each shift."""
    evaluate = stability.form_on_state(rod, state)
    return [stability.count_form(evaluate, state.s, shift=mu).index for mu in shifts]


@pytest.mark.parametrize("mirror", list(MIRRORS))
def test_the_mirror_image_solves_the_mirrored_problem(modules, tilted, mirror):
    """Exact to rounding: the image of a solution satisfies the mirrored boundary conditions
    as well as the solution its own, the right-hand side commutes with the reflection, the
    second variation has the same spectrum (counts below shifts) and the ordinates change
    sign as derived."""
    _, rod, mod = modules
    p = tilted.params
    assert all(abs(p[k]) > 0.1 for k in ("psi", "alpha", "theta0", "chi", "beta", "phi0",
                                         "u1", "u2", "u3"))
    image = mirrored(mod, tilted, mirror)
    q = image.params
    own = np.max(np.abs(mod.bc(tilted.y[:, 0], tilted.y[:, -1], p)))
    assert np.max(np.abs(mod.bc(image.y[:, 0], image.y[:, -1], q))) <= max(2 * own, 1e-12)
    assert np.max(np.abs(mod.rhs(image.s, image.y, q) - image.yp)) < 1e-12
    assert spectrum_counts(rod, image) == spectrum_counts(rod, tilted)
    assert stability.index(rod, image) == stability.index(rod, tilted)
    signs = expected_signs(rod, mirror)
    before = rod.ordinate_values(tilted.s, tilted.y, p)
    after = rod.ordinate_values(image.s, image.y, q)
    moved = [name for name in before if abs(before[name]) > 1e-3]
    assert {"z1", "twist", "m3", "mz1", "mchi", "mB", "mphi", "m1", "mA", "m0"} <= set(moved)
    for name in before:
        assert after[name] == pytest.approx(signs[name] * before[name], abs=1e-12), name


@pytest.mark.parametrize("mirror", list(MIRRORS))
def test_continuations_from_mirror_images_are_mirror_images(modules, mirror):
    """The rotating arm of BASE with its arm's plane tilted (chi), the load out of the plane
    (beta), the clamp twisted (phi0) and an intrinsic twist (u3), continued in psi both ways
    through a fold on each side, and again from the mirror image of its start: two
    computations whose labels (LP, UZ, EP), index and columns are mirror images to 1e-9
    (psi -> -psi, and the two directions swapped, for x -> -x), and so are the snap-back
    targets at the folds."""
    from elastica_auto.branches.branch import StoredLabel
    _, rod, mod = modules
    label = BASE
    for name, value in (("psi", 0.3), ("chi", 0.4), ("beta", 0.15), ("phi0", 0.2),
                        ("u3", 0.3)):
        (br,) = ea.continuation(rod, label, name, bounds=(-0.1, value + 0.1), uz=[value],
                                max_points=60)
        label = br.label("UZ1")
    image = StoredLabel("UZ", 1, 0, mirrored(mod, label.state, mirror), None, None)
    kw = dict(bounds=(-1.2, 1.2), directions="both", uz=[-0.5, 0.5], max_points=200)
    one, two = (ea.continuation(rod, start, "psi", **kw) for start in (label, image))
    turn = -1 if "psi" in MIRRORS[mirror][3] else 1
    signs = expected_signs(rod, mirror)
    assert sum(len(br.folds) for br in one) == 2
    for a, b in zip(one, two[::turn]):
        assert [p.type for p in a.points] == [p.type for p in b.points]
        assert set(a.columns["index"].tolist()) == {0, 1}
        np.testing.assert_array_equal(a.columns["index"], b.columns["index"])
        np.testing.assert_allclose(a.columns["psi"], turn * b.columns["psi"], rtol=0,
                                   atol=1e-9)
        for name, sign in signs.items():
            np.testing.assert_allclose(a.columns[name], sign * b.columns[name], rtol=0,
                                       atol=1e-9, err_msg=name)
    assert len(one.snaps) == len(two.snaps) >= 2
    for row in one.snaps:
        (match,) = [r for r in two.snaps if abs(r["value"] - turn * row["value"]) < 1e-9
                    and abs(r["target_m1"] - signs["m1"] * row["target_m1"]) < 1e-6]
        for name in ("z1", "twist", "mz1", "gamma"):
            assert match[f"target_{name}"] == pytest.approx(
                signs[name] * row[f"target_{name}"], abs=1e-6)


def test_periods_of_alpha_chi_beta_phi0(modules, tilted):
    """alpha, chi and beta enter through sines and cosines: a solution is one at the angle
    plus 2 pi k, with the same index and ordinates; phi0 + 2 pi k turns the clamp's
    quaternion into (-1)^k q_c, and (-1)^k q is the same frame (as for theta0)."""
    from elastica_auto.core.solution import State
    _, rod, mod = modules
    y, p = tilted.y, tilted.params
    own = np.max(np.abs(mod.bc(y[:, 0], y[:, -1], p)))
    slopes = mod.rhs(tilted.s, y, p)
    index, ordinates = stability.index(rod, tilted), rod.ordinate_values(tilted.s, y, p)
    for name in ("alpha", "chi", "beta", "phi0"):
        for k in (1, -2, 3):
            shifted = {**p, name: p[name] + 2 * math.pi * k}
            z = y.copy()
            if name == "phi0" and k % 2:
                z[3:7] *= -1
            assert np.max(np.abs(mod.bc(z[:, 0], z[:, -1], shifted))) <= max(2 * own, 1e-12)
            zp = mod.rhs(tilted.s, z, shifted)
            sign = -1.0 if name == "phi0" and k % 2 else 1.0
            assert np.max(np.abs(zp[3:7] - sign * slopes[3:7])) < 1e-12
            assert np.max(np.abs(np.delete(zp - slopes, np.s_[3:7], 0))) < 1e-12
            assert stability.index(rod, State(tilted.s, z, zp, shifted)) == index
            got = rod.ordinate_values(tilted.s, z, shifted)
            for o in ordinates:
                assert got[o] == pytest.approx(ordinates[o], abs=1e-12), (name, k, o)


def test_the_declared_periods_are_those_found_by_hand(modules, tilted, rotating):
    """What each periodic parameter declares a period does to the states
    (`periods_applied`, which the stepper uses to copy a repeating branch) is what the two
    tests above find: q -> (-1)^k q for k turns of theta0 and phi0 and nothing for psi,
    alpha, chi and beta (the spatial rod); theta -> theta + 2 pi k for theta0 (the planar
    rod: theta(0) = theta0, and theta enters the ODE and the tip through sines and
    cosines), checked there on the planar module's own residuals."""
    from elastica_auto.model.problem import periods_applied
    planar, rod, _ = modules
    for name in ("psi", "alpha", "theta0", "chi", "beta", "phi0"):
        for k in (1, -2, 3):
            z, zp = tilted.y.copy(), tilted.yp.copy()
            if name in ("theta0", "phi0") and k % 2:
                z[3:7] *= -1
                zp[3:7] *= -1
            assert np.array_equal(periods_applied(rod, name, tilted.y, k), z), (name, k)
            assert np.array_equal(periods_applied(rod, name, tilted.yp, k, True), zp)
    flat, _ = rotating
    for br in flat:
        for p in (p for p in br.points if p.type == "UZ"):
            st = br.label(p.name).state
            for k in (1, -2, 3):
                turned = {**st.params, "theta0": st.params["theta0"] + 2 * math.pi * k}
                z = periods_applied(planar, "theta0", st.y, k)
                assert np.array_equal(z[1:], st.y[1:])
                assert np.allclose(z[0] - st.y[0], 2 * math.pi * k, rtol=0, atol=1e-12)
                assert np.max(np.abs(planar.bc(z[:, 0], z[:, -1], turned)
                                     - planar.bc(st.y[:, 0], st.y[:, -1], st.params))) < 1e-12
                assert np.max(np.abs(planar.rhs(st.s, z, turned)
                                     - planar.rhs(st.s, st.y, st.params))) < 1e-12
                assert np.array_equal(periods_applied(planar, "theta0", st.yp, k, True), st.yp)


def test_straight_rod_branch_points_are_both_stiffnesses_critical_loads(modules):
    """The straight rod continued in P (eps = 0.25, b2 = 2): a branch point at each B_i k^2
    with eps k tan k = 1, B_1 = 1 (in-plane) and B_2 = b2 (out of plane), and the index
    counts the critical loads passed: 0 -> 1 -> 2 -> 3."""
    from scipy.optimize import brentq
    _, rod, _ = modules
    k1 = brentq(lambda k: 0.25 * k * math.tan(k) - 1, 0.1, math.pi / 2 - 1e-9, xtol=1e-15)
    k2 = brentq(lambda k: 0.25 * k * math.tan(k) - 1, math.pi, 1.5 * math.pi - 1e-9,
                xtol=1e-15)
    want = sorted(b * k * k for b in (1.0, 2.0) for k in (k1, k2) if b * k * k < 17)
    (br,) = ea.continuation(rod, {"P": 0.0, "eps": 0.25, "b2": 2.0}, "P", bounds=(-1, 17),
                            max_points=100)
    bps = [p for p in br.points if p.type == "BP"]
    got = [p.params["P"] for p in bps]
    assert len(got) == len(want) == 3
    assert np.max(np.abs(np.subtract(got, want)) / np.array(want)) < 1e-9
    inner = [p.index for p in br.points if p.type == ""]
    assert sorted(set(inner)) == [0, 1, 2, 3] and inner == sorted(inner)
    for p in br.points:
        assert abs(p.ordinates["z1"]) < 1e-12 and abs(p.ordinates["m1"]) < 1e-12


def test_draw_projects_on_the_plane(modules, generic):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from elastica_auto.branches.branch import PROFILE_GRID
    _, _, mod = modules
    fig, ax = plt.subplots()
    mod.draw(ax, generic(PROFILE_GRID), generic.params)
    gids = {a.get_gid() for a in ax.get_children()}
    assert {"rod", "lever arm", "load"} <= gids
    (rod,) = [line for line in ax.lines if line.get_gid() == "rod"]
    assert np.allclose(rod.get_xdata(), generic(PROFILE_GRID)[0])
    plt.close(fig)


def prandtl_load(eps):
    """The smallest lambda = P / sqrt(B2 C) of the reduced lateral-torsional problem of a
    cantilever with a perpendicular tip load and an in-plane-rigid section (Prandtl-Michell),
    the load applied eps sqrt(B2/C) from the centroid against its direction: the twist phi
    with C phi'' + (P^2 (1 - s)^2 / B2) phi = 0, phi(0) = 0, C phi'(1) = P eps phi(1);
    scaled, phi'' + lambda^2 (1 - s)^2 phi = 0, phi'(1) = lambda eps phi(1). By shooting."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq

    def residual(lam):
        sol = solve_ivp(lambda s, y: (y[1], -lam ** 2 * (1 - s) ** 2 * y[0]), (0, 1),
                        (0.0, 1.0), rtol=1e-12, atol=1e-13)
        return sol.y[1, -1] - lam * eps * sol.y[0, -1]
    return brentq(residual, 1.0, 6.0, xtol=1e-12)


@pytest.mark.parametrize("eps", [0.0, 0.1, -0.1])
def test_lateral_torsional_buckling_of_a_stiff_section(modules, eps):
    """The load perpendicular to the rod (alpha = pi/2, along +x), the arm perpendicular to
    the tip and pointing against the load (psi = -pi/2), b2 = c = 1e-4 (in-plane stiffness
    1e4 times larger): the out-of-plane branch point is the Prandtl-Michell load, 4.0125993
    sqrt(B2 C) at eps = 0 and the shooting values 3.5415326 (eps = 0.1: load above the
    centroid, destabilising) and 4.3613946 (eps = -0.1); the in-plane flexibility raises it
    by O(B2/B1) (1.1e-3 at B2/B1 = 1e-3, 1.1e-4 at 1e-4, linear: seen). The index goes 0 -> 1
    there."""
    _, rod, _ = modules
    ratio = 1e-4
    (br,) = ea.continuation(rod, {"P": 0.0, "eps": eps, "b2": ratio, "c": ratio,
                                  "alpha": math.pi / 2, "psi": -math.pi / 2}, "P",
                            bounds=(-1, 6 * ratio), ds=0.2 * ratio, ds_max=0.5 * ratio,
                            max_points=100)
    (bp,) = [p for p in br.points if p.type == "BP"]
    want = prandtl_load(eps)
    assert abs(bp.params["P"] / ratio / want - 1) < 3e-4
    assert {p.index for p in br.points if p.type == "" and p.params["P"] < bp.params["P"]} \
        == {0}
    assert {p.index for p in br.points if p.type == "" and p.params["P"] > bp.params["P"]} \
        == {1}


def assert_rule_agrees(branch):
    """Across every fold the fold rule (the distinguished ordinate's slope) gives the direct
    count's index: no disagreement away from LP and BP rows, and at least one fold changes
    the index."""
    assert not branch.warnings, branch.warnings
    for p in branch.points:
        assert "disagreement" not in p.note, p.note
        if p.type not in ("LP", "BP"):
            assert p.index == p.index_rule == p.index_direct >= 0
    changes = {(a.index, b.index) for a, b in zip(branch.points, branch.points[2:])
               if a.type == "" and b.type == "" and a.index != b.index}
    return changes


def assert_out_of_plane_changes_at_branch_points(branch):
    """The out-of-plane index of the planar points changes only across a located BP."""
    last = None
    for p in branch.points:
        if p.type == "BP":
            last = None
        elif p.type == "" and p.ordinates["index_out"] >= 0:
            assert last is None or p.ordinates["index_out"] == last, (p.params, p.note)
            last = p.ordinates["index_out"]


def test_fold_rule_with_the_distinguished_ordinates(modules, rotating):
    """The fold rule reads m1 = dE/dpsi (the rotating arm, b2 = 2) and beps = dE/deps (eps
    continued at P = 9 pi^2/4 from a buckled state of index 3 through its fold to index 2)."""
    _, rod, _ = modules
    _, branches = rotating
    for br in branches:
        assert assert_rule_agrees(br) == {(1, 0)}
        assert_out_of_plane_changes_at_branch_points(br)      # b2 = 2: none, index_out 0
    base = ea.continuation(rod, {**BASE, "P": 9 * math.pi ** 2 / 4}, "psi", bounds=(-1, 0.4),
                           uz=[0.3], max_points=100)
    (br,) = ea.continuation(rod, base.label("UZ1"), "eps", bounds=(-2, 2), directions="-",
                            max_points=60)
    assert [p.type for p in br.points].count("LP") == 1
    assert assert_rule_agrees(br) == {(3, 2)}


@pytest.mark.parametrize("seed", range(4))
def test_jacobians_are_the_complex_step_derivatives(modules, seed):
    """rhs_jac and bc_jac against complex-step derivatives of rhs and bc (exact to rounding:
    no subtraction), at random states (|q| != 1 too) and random parameters: the hand-written
    reference's (tests/reference), with which tests/test_energy_rod.py compares the derived
    module's."""
    _, _, mod = modules
    rng = np.random.default_rng(seed)
    p = dict(zip(("P", "eps", "psi", "alpha", "theta0", "chi", "beta", "phi0", "u1", "u2", "u3"),
                 rng.uniform(-3, 3, 11)))
    p.update(b2=rng.uniform(0.5, 3), c=rng.uniform(0.3, 2))
    s = np.linspace(0, 1, 6)
    y = rng.standard_normal((10, 6))
    h = 1e-30
    want = np.empty((10, 10, 6))
    for j in range(10):
        yc = y.astype(complex)
        yc[j] += 1j * h
        want[:, j] = mod.rhs(s, yc, p).imag / h
    assert np.abs(mod.rhs_jac(s, y, p) - want).max() <= 1e-13 * np.abs(want).max()
    ya, yb = rng.standard_normal(10), rng.standard_normal(10)
    for end, got in enumerate(mod.bc_jac(ya, yb, p)):
        want = np.empty((10, 10))
        for j in range(10):
            e = np.zeros(10, complex)
            e[j] = 1j * h
            want[:, j] = np.asarray(mod.bc(ya + (e if end == 0 else 0),
                                           yb + (e if end == 1 else 0), p)).imag / h
        assert np.abs(got - want).max() <= 1e-13 * max(1.0, np.abs(want).max())


# ---- out-of-plane branch points of planar branches (issue 20, item 3) -----------------------

def shooting_matrix(mod, p, m0):
    """Shooting on m(0) for the spatial rod at ``p`` (independent of the collocation): the
    state y(1) from y(0) = (0, q_c, m0) and the 3 x 3 derivative of the tip condition
    m(1) - a x F in m0, by the variational equations (the right-hand side's Jacobian by
    central differences) integrated with DOP853 to 1e-11. Returns (tip residual, matrix)."""
    from scipy.integrate import solve_ivp

    def jac(s, y):
        out = np.empty((10, 10))
        for j in range(10):
            e = np.zeros(10)
            e[j] = 1e-6
            out[:, j] = (mod.rhs(s, (y + e)[:, None], p)[:, 0]
                         - mod.rhs(s, (y - e)[:, None], p)[:, 0]) / 2e-6
        return out

    def f(s, z):
        y, v = z[:10], z[10:].reshape(10, 3)
        return np.concatenate((mod.rhs(np.array([s]), y[:, None], p)[:, 0],
                               (jac(np.array([s]), y) @ v).ravel()))

    ya = np.concatenate((np.zeros(3), mod.clamp_quaternion(p), m0))
    v0 = np.zeros((10, 3))
    v0[7:10] = np.eye(3)
    z = solve_ivp(f, (0, 1), np.concatenate((ya, v0.ravel())), method="DOP853", rtol=1e-11,
                  atol=1e-12).y[:, -1]
    yb, v = z[:10], z[10:].reshape(10, 3)
    gb = np.empty((3, 10))
    for j in range(10):
        e = np.zeros(10)
        e[j] = 1e-6
        gb[:, j] = (mod.bc(ya, yb + e, p)[7:] - mod.bc(ya, yb - e, p)[7:]) / 2e-6
    return mod.bc(ya, yb, p)[7:], gb @ v


def shooting_solution(mod, p, m0):
    """m(0) of the equilibrium near ``m0`` at ``p`` by Newton on the shooting residual."""
    for _ in range(8):
        res, mat = shooting_matrix(mod, p, m0)
        m0 = m0 - np.linalg.solve(mat, res)
        if np.max(np.abs(res)) < 1e-12:
            break
    return m0


def test_out_of_plane_branch_point_in_b2(modules):
    """A planar buckled state (P = 9 pi^2/4, eps = 0.25, psi = 0.3, index 3: 2 in the plane,
    1 out of it) continued down in b2: the planar state does not depend on b2 (u2 = 0), and
    at b2 = 1.4572075 its out-of-plane block gets a zero eigenvalue. The branch point is
    located where the shooting
    matrix of the linearised problem (variational equations, solve_ivp) is singular, to 1e-7;
    the out-of-plane index 1 -> 2 there by the conjugate-point count of the out-of-plane block;
    no fold rule disagreement after it. (Not located while Newton's method refused iterates
    whose residual was rounding, their correction being that rounding amplified by the
    near-singular Jacobian: "no decrease of the Newton correction".)"""
    from form_reference import Form, conjugate_count
    from scipy.optimize import brentq
    _, rod, mod = modules
    base = ea.continuation(rod, {**BASE, "P": 9 * math.pi ** 2 / 4}, "psi", bounds=(-1, 0.4),
                           uz=[0.3], max_points=100)
    (br,) = ea.continuation(rod, base.label("UZ1"), "b2", bounds=(1.0, 3), directions="-",
                            max_points=60)
    assert br.end == "EP" and not br.warnings, br.warnings
    (bp,) = [p for p in br.points if p.type == "BP"]
    assert all("disagreement" not in p.note for p in br.points)
    st = base.label("UZ1").state
    m0 = shooting_solution(mod, st.params, st.y[7:10, 0].copy())
    want = brentq(lambda b2: np.linalg.det(shooting_matrix(mod, {**st.params, "b2": b2},
                                                           m0)[1]), 1.4, 1.5, xtol=1e-12)
    print(f"branch point b2 = {bp.params['b2']:.10f}, shooting {want:.10f}")
    assert abs(bp.params["b2"] - want) < 1e-7

    def out_of_plane(b2):
        p = {**st.params, "b2": b2}

        def field(name):
            return lambda s: getattr(mod.second_variation(s, st(s), p), name)[:, :2, :2]
        end = mod.second_variation(st.s, st.y, p).E1[:2, :2]
        return conjugate_count(Form(k=2, A=field("A"), B=field("B"), C=field("C"), E1=end,
                                    G0=np.eye(2))).index
    assert (out_of_plane(want * (1 + 1e-4)), out_of_plane(want * (1 - 1e-4))) == (1, 2)
    before = [p for p in br.points if p.type == "" and p.params["b2"] > want]
    after = [p for p in br.points if p.type == "" and p.params["b2"] < want]
    assert before and after
    assert {(p.index, p.ordinates["index_out"]) for p in before} == {(3, 1.0)}
    assert {(p.index, p.ordinates["index_out"]) for p in after} == {(4, 2.0)}
    assert_out_of_plane_changes_at_branch_points(br)


# ---- the isotropic rod's rotation about the load line (issue 20, item 4) ----------------------

def turn_about_load_line(mod, y, p, theta):
    """The group action of the symmetry: r -> Q r, m -> Q m, q -> q_Q (x) q (x) q_3(-theta),
    Q the rotation by theta about the clamp axis (docs/kirchhoff.md, "Symmetry")."""
    e = mod.clamp_axis(p)
    qq = mod.qaxis(e, theta)
    rot = mod.rotation(qq)
    q = mod.qmul(mod.qmul(qq[:, None], y[3:7]), mod.qaxis((0, 0, 1), -theta)[:, None])
    return np.vstack((rot @ y[0:3], q, rot @ y[7:10]))


@pytest.fixture(scope="module")
def isotropic(modules):
    """The isotropic straight rod (b2 = 1, eps = 0.25, psi = 0) loaded along its axis,
    continued in P, and the buckled branches switched onto at its first branch point."""
    _, rod, _ = modules
    return ea.continuation(rod, {"P": 0.0, "eps": 0.25, "b2": 1.0}, "P", bounds=(-1, 5),
                           max_points=60, switch=1, uz=[3.0])


def test_isotropic_straight_rod_double_branch_point(isotropic):
    """b2 = 1: both bending directions buckle at the same load, P = k^2 with eps k tan k = 1
    (1.5991918), a zero eigenvalue of multiplicity 2: the determinant keeps its sign and the
    branch point is found by the index (0 -> 2) and located where it changes, to 1e-9."""
    from scipy.optimize import brentq
    k1 = brentq(lambda k: 0.25 * k * math.tan(k) - 1, 0.1, math.pi / 2 - 1e-9, xtol=1e-15)
    trivial = isotropic[0]
    assert trivial.end == "EP" and not trivial.warnings, trivial.warnings
    (bp,) = [p for p in trivial.points if p.type == "BP"]
    assert abs(bp.params["P"] / (k1 * k1) - 1) < 1e-9
    assert "even multiplicity" in bp.note
    inner = [p.index for p in trivial.points if p.type == ""]
    assert sorted(set(inner)) == [0, 2] and inner == sorted(inner)


def unfolding_of(point):
    import re
    (mu,) = re.findall(r"unfolding (\S+)", point.note)
    return float(mu)


def test_isotropic_buckled_branch_with_a_phase_condition(modules, isotropic):
    """The buckled branches born at the double branch point form circles (a rotation about
    the load line turns a solution into a solution), so their Jacobian is singular: each is
    continued with the phase condition and the unfolding parameter, which stays at rounding
    (< 1e-10: it is zero at every solution); the circle is real (a buckled state turned by
    0.7 about the load line solves the collocation equations and boundary conditions as well
    as it does, to 1e-10); the index is counted without the zero mode (zero_mode = 1), and it
    and the numbers of eigenvalues below shifts equal a dense Legendre-Galerkin count of the
    form on the complement of the rotation field e - d3; without the constraint the dense
    spectrum has that zero eigenvalue."""
    from form_reference import Form, dense_count

    from elastica_auto.numerics.collocation import Discretisation
    _, rod, mod = modules
    switched = isotropic[1:]
    assert len(switched) == 2
    for br in switched:
        assert br.end == "EP" and not br.warnings, br.warnings
        assert len(br.points) > 8
        for p in br.points:
            assert abs(unfolding_of(p)) < 1e-10
            if p.type != "EP":       # the branch point itself is on the straight rod
                assert p.ordinates["zero_mode"] == 1.0 and abs(p.ordinates["z1"]) > 1e-3
                assert p.index == p.index_direct == 0
    (uz,) = [p for p in switched[0].points if p.type == "UZ"]
    st = switched[0].label(uz.name).state
    disc = Discretisation(rod, st.s)
    own = disc.evaluate(st.y, st.params)
    turned = disc.evaluate(turn_about_load_line(mod, st.y, st.params, 0.7), st.params)
    worst = max(np.max(np.abs(turned.col)), np.max(np.abs(turned.bc)))
    print(f"turned solution: residual {worst:.1e} (the solution's own "
          f"{max(np.max(np.abs(own.col)), np.max(np.abs(own.bc))):.1e})")
    assert worst < 1e-10
    assert np.max(np.abs(turned.y - st.y)) > 0.1

    def field(name):
        return lambda s: getattr(mod.second_variation(s, st(s), st.params), name)
    end = mod.second_variation(st.s, st.y, st.params).E1

    def dense(constrained, shift=0.0):
        cons = [(lambda s: mod.zero_mode(s, st(s), st.params).T, np.zeros(3), np.zeros(3))] \
            if constrained else []
        return dense_count(Form(k=3, A=field("A"), C=field("C"), E1=end, G0=np.eye(3),
                                B=lambda s: field("B")(s) - shift * np.eye(3),
                                constraints=cons))
    free = dense(False)[2]
    assert np.min(np.abs(free)) < 1e-6 * np.max(np.abs(free[:8]))      # the zero mode
    index, smallest, spectrum = dense(True)
    assert smallest > 1e-3 and index == uz.index == 0
    low = spectrum[spectrum < 60]
    shifts = [(x + y) / 2 for x, y in zip(low[:-1], low[1:]) if y - x > 0.5]
    evaluate = stability.form_on_state(rod, st)
    engine = [stability.count_form(evaluate, st.s, shift=mu).index for mu in shifts]
    print("shifts", np.round(shifts, 3), "engine", engine)
    assert len(shifts) >= 3
    assert engine == [int(np.sum(spectrum < mu)) for mu in shifts]


def test_switch_onto_the_lateral_torsional_branch(modules):
    """The lateral-torsional branch point of a section with B2 = C = 1e-2 (load perpendicular,
    eps = 0: 4.0596 sqrt(B2 C), docs/kirchhoff.md) switched onto: both halves of the branch
    born there are non-planar (z(1) = -+0.36 at P = 0.0495), mirror images of each other; a
    state of it solves the problem by an independent shooting on m(0) (Newton on the tip
    condition, DOP853), which lands on the collocation's m(0) and tip to 1e-6; its index by
    direct count equals the conjugate-point count of the 3 x 3 Jacobi system (0: the buckled
    section is stable), while the planar branch past the branch point has index 1."""
    _, rod, mod = modules
    ratio = 1e-2
    runs = ea.continuation(rod, {"P": 0.0, "eps": 0.0, "b2": ratio, "c": ratio,
                                 "alpha": math.pi / 2, "psi": -math.pi / 2}, "P",
                           bounds=(-1, 0.05), ds=0.2 * ratio, ds_max=5 * ratio,
                           max_points=60, switch=1, uz=[0.0495])
    planar, *switched = runs
    (bp,) = [p for p in planar.points if p.type == "BP"]
    assert bp.params["P"] == pytest.approx(4.0596 * ratio, rel=1e-4)
    assert {p.index for p in planar.points if p.type in ("", "UZ", "EP")
            and p.params["P"] > bp.params["P"]} == {1}
    assert len(switched) == 2
    tips = []
    for br in switched:
        assert br.end == "EP" and not br.warnings, br.warnings
        assert all("disagreement" not in p.note for p in br.points)
        assert {p.index for p in br.points if p.type != "EP"} == {0}
        (uz,) = [p for p in br.points if p.type == "UZ"]
        st = br.label(uz.name).state
        assert abs(uz.ordinates["z1"]) > 0.3 and uz.ordinates["index_out"] == -1
        m0 = shooting_solution(mod, st.params, st.y[7:10, 0].copy())
        assert np.max(np.abs(m0 - st.y[7:10, 0])) < 1e-6
        assert conjugate_index(mod, st) == stability.index(rod, st) == 0
        tips.append(st.y[0:3, -1])
    assert tips[0][2] == pytest.approx(-tips[1][2], abs=1e-7)          # mirror images
    assert tips[0][:2] == pytest.approx(tips[1][:2], abs=1e-7)


def test_a_branch_s_split_index_is_the_engine_s_count(monkeypatch):
    """index_in and index_out at the points of a branch are the counts of the form's parts
    that gave the point's index (`SecondVariation` ``parts``), not a second count in the
    module's ordinates: the module counts them itself (``part_counts``) only at points the
    engine did not count as steps (the start, labels, the end), and in-plane plus
    out-of-plane is the index wherever both are counted."""
    from elastica_auto.energy import runtime
    rod = load_problem(K3)
    calls = []
    counted = runtime.part_counts       # what the derived index_in, index_out count with

    def part_counts(*args, **kwargs):
        calls.append(args)
        return counted(*args, **kwargs)
    counted.cache_clear()
    monkeypatch.setattr(runtime, "part_counts", part_counts)
    (br,) = ea.continuation(rod, BASE, "psi", bounds=(-0.6, 0.6), max_points=40, ds_max=0.05)
    stepped = [p for p in br.points if not p.type]
    assert len(stepped) >= 15
    assert len(calls) <= len(br.points) - len(stepped)
    both = [p for p in br.points if min(p.ordinates["index_in"], p.ordinates["index_out"]) >= 0]
    assert len(both) >= len(stepped)
    assert all(p.ordinates["index_in"] + p.ordinates["index_out"] == p.index_direct
               for p in both)


def test_symmetric_branch_points_are_placed_where_the_search_finds_them(modules,
                                                                       monkeypatch):
    """b2 = 1: the branch points of the rotating arm lie where the symmetry holds, psi = k pi
    (the module's symmetric_values): placed there exactly, with no search. Against the
    determinant's root located by the search (the hook taken away): the same labels in the
    same order, the branch points within 1e-9, the other points' parameters and indices the
    same. A hook that answers a value outside [lo, hi] ends the branch (MX) and says so."""
    _, rod, mod = modules
    start = {"P": math.pi ** 2 / 4, "eps": 0.25, "b2": 1.0}
    kw = dict(bounds=(-7.0, 1.0), max_points=150)
    (placed,) = ea.continuation(rod, start, "psi", **kw)
    monkeypatch.setattr(rod, "_symmetric_values", None)
    (searched,) = ea.continuation(rod, start, "psi", **kw)
    bps = [p for p in placed.points if p.type == "BP"]
    assert [round(p.params["psi"] / math.pi, 9) for p in bps] == [0.0, -2.0]
    assert all(p.params["psi"] == round(p.params["psi"] / math.pi) * math.pi for p in bps)
    assert [p.type for p in placed.points if p.type] == \
        [p.type for p in searched.points if p.type]
    for a, b in zip([p for p in placed.points if p.type], [p for p in searched.points
                                                           if p.type]):
        assert abs(a.params["psi"] - b.params["psi"]) < 1e-9
        if a.type != "BP":
            assert a.index == b.index
    monkeypatch.setattr(rod, "_symmetric_values", lambda name, lo, hi, p: [hi + 1.0])
    (bad,) = ea.continuation(rod, start, "psi", **kw)
    assert bad.end == "MX" and "not all finite and in [lo, hi]" in bad.message


def test_isotropic_rotating_arm_through_the_symmetric_point(modules):
    """b2 = 1, P = pi^2/4: where the arm lies along the tip tangent (psi = 0) the buckled rod
    has the rotational zero mode (a circle of equilibria), and one out-of-plane eigenvalue
    crosses zero there: a branch point, both ways along the arm's rotation. The kernel the
    engine counts there is that one mode: a dense Legendre-Galerkin spectrum of the whole form
    (no constraint) at the located point has exactly one eigenvalue within delta of zero, and
    the direct count changes by one across it. The fold rule agrees with the direct count at
    every point, the user points placed on the symmetric point (before or after the BP)
    included, whose index, with the zero mode left out, is the dense count on its complement
    (the smaller of the two sides)."""
    from form_reference import Form, dense_count
    _, rod, mod = modules
    kw = dict(uz=[0.0], max_points=80)
    (out,) = ea.continuation(rod, {"P": math.pi ** 2 / 4, "eps": 0.25, "b2": 1.0}, "psi",
                             bounds=(-0.3, 1.0), **kw)
    back = [br for br in ea.continuation(rod, out.label(out.points[-1].name), "psi",
                                         bounds=(-0.31, 0.3), directions="both", **kw)
            if br.points[-1].params["psi"] > 0]
    assert len(back) == 1
    for br in (out, back[0]):
        assert br.end == "EP" and not br.warnings, br.warnings
        assert not [p.note for p in br.points if "disagreement" in p.note]
        pts = br.points
        k = next(k for k, p in enumerate(pts) if p.type == "BP")
        assert abs(pts[k].params["psi"]) < 1e-9
        off = [p.index_direct for p in (pts[k - 2], pts[k + 2])]
        (uz,) = [p for p in pts if p.type == "UZ" and abs(p.params["psi"]) < 1e-9]
        at = br.label(uz.name).state        # psi = 0 to rounding: the zero mode is left out

        def field(name, at=at):
            return lambda s: getattr(mod.second_variation(s, at(s), at.params), name)
        form = dict(k=3, A=field("A"), B=field("B"), C=field("C"), G0=np.eye(3),
                    E1=mod.second_variation(at.s, at.y, at.params).E1)
        spectrum = dense_count(Form(**form))[2]
        assert np.sum(np.abs(spectrum) < 1e-3 * 0.5) == 1, np.sort(np.abs(spectrum))[:3]
        assert abs(off[1] - off[0]) == 1 == stability.kernel_dimension(rod, at), off
        cons = [(lambda s: mod.zero_mode(s, at(s), at.params).T, np.zeros(3), np.zeros(3))]
        want = dense_count(Form(**{**form, "constraints": cons}))[0]
        assert uz.index == uz.index_direct == want == min(off)
