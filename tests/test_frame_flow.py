"""The gradient flow of frames (elastica_auto/energy/frame_flow.py; issue 47 item 2's
``gradient_flow`` for rotation coordinates; docs/energy.md, "The gradient flow of frames"),
against what is independent of it:

* the discrete strain and midpoint frame of an interval against their closed forms (a turn by
  a known angle about a known axis), and their derivatives against the complex step;
* the force against central differences of the discrete energy, its Jacobian against central
  differences of the force, at random frame fields with |q| != 1 (the spatial rod and the
  column in space);
* the exact reduction: on a planar field of the spatial rod the discrete energy and the force
  are the planar elastica's derived flow's (the same energy, the midpoint rule), and the
  flow from a planar start ends at the planar flow's angles; the energy decreases at every
  step (a Lyapunov check);
* where a snap lands: every fold of the rotating arm at eps = 0.25, P = pi^2/4, b2 = 2 (its
  planar stable stretch stable out of plane, docs/three-d.md) lands on the planar elastica's
  target with its released energy; the landed state is an equilibrium: the BVP solved from it
  (scipy's solve_bvp, not the engine's corrector) is an equilibrium that the shooting scan
  finds at that parameter, with index 0 by the direct count; a run file with ``landing =
  true`` gives the landings, and ``snaps`` lists them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.analysis.equilibria import beyond_fold, enumerate_equilibria, snap_lps
from elastica_auto.analysis.landing import BEYOND, NODES, overdamped_path, land
from elastica_auto.core.solution import State
from elastica_auto.energy import frame_flow as ff
from elastica_auto.energy.loader import execute
from elastica_auto.numerics.bvp import solve_fixed
from elastica_auto.numerics.stability import count_form
from helpers import EXAMPLES, run_cli

ARM = {"eps": 0.25, "P": math.pi ** 2 / 4}


def _qaxis(axis, angle):
    """Quaternions (4, m) of turns by ``angle`` (m,) about the unit ``axis``."""
    angle = np.asarray(angle, dtype=float)
    return np.vstack((np.cos(angle / 2), np.outer(axis, np.sin(angle / 2))))


def _matrix(axis, angle):
    """Rodrigues' rotation by ``angle`` about the unit ``axis`` (3, 3)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


@pytest.fixture(scope="module")
def rod():
    return ea.load_problem("kirchhoff_lever_arm")


@pytest.fixture(scope="module")
def planar():
    """The planar elastica with its derived gradient flow (the midpoint rule; the shipped
    module keeps its hand-written one, the paper's trapezoidal potential)."""
    shipped = ea.load_problem("elastica_lever_arm")
    module = execute(shipped.generated, "derived")
    module.exact_start, module.shooting = shipped.module.exact_start, shipped.module.shooting
    return ea.Problem(module, "derived")


def test_an_intervals_strain_and_midpoint_frame_are_the_turn_between_its_frames():
    """q_b = q_a (x) (cos(phi/2), sin(phi/2) n), the body turn R_b = R_a Rot(n, phi): U = phi
    n / h and Rbar = R_a Rot(n, phi / 2), whatever the scales of the quaternions, for phi
    from 0 and 1e-9 (the series) to 6.2 (beyond a half turn: the quaternions' great arc);
    the derivatives are the complex step's."""
    rng = np.random.default_rng(4)
    m = 40
    phi = np.concatenate((rng.uniform(0, 6.2, m - 7), [0.0, 1e-9, 1e-5, 2.9, math.pi, 3.5,
                                                       6.2]))
    axes = rng.normal(size=(3, m))
    axes /= np.linalg.norm(axes, axis=0)
    qa = rng.normal(size=(4, m))
    turn = np.array([_qaxis(axes[:, i], phi[i])[:, 0] for i in range(m)]).T
    qb = ff.hamilton(qa, turn) * rng.uniform(0.5, 2, m)
    h = rng.uniform(0.01, 0.2, m)
    U, Rbar = ff.geometry(qa, qb, h)
    np.testing.assert_allclose(U, axes * phi / h, rtol=1e-12, atol=1e-12)
    Ra = ff.rotation(qa)
    for i in range(m):
        np.testing.assert_allclose(Rbar[:, :, i], Ra[:, :, i] @ _matrix(axes[:, i], phi[i] / 2),
                                   atol=1e-14)
    U2, R2, dU, dR = ff.geometry_jacobian(qa, qb, h)
    np.testing.assert_allclose(U2, U, rtol=1e-14, atol=1e-14)
    q = np.concatenate((qa, qb)).astype(complex)
    for i in range(8):
        q[i] += 1j * ff.COMPLEX_STEP
        u, r = ff.geometry(q[:4], q[4:], h)
        q[i] -= 1j * ff.COMPLEX_STEP
        scale = np.abs(u.imag).max() / ff.COMPLEX_STEP
        np.testing.assert_allclose(dU[:, i], u.imag / ff.COMPLEX_STEP, atol=1e-12 * scale)
        np.testing.assert_allclose(dR[:, :, i], r.imag / ff.COMPLEX_STEP, atol=1e-14)


