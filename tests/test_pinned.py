"""The pinned end (equations/elastica_pinned.py, docs/pinned-end.md), checked against facts the
module and the engine do not compute:

* a dead-load equilibrium of ``elastica_lever_arm``, found here by shooting, pinned at its own
  arm end, is an equilibrium of the pinned module with reaction n = the load;
* the first integral: (m + r x n).e_z = kappa + x n_y - y n_x is constant along s;
* the constrained index against a dense finite-difference count (the quadratic form projected
  on the null space of the discretised constraints) and against spectra known in closed form;
* the fold rule with the ordinates m1 (psi) and m0 (theta0) against the direct count along
  small runs; with the ordinate's sign flipped, or the constraints dropped, they disagree;
* the mirror symmetry (x, theta, n_x, psi, X) -> -(x, theta, n_x, psi, X).

The second variation, derived again here from the Lagrangian L = int kappa^2/2 - n . (r(1) +
a - R), r(1) = int (-sin theta, cos theta), a = eps (sin u, cos u), u = psi - theta(1): for
h = delta theta with h(0) = 0, Q[h] = int h'^2 + (n_y cos theta - n_x sin theta) h^2 + (n . a)
h(1)^2, restricted to delta(r(1) + a) = int (-cos theta, -sin theta) h + eps (-cos u, sin u)
h(1) = 0.
"""

from __future__ import annotations

import math
import types

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicHermiteSpline
from scipy.linalg import null_space
from scipy.optimize import brentq

import elastica_auto as ea
from elastica_auto import SecondVariation
from elastica_auto.numerics import stability
from elastica_auto.branches.branch import PROFILE_GRID
from elastica_auto.model.problem import load_problem
from elastica_auto.core.solution import State

STOP = ["n_abs > 80"]          # past the first fold of each direction


@pytest.fixture(scope="module")
def pinned():
    return load_problem("elastica_pinned")


@pytest.fixture(scope="module")
def psi_run(pinned):
    return ea.continuation(pinned, {"eps": 0.25}, "psi", directions="both", stop=STOP,
                           bounds=(-4 * math.pi, 4 * math.pi), ds=0.05, ds_max=0.5)


@pytest.fixture(scope="module")
def theta0_run(pinned):
    return ea.continuation(pinned, {"eps": 0.25}, "theta0", directions="both", stop=STOP,
                           bounds=(-4 * math.pi, 4 * math.pi), ds=0.05, ds_max=0.5)


def _points(branches):
    for br in branches:
        for k, pt in enumerate(br.points):
            yield br, k, pt


# ---- 1. the equations: a dead-load equilibrium pinned at its arm end ---------------------

def _dead_load_equilibrium(P, eps, psi, alpha):
    """theta'(0) of a buckled dead-load equilibrium (theta0 = 0) by shooting and Brent's
    method on kappa(1) + eps P sin(psi + alpha - theta(1)), and the solution on s."""
    def f(s, y):
        return [y[1], -P * math.sin(y[0] - alpha), -math.sin(y[0]), math.cos(y[0])]

    def end(k):
        return solve_ivp(f, (0, 1), [0, k, 0, 0], rtol=1e-12, atol=1e-12, dense_output=True)

    def residual(k):
        yb = end(k).y[:, -1]
        return yb[1] + eps * P * math.sin(psi + alpha - yb[0])

    ks = np.linspace(-10.1, 10, 41)
    r = [residual(k) for k in ks]
    i = next(i for i in range(len(ks) - 1) if r[i] * r[i + 1] < 0)
    k = brentq(residual, ks[i], ks[i + 1], xtol=1e-14)
    return end(k)


@pytest.mark.parametrize("P, eps, psi, alpha", [(math.pi ** 2 / 4, 0.25, 0.0, 0.0),
                                                (9 * math.pi ** 2 / 4, 0.5, 0.7, 0.3)])
def test_dead_load_equilibrium_pinned_at_its_arm_end_is_an_equilibrium(pinned, P, eps, psi,
                                                                         alpha):
    sol = _dead_load_equilibrium(P, eps, psi, alpha)
    s = np.linspace(0, 1, 41)
    y4 = sol.sol(s)
    t1, x1, y1 = y4[0, -1], y4[2, -1], y4[3, -1]
    pin = (x1 + eps * math.sin(psi - t1), y1 + eps * math.cos(psi - t1))
    n = P * np.array((math.sin(alpha), -math.cos(alpha)))
    # the reaction n: the pin's multipliers, free parameters
    p = {"eps": eps, "psi": psi, "theta0": 0.0, "X": pin[0], "Y": pin[1], "nx": n[0],
         "ny": n[1]}
    assert np.max(np.abs(pinned.bc(y4[:, 0], y4[:, -1], p))) < 1e-8
    dead = load_problem("elastica_lever_arm")
    want = dead.rhs(s, y4, {"P": P, "eps": eps, "psi": psi, "alpha": alpha, "theta0": 0.0})
    np.testing.assert_allclose(pinned.rhs(s, y4, p), want, rtol=0, atol=1e-12)


def test_guess_is_solved_to_an_equilibrium_with_a_compressive_reaction(psi_run):
    start = psi_run[0].points[0]
    assert start.index == 0
    n = np.array((start.ordinates["n_x"], start.ordinates["n_y"]))
    assert n[1] < 0 and 10 < np.hypot(*n) < 30


# ---- 2. the first integral ---------------------------------------------------------------

def test_moment_about_the_clamp_is_constant_along_s(psi_run, theta0_run):
    checked = 0
    for br, k, pt in _points(list(psi_run) + list(theta0_run)):
        th, kap, x, y, nx, ny = pt.profile
        first = kap + x * ny - y * nx
        scale = 1 + np.max(np.abs(kap))
        assert np.ptp(first) < 1e-6 * scale, (br.number, k, np.ptp(first))
        # and at s = 1 it is the moment of n about the clamp through the pin: kappa(1) =
        # (a x n).e_z, so first = ((r(1) + a) x n).e_z = X n_y - Y n_x
        want = pt.params["X"] * ny[0] - pt.params["Y"] * nx[0]
        assert first[-1] == pytest.approx(want, abs=1e-6 * scale)
        checked += 1
    assert checked > 200


# ---- 3. the constrained index ------------------------------------------------------------

def _form(theta, p, n):
    """(b(s), c, [(g_i(s), d_i)]) of the module docstring, from the Lagrangian (above)."""
    nx, ny = n
    t1 = float(theta(1.0))
    u = p["psi"] - t1
    a = p["eps"] * np.array((math.sin(u), math.cos(u)))
    da = p["eps"] * np.array((-math.cos(u), math.sin(u)))       # d a / d theta(1)
    return (lambda s: ny * np.cos(theta(s)) - nx * np.sin(theta(s)), float(a @ n),
            [(lambda s: -np.cos(theta(s)), da[0]), (lambda s: -np.sin(theta(s)), da[1])])


def dense_count(b, c, constraints, size=150):
    """(negative eigenvalues, smallest |eigenvalue|) of Q[h] = int h'^2 + b h^2 + c h(1)^2,
    h(0) = 0, restricted by int g_i h + d_i h(1) = 0: second differences on ``size`` nodes,
    the trapezoidal rule, in the mass-scaled unknowns v = sqrt(w) h, projected on the null
    space of the constraints (without ``constraints``: the unrestricted count)."""
    dx = 1.0 / size
    s = np.arange(1, size + 1) * dx
    w = np.full(size, dx)
    w[-1] = dx / 2
    q = (np.diag(np.full(size, 2.0)) - np.diag(np.ones(size - 1), 1)
         - np.diag(np.ones(size - 1), -1)) / dx
    q[-1, -1] = 1.0 / dx
    q += np.diag(w * b(s))
    q[-1, -1] += c
    scale = 1 / np.sqrt(w)
    q = scale[:, None] * q * scale[None, :]
    if constraints:
        rows = np.array([w * g(s) + d * (np.arange(size) == size - 1)
                         for g, d in constraints]) * scale
        z = null_space(rows)
        q = z.T @ q @ z
    mu = np.linalg.eigvalsh(q)
    return int(np.sum(mu < 0)), float(np.min(np.abs(mu)))