@pytest.mark.parametrize("name, params", [
    ("kirchhoff_lever_arm", {"P": 20.0, "eps": 0.5, "psi": 1.0, "alpha": 0.4, "beta": 0.3,
                             "chi": 0.2, "theta0": 0.3, "phi0": 0.5, "b2": 2.0, "u1": 0.3,
                             "u3": -0.2}),
    ("spatial_column", {"P": 3.0})])
def test_the_frame_flow_is_the_gradient_of_its_energy(name, params):
    """force = -grad E / mass and its Jacobian against central differences of the energy and
    of the force, at a random frame field with |q| != 1 (no equilibrium); the mass of a
    quaternion component is 4 M (the frames' metric)."""
    problem = ea.load_problem(name if name == "kirchhoff_lever_arm"
                              else EXAMPLES / f"{name}.py")
    p = {**problem.defaults(), **params}
    nodes = np.linspace(0, 1, 21)
    flow = problem.gradient_flow(p, nodes)
    rows = [problem.states.index(c) for c in
            (("q0", "q1", "q2", "q3") if name == "kirchhoff_lever_arm"
             else ("R_q0", "R_q1", "R_q2", "R_q3"))]
    rng = np.random.default_rng(2)
    y = np.zeros((problem.n, len(nodes)))
    y[rows] = rng.normal(size=(4, 1)) + 0.4 * rng.normal(size=(4, len(nodes))) * nodes
    u = flow.to_u(y)
    weights = ea.trapezoid_weights(nodes)[1:]
    np.testing.assert_allclose(flow.mass, 4 * np.tile(weights, 4), rtol=1e-15)
    d = 1e-6
    eye = np.eye(len(u))
    grad = np.array([(flow.energy(u + d * e) - flow.energy(u - d * e)) / (2 * d) for e in eye])
    np.testing.assert_allclose(-flow.mass * flow.force(u), grad,
                               atol=1e-7 * (1 + np.abs(grad).max()))
    jac = np.array([(flow.force(u + d * e) - flow.force(u - d * e)) / (2 * d) for e in eye]).T
    np.testing.assert_allclose(flow.jacobian(u).toarray(), jac, atol=1e-6 * np.abs(jac).max())


def _planar_field(theta, theta0=0.0):
    """The spatial rod's quaternions of the planar field theta: Rz(theta) R_REF."""
    import elastica_auto.equations.kirchhoff_lever_arm as K
    return K.qmul(_qaxis((0, 0, 1), theta), K.Q_REF[:, None])


def _angles(q):
    """theta of a planar field of quaternions (R = Rz(theta) R_REF), unwrapped."""
    import elastica_auto.equations.kirchhoff_lever_arm as K
    back = K.qmul(q, (K.Q_REF * np.array((1, -1, -1, -1)))[:, None])
    return np.unwrap(2 * np.arctan2(back[3], back[0]))


def test_a_planar_field_of_the_spatial_rod_flows_as_the_planar_elastica(rod, planar):
    """The exact reduction: at a random planar field (b2 = 2) the spatial rod's discrete
    energy is the planar one, its force the planar one's turn about e_z (nothing out of the
    plane), and the flow from it ends where the planar flow ends, at the same angles; the
    energy is non-increasing at every step of the integration."""
    p3 = {**rod.defaults(), "P": 9 * math.pi ** 2 / 4, "eps": 0.5, "psi": 1.0, "b2": 2.0,
          "theta0": 0.3, "alpha": 0.2}
    p2 = {k: p3[k] for k in planar.defaults()}
    nodes = np.linspace(0, 1, NODES + 1)
    f3, f2 = rod.gradient_flow(p3, nodes), planar.gradient_flow(p2, nodes)
    theta = 0.3 + np.concatenate(([0.0], np.cumsum(np.random.default_rng(0).normal(
        size=NODES)) * 0.05))
    y = np.zeros((10, len(nodes)))
    y[3:7] = _planar_field(theta)
    u3, u2 = f3.to_u(y), theta[1:]
    assert f3.energy(u3) == pytest.approx(f2.energy(u2), rel=1e-13)
    q = y[3:7, 1:]
    omega = 2 * ff.hamilton(f3.force(u3).reshape(4, -1), q * np.array((1, -1, -1, -1))[:, None])
    scale = np.abs(f2.force(u2)).max()
    np.testing.assert_allclose(omega[3], f2.force(u2), atol=1e-13 * scale)
    np.testing.assert_allclose(omega[:3], 0, atol=1e-13 * scale)
    _, e2, end2 = overdamped_path(f2, u2)
    _, e3, end3 = overdamped_path(f3, u3)
    assert np.all(np.diff(e3) <= 1e-13 * abs(e3[0]))
    np.testing.assert_allclose(_angles(end3.reshape(4, -1)), end2, atol=1e-7)
    assert e3[-1] == pytest.approx(e2[-1], rel=1e-12)


@pytest.fixture(scope="module")
def arms(rod, planar):
    """The rotating arm at eps = 0.25, P = pi^2/4 around the straight rod, psi in [-2, 2]
    (its folds at +-0.8173 end the stable stretch), with its landings: the planar elastica's
    derived flow and the spatial rod's (b2 = 2) flow of frames."""
    return {key: ea.continuation(problem, {**ARM, **extra}, "psi", directions="both",
                                 bounds=(-2.0, 2.0), landing=True)
            for key, problem, extra in (("planar", planar, {}), ("spatial", rod, {"b2": 2.0}))}


def test_snaps_of_the_spatial_rod_land_where_the_planar_elasticas_land(arms):
    """The same folds, each landing on the same target (m(0).e_z), with the same energy
    released (the flows are the same on planar fields; the folds agree to 1e-9)."""
    mine, theirs = arms["spatial"].snaps, arms["planar"].snaps
    assert len(mine) == len(theirs) >= 2
    assert sum(r["landed"] for r in mine) >= 2
    for a, b in zip(mine, theirs):
        assert (a["lp"], a["landed"]) == (b["lp"], b["landed"])
        assert a["target_m0"] == pytest.approx(b["target_m0"], abs=1e-7)
        if a["landed"]:
            assert a["energy_released"] == pytest.approx(b["energy_released"], rel=1e-6)