def _random_states(pinned, count, seed=20261202):
    """Smooth theta(s) = sum_k a_k sin(k pi s / 2) (theta0 = 0), random n with |n_x|, |n_y| <= 100,
    eps in [-0.6, 0.6], psi in [0, 2 pi): not equilibria, Q is a quadratic form for any."""
    rng = np.random.default_rng(seed)
    k = np.arange(1, 6)
    for _ in range(count):
        a = rng.normal(0, 1.5, 5) / k
        n = rng.uniform(-100, 100, 2)
        p = {**pinned.defaults(), "eps": rng.uniform(-0.6, 0.6),
             "psi": rng.uniform(0, 2 * math.pi), "nx": n[0], "ny": n[1]}

        def theta(s, a=a):
            return a @ np.sin(np.outer(k, np.atleast_1d(s)) * math.pi / 2)[:, ...].reshape(
                5, -1) if np.ndim(s) else float(a @ np.sin(k * s * math.pi / 2))

        mesh = np.linspace(0, 1, 201)
        dth = (a * k * math.pi / 2) @ np.cos(np.outer(k, mesh) * math.pi / 2)
        y = np.vstack((theta(mesh), dth, np.zeros((2, len(mesh)))))
        yield theta, p, n, State.from_values(pinned, mesh, y, p)


def test_constrained_index_matches_a_dense_projected_count(pinned):
    compared, changed, counts = 0, 0, []
    for theta, p, n, state in _random_states(pinned, 30):
        b, c, cons = _form(theta, p, n)
        expected, gap = dense_count(b, c, cons)
        if gap < 1.0:       # second differences on 150 nodes: eigenvalue errors < 0.1
            continue
        compared += 1
        got = stability.index(pinned, state)
        assert got == expected, (p, n, got, expected)
        free, _ = dense_count(b, c, [])
        changed += free != expected
        counts.append(expected)
    assert compared >= 20
    # not degenerate: several indices, and the constraints change the count often
    assert len(set(counts)) >= 3 and changed >= compared // 4, (counts, changed)


def test_constrained_index_matches_the_dense_count_on_the_run(pinned, psi_run, theta0_run):
    compared = 0
    for br, k, pt in _points(list(psi_run) + list(theta0_run)):
        if k % 20:
            continue
        theta = CubicHermiteSpline(PROFILE_GRID, pt.profile[0], pt.profile[1])
        n = pt.profile[4:, 0]
        expected, gap = dense_count(*_form(theta, pt.params, n))
        if gap < 1.0:
            continue
        assert pt.index_direct == expected, (br.number, k, pt.index_direct, expected)
        compared += 1
    assert compared >= 12


class _Hook:
    """A stand-in problem whose second variation is b = -beta^2, c = 0 with given constraints:
    eigenfunctions sin((j - 1/2) pi s), eigenvalues ((j - 1/2) pi)^2 - beta^2."""
    has_second_variation = True

    def __init__(self, beta, constraints):
        self.beta, self.constraints = beta, constraints

    def second_variation(self, s, y, p):
        return 1.0, -self.beta ** 2, 0.0, [(g(s), d) for g, d in self.constraints]


def _mode(j):
    return lambda s: np.sin((j - 0.5) * math.pi * s)


@pytest.mark.parametrize("constraints, expected", [
    ([], 2),                                    # (pi/2)^2, (3 pi/2)^2 < 25 < (5 pi/2)^2
    ([(_mode(1), 0.0)], 1),                     # orthogonal to the first mode
    ([(_mode(1), 0.0), (_mode(2), 0.0)], 0),    # to both negative modes
    ([(_mode(3), 0.0)], 2),                     # to a positive mode: nothing removed
    ([(lambda s: 0 * s, 1.0)], 1),              # h(1) = 0: sin(j pi s), pi^2 < 25 < 4 pi^2
    ([(_mode(1), 0.0), (_mode(3), 0.0)], 1),
])
def test_constrained_index_with_known_spectra(pinned, constraints, expected):
    mesh = np.linspace(0, 1, 41)
    state = State.from_values(pinned, mesh, np.zeros((4, len(mesh))), pinned.defaults())
    assert stability.index(_Hook(5.0, constraints), state) == expected
    # the dense count agrees (its own check)
    cons = [(g, d) for g, d in constraints]
    assert dense_count(lambda s: -25.0 + 0 * s, 0.0, cons)[0] == expected


# ---- 4. the fold rule with m1 and m0 -----------------------------------------------------