def test_the_landed_state_is_a_stable_equilibrium_of_the_bvp(rod, arms):
    """From the end of the dynamics (the discrete equilibrium at the fold's psi moved
    BEYOND), the BVP solved by scipy's solve_bvp converges to an equilibrium that the
    shooting scan finds at that psi (its m(0) to 1e-7), of index 0 by the direct count, the
    enumerated target's."""
    branch = next(br for br in arms["spatial"] if snap_lps(br))
    fold, side = snap_lps(branch)[0]
    beyond = beyond_fold(branch, fold, side)
    landing = land(rod, fold.state, fold.tangent, enumerate_equilibria(rod, fold.params),
                   "psi", beyond)
    assert landing.target is not None
    assert np.all(np.diff(landing.energies) <= 1e-13 * abs(landing.energies[0]))
    p = {**fold.params, "psi": fold.params["psi"] + beyond * BEYOND}
    s = np.linspace(0, 1, NODES + 1)
    q = np.hstack((fold.state.y[3:7, :1], landing.end.reshape(4, -1)))
    U, _ = ff.geometry(q[:, :-1], q[:, 1:], np.diff(s))
    u = np.hstack((U[:, :1], 0.5 * (U[:, :-1] + U[:, 1:]), U[:, -1:]))  # at the nodes
    R = ff.rotation(q)
    k = np.array((1.0, p["b2"], p["c"]))[:, None]
    m = np.einsum("abm,bm->am", R, k * u)
    d3 = R[:, 2]
    r = np.hstack((np.zeros((3, 1)), np.cumsum(0.5 * (d3[:, :-1] + d3[:, 1:]) * np.diff(s),
                                               axis=1)))
    y = np.vstack((r, q, m))
    solved = solve_fixed(rod, State(s, y, rod.rhs(s, y, p), p), p, tol=1e-8, max_nodes=10000)
    assert solved.success, solved.message
    state = solved.state
    count = count_form(lambda pts: rod.second_variation(pts, state(pts), p), state.s)
    assert count.index == 0
    found = [eq for eq in enumerate_equilibria(rod, p)
             if np.max(np.abs(eq.state.y[7:10, 0] - state.y[7:10, 0])) < 1e-7]
    assert len(found) == 1 and found[0].index == 0


def test_a_run_file_with_landing_lands_the_spatial_rod(tmp_path, cli_exe, arms):
    """``landing = true`` on the spatial rod: the run's snap-back table marks the landings,
    ``snaps`` lists them (the same targets as the Python run's)."""
    toml = tmp_path / "arm3d.toml"
    toml.write_text('equation = "kirchhoff_lever_arm"\nstart = "trivial"\n[parameters]\n'
                    'eps = 0.25\nP = "pi^2/4"\nb2 = 2\n[continuation]\nparameter = "psi"\n'
                    'directions = "both"\nbounds = [-2, 2]\nlanding = true\n')
    proc = run_cli(cli_exe, "run", toml, "--out", tmp_path)
    assert proc.returncode == 0, proc.stderr
    proc = run_cli(cli_exe, "snaps", tmp_path / "arm3d.h5")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    marked = [ln.split() for ln in lines[1:] if len(ln.split()) > 3 and ln.split()[-3] == "<-"]
    landed = [r for r in arms["spatial"].snaps if r["landed"]]
    assert len(marked) == len(landed) >= 2
    for cols, r in zip(marked, landed):
        assert cols[0] == r["lp"]
        assert float(cols[-2]) == pytest.approx(r["energy_released"], rel=1e-4)


def test_the_damped_model_of_frames_lands_as_the_planar_ones(rod, planar, arms):
    """The damped model (c = 2, from rest; the frames' kinetic energy with the mass 4 M of
    the quaternions) from the first fold of each: the same target (m(0).e_z), its total
    energy non-increasing step by step."""
    ends = []
    for key, problem in (("planar", planar), ("spatial", rod)):
        branch = next(br for br in arms[key] if snap_lps(br))
        fold, side = snap_lps(branch)[0]
        equilibria = enumerate_equilibria(problem, fold.params)
        landing = land(problem, fold.state, fold.tangent, equilibria, "psi",
                       beyond_fold(branch, fold, side), damping=2.0)
        assert landing.target is not None
        assert np.all(np.diff(landing.energies) <= 1e-9 * abs(landing.energies[0]))
        ends.append(equilibria[landing.target].ordinates["m0"])
    assert ends[1] == pytest.approx(ends[0], abs=1e-7)