@pytest.mark.parametrize("run", ["psi_run", "theta0_run"])
def test_fold_rule_and_direct_count_agree(run, request, pinned):
    branches = request.getfixturevalue(run)
    folds = 0
    for br, k, pt in _points(branches):
        assert pt.index >= 0 and not pt.note, (br.number, k, pt.note)
        assert pt.index_rule == pt.index
        if pt.type == "LP":
            folds += 1
        else:
            assert pt.index_direct == pt.index
    assert folds >= 2
    # at every fold the sign rule on the ordinate gives the direct count's change, and with
    # the ordinate's sign flipped the opposite one (teeth)
    name = branches[0].parameter
    ordinate = next(o for o in pinned.ordinates.values() if o.parameter == name).name
    enters = pinned.parameters[name].enters
    for br in branches:
        lam, ords = br.column(name), br.column(ordinate)
        direct = br.column("index_direct")
        for k in np.flatnonzero(br.column("type") == "LP"):
            change = direct[k + 1] - direct[k - 1]
            assert abs(change) == 1
            assert stability.fold_sign(enters, lam, ords, k) == change
            assert stability.fold_sign(enters, lam, -ords, k) == -change


def test_without_the_constraints_the_direct_count_differs(psi_run):
    """The pin matters: the unconstrained count (the dead-load form with n as the load) is
    larger than the constrained one on much of the run, so the agreement above is not that
    of the unconstrained problem."""
    base = load_problem("elastica_pinned")

    def unconstrained(s, y, p):
        form = base.second_variation(s, y, p)        # (its fields are (m, k, k))
        return SecondVariation(form.A[:, 0, 0], form.B[:, 0, 0], form.C[:, 0, 0],
                               E0=form.E0, E1=form.E1, fixed0=[0])
    loose = types.SimpleNamespace(has_second_variation=True,
                                  second_variation=unconstrained)
    differ = total = 0
    for br, k, pt in _points(psi_run):
        if k % 5:
            continue
        state = State.from_values(base, PROFILE_GRID, pt.profile[:4], pt.params)
        total += 1
        differ += stability.index(loose, state) > pt.index_direct
    assert differ >= total // 4, (differ, total)


# ---- 5. mirror symmetry ------------------------------------------------------------------

def test_mirror_image_solves_the_mirrored_problem(pinned, psi_run):
    """(theta, kappa, x, n_x) -> -(...), psi -> -psi, X -> -X maps solutions to solutions
    with m1 -> -m1 and the same index; along the run (X = 0) the mirror images of the
    points are points of the branch (psi, m1) -> (-psi, -m1) of the mirrored start."""
    sign = np.array((-1, -1, -1, 1))[:, None]
    for br, k, pt in _points(psi_run):
        if k % 7:
            continue
        y = pt.profile[:4] * sign
        p = {**pt.params, "psi": -pt.params["psi"], "X": -pt.params["X"],
             "nx": -pt.params["nx"]}
        assert np.max(np.abs(pinned.bc(y[:, 0], y[:, -1], p))) < 1e-7
        np.testing.assert_allclose(pinned.rhs(PROFILE_GRID, y, p),
                                   sign * pinned.rhs(PROFILE_GRID, pt.profile[:4], pt.params),
                                   atol=1e-12)
        a = stability.index(pinned, State.from_values(pinned, PROFILE_GRID, pt.profile[:4],
                                                      pt.params))
        b = stability.index(pinned, State.from_values(pinned, PROFILE_GRID, y, p))
        assert a == b


def test_mirrored_pin_gives_the_mirrored_branch(pinned):
    """At X = +-0.1 the psi-branches from the mirror-image starts are mirror images."""
    out = []
    for x in (0.1, -0.1):
        start = ea.continuation(pinned, {"X": x}, "psi", directions="+", max_points=2)[0]
        out.append(start.points[0])
    assert out[0].ordinates["n_x"] == pytest.approx(-out[1].ordinates["n_x"], abs=1e-8)
    one, two = (ea.continuation(pinned, {"X": x}, "psi", directions=d, max_points=40,
                                ds=0.05, ds_max=0.5)[0] for x, d in ((0.1, "+"), (-0.1, "-")))
    psi1, m1 = one.column("psi"), one.column("m1")
    psi2, m2 = two.column("psi"), two.column("m1")
    assert len(psi1) == len(psi2) == 40
    np.testing.assert_allclose(psi2, -psi1, atol=1e-7)
    np.testing.assert_allclose(m2, -m1, atol=1e-6 * (1 + np.max(np.abs(m1))))
    np.testing.assert_array_equal(one.column("index"), two.column("index"))
