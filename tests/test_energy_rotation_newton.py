"""Energy modules with a rotation coordinate whose density is not quadratic in the strains
(issue 47: the Legendre transform by Newton's method per point, Jacobians by the implicit
function theorem; docs/energy.md, "The SO(3) formulation"), against what is independent of the
derivation:

* rhs_jac and rhs_dp against central differences of rhs, at random states with |q| != 1: a
  bending law m = B u + k u^3 and a tendon's length |e3 + u x d| (an offset d across the
  section, as a tendon-driven robot's);
* the second variation against the finite-difference Hessian of the rod discretised
  independently (tests/rod_hessian.py: frames at the nodes, curvatures log(R_j^T R_(j+1)) / h,
  midpoint rules) at random frame fields, extrapolated from two meshes;
* a closed form: the column in space with the law m = B u + k u^3 buckles at Euler's loads
  (the cubic term leaves the linearisation alone), and its post-buckling branch has
  P - P_c = (P_c / 8 + (3/4) k (pi/2)^4) a^2 + O(a^4), a the tip's angle (derived in
  docs/energy.md, "A nonlinear bending law"), k = 0 giving the elastica's P_c a^2 / 8;
* a density not convex in the strains: one line, exit status 2 (tests/test_energy_loading.py).
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.model.second_variation import as_second_variation
from rod_hessian import expm, hessian, logm

HEAD = '''
import numpy as np


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param, Rotation
    s, P, b2, c, k, tau, d1, d2 = sp.symbols("s P b2 c k tau d1 d2", real=True)
    R = Rotation("R")
    x, y, z = (sp.Function(name)(s) for name in ("x", "y", "z"))
    u1, u2, u3 = R.strain
    tendon = sp.sqrt((u3 * d2) ** 2 + (u3 * d1) ** 2 + (1 + u1 * d2 - u2 * d1) ** 2)
    return Energy(density={density}, end1=P * z,
                  s=s, coordinates=[R], quadratures={{x: R.d3[0], y: R.d3[1], z: R.d3[2]}},
                  fixed0={{R: (1, 0, 0, 0), x: 0, y: 0, z: 0}},
                  parameters={{P: Param(0.0), b2: Param(2.0), c: Param(0.8), k: Param(0.5),
                               {extra}}})


def exact_start(s, p):
    """The straight column along e_z."""
    out = np.zeros((10, len(s)))
    out[0] = 1.0
    out[9] = s
    return out
'''

CUBIC = "(u1**2 + b2*u2**2 + c*u3**2)/2 + k*(u1**4 + u2**4)/4"
TENDON = "(u1**2 + b2*u2**2 + c*u3**2)/2 + k*u1**4/4 + tau*tendon"
MODELS = {"cubic": (CUBIC, ""),
          "tendon": (TENDON, "tau: Param(0.7), d1: Param(0.1), d2: Param(-0.15)")}


def _module(tmp_path, name):
    density, extra = MODELS[name]
    path = tmp_path / f"{name}_column.py"
    path.write_text(textwrap.dedent(HEAD.format(density=density, extra=extra)))
    return ea.load_problem(path)


@pytest.fixture(scope="module")
def cubic(tmp_path_factory):
    return _module(tmp_path_factory.mktemp("cubic"), "cubic")


@pytest.mark.parametrize("name", sorted(MODELS))
def test_the_jacobians_are_the_rhs_s_derivatives(tmp_path, name):
    """rhs_jac (the implicit function theorem through the Newton inverse, the frames and the
    body moment) and rhs_dp against central differences of rhs at random states, |q| != 1,
    random parameters; and the Newton inverse inverts the Legendre map: the momentum
    R dL/du at the strains it returns is the state's m."""
    problem = _module(tmp_path, name)
    rng = np.random.default_rng(5)
    s = np.linspace(0, 1, 9)
    for _ in range(3):
        y = rng.normal(size=(problem.n, len(s)))
        p = {key: value + rng.uniform(-0.2, 0.2) for key, value in problem.defaults().items()}
        p["P"] = rng.uniform(-3, 3)
        jac = problem.rhs_jac(s, y, p)
        d = 1e-6
        fd = np.array([(problem.rhs(s, y + d * e[:, None], p)
                        - problem.rhs(s, y - d * e[:, None], p)) / (2 * d)
                       for e in np.eye(problem.n)]).transpose(1, 0, 2)
        np.testing.assert_allclose(jac, fd, atol=1e-7 * (1 + np.abs(fd).max()))
        for key in p:
            up, down = {**p, key: p[key] + d}, {**p, key: p[key] - d}
            fd = (problem.rhs(s, y, up) - problem.rhs(s, y, down)) / (2 * d)
            np.testing.assert_allclose(problem.rhs_dp(s, y, p, key), fd,
                                       atol=1e-7 * (1 + np.abs(fd).max()), err_msg=key)
        # q' = q (x) (0, u) / 2 gives u; m_b = R^T m must be dL/du there
        q, m = y[:4], y[4:7]
        qn = q / np.linalg.norm(q, axis=0)
        dq = problem.rhs(s, y, p)[:4] / np.linalg.norm(q, axis=0)
        u = 2 * _hamilton(qn * np.array((1, -1, -1, -1))[:, None], dq)[1:]
        rot = _rotation(qn)
        mb = np.einsum("ijm,im->jm", rot, m)
        np.testing.assert_allclose(_moment(u, p, name), mb, atol=1e-10 * (1 + np.abs(mb).max()))


def _hamilton(a, b):
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array((a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 + a2 * b0 + a3 * b1 - a1 * b3, a0 * b3 + a3 * b0 + a1 * b2 - a2 * b1))


def _rotation(q):
    w, x, y, z = q / np.linalg.norm(q, axis=0)
    return np.array(((w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
                     (2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
                     (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z)))


def _moment(u, p, name):
    """dL/du of the models, written out by hand (not derived)."""
    u1, u2, u3 = u
    k = p["k"]
    if name == "cubic":
        return np.array((u1 + k * u1 ** 3, p["b2"] * u2 + k * u2 ** 3, p["c"] * u3))
    d1, d2, tau = p["d1"], p["d2"], p["tau"]
    t = np.array((-u3 * d2, u3 * d1, 1 + u1 * d2 - u2 * d1))
    length = np.linalg.norm(t, axis=0)
    # d|t|/du = (dt/du)^T t / |t|, dt/du1 = (0, 0, d2), dt/du2 = (0, 0, -d1), dt/du3 = (-d2, d1, 0)
    grad = np.array((d2 * t[2], -d1 * t[2], -d2 * t[0] + d1 * t[1])) / length
    return np.array((u1 + k * u1 ** 3, p["b2"] * u2, p["c"] * u3)) + tau * grad


def test_the_second_variation_is_the_hessian_of_a_discretised_rod(cubic):
    """d2E[w] of the derived second variation (the Newton inverse's strains inside) for random
    rotation fields w (w(0) = 0) at random frame fields, against w.H w, H the Hessian by
    central differences of the column discretised in this test (tests/rod_hessian.py's
    frames and midpoint rules, with the cubic law and the load), extrapolated from N = 100
    and 200 (second order): to a tenth of the discretisation's change (and 1e-7 relative)."""
    rng = np.random.default_rng(21)
    x, weights = np.polynomial.legendre.leggauss(60)
    gauss, weights = 0.5 * (x + 1), 0.5 * weights
    for _ in range(3):
        p = {**cubic.defaults(), "P": rng.uniform(-4, 4), "k": rng.uniform(0.1, 2),
             "b2": rng.uniform(0.5, 3), "c": rng.uniform(0.3, 2)}
        coef = rng.normal(size=(3, 4))

        def unit(s):
            q = coef[0][:, None] + coef[1][:, None] * s + coef[2][:, None] * s ** 2
            return q / np.sqrt(np.sum(q * q, axis=0))

        def state(s):
            s = np.asarray(s, dtype=float)
            q = unit(s)
            dq = unit(s + 1e-30j).imag / 1e-30
            u = 2 * _hamilton(np.vstack((q[0], -q[1:])), dq)[1:]
            m = np.einsum("ijm,jm->im", _rotation(q), _moment(u, p, "cubic"))
            return np.vstack((q * (1 + 0.3 * np.sin(2 * s)), m, np.zeros((3, len(s)))))

        a, b, c = rng.normal(size=(3, 3))

        def w(s):
            return np.outer(a, s) + np.outer(b, s ** 2) + np.outer(c, np.sin(3 * s))

        def dw(s):
            return np.outer(a, np.ones_like(s)) + np.outer(b, 2 * s) + \
                np.outer(c, 3 * np.cos(3 * s))
        form = as_second_variation(cubic.second_variation(gauss, state(gauss), p), "d")
        ends = as_second_variation(cubic.second_variation(np.linspace(0, 1, 5),
                                                          state(np.linspace(0, 1, 5)), p), "d")
        wg, dg = w(gauss), dw(gauss)
        integrand = (np.einsum("im,mij,jm->m", dg, form.A, dg)
                     + 2 * np.einsum("im,mij,jm->m", dg, form.C, wg)
                     + np.einsum("im,mij,jm->m", wg, form.B, wg))
        w1 = w(np.array([1.0]))[:, 0]
        exact = float(weights @ integrand + w1 @ ends.E1 @ w1)
        stiff = np.array((1.0, p["b2"], p["c"]))

        def interval(p, r0, r1, h):
            u = logm(np.swapaxes(r0, -1, -2) @ r1) / h
            bend = h * (0.5 * np.einsum("...i,i,...i->...", u, stiff, u)
                        + p["k"] * (u[..., 0] ** 4 + u[..., 1] ** 4) / 4)
            d3 = (r0 @ expm(0.5 * u * h))[..., 2, 2]
            return bend + h * p["P"] * d3                # + P z(1), z(1) = int d3.e_z

        class Frames:
            """What rod_hessian reads: the quaternions in rows 3:7, ``rotation``."""
            params = p
            rotation = staticmethod(_rotation)

            def __call__(self, s):
                return np.vstack((np.zeros((3, len(s))), state(s)[:4]))
        discrete = []
        for n in (100, 200):
            grid = np.linspace(0, 1, n + 1)[1:]
            wn = w(grid).T.ravel()
            # delta = 1e-5: the quartic term's fourth derivative, 6 k / h^3, makes the
            # differences' error delta^2 k / (2 h^3) per entry
            big = hessian(Frames, Frames(), n, delta=1e-5, interval=interval,
                          end=lambda p, r: 0.0)
            discrete.append(float(wn @ big @ wn))
        change = abs(discrete[1] - discrete[0])
        extrapolated = discrete[1] + (discrete[1] - discrete[0]) / 3
        assert abs(exact - extrapolated) <= 0.1 * change + 1e-7 * (1 + abs(exact))


@pytest.mark.parametrize("k", [0.0, 0.5])
def test_the_column_with_a_cubic_law_buckles_as_derived(cubic, k):
    """Continued in P from the straight column: branch points at Euler's loads B (pi/2)^2
    about both axes (2.4674 for B = 1, 4.9348 for b2 = 2) to 1e-8, the index counting the
    loads below P; on the branch switched at the first, P - P_c against 1 - z(1) = a^2/4 +
    O(a^4) (a the tip's angle; dE_dP = z(1)) has the slope 4 (P_c / 8 + (3/4) k (pi/2)^4)
    at a = 0 (a cubic fit near the branch point), to 1e-4."""
    main = ea.continuation(cubic, {"P": 0.0, "k": k}, "P", bounds=(0, 5.5))[0]
    bps = [pt.params["P"] for pt in main.points if pt.type == "BP"]
    pc = math.pi ** 2 / 4
    assert bps[:2] == pytest.approx([pc, 2 * pc], rel=1e-8)
    cols = main.columns
    for P, index in zip(cols["P"], cols["index"]):
        if min(abs(P - pc), abs(P - 2 * pc)) > 1e-6:
            assert index == int(P > pc) + int(P > 2 * pc)
    branches = ea.continuation(cubic, {"P": 0.0, "k": k}, "P", bounds=(0, 2.7), switch=1,
                               ds=0.01, ds_max=0.01)
    pts = np.array([(1 - z1, P) for br in branches[1:]
                    for z1, P in zip(br.columns["dE_dP"], br.columns["P"])])
    near = pts[pts[:, 0] < 0.01]
    assert len(near) > 20
    slope = np.polyfit(near[:, 0], near[:, 1], 3)[-2]
    assert slope == pytest.approx(4 * (pc / 8 + 0.75 * k * (math.pi / 2) ** 4), rel=1e-4)


def test_the_flow_of_frames_needs_no_inverse(cubic):
    """The gradient flow of the cubic column (its strains are the frames', no Legendre
    inverse): force = -grad E / mass against central differences of its energy."""
    p = {**cubic.defaults(), "P": 3.0}
    nodes = np.linspace(0, 1, 21)
    flow = cubic.gradient_flow(p, nodes)
    rng = np.random.default_rng(6)
    y = np.zeros((cubic.n, len(nodes)))
    y[:4] = rng.normal(size=(4, 1)) + 0.4 * rng.normal(size=(4, len(nodes))) * nodes
    u = flow.to_u(y)
    d = 1e-6
    grad = np.array([(flow.energy(u + d * e) - flow.energy(u - d * e)) / (2 * d)
                     for e in np.eye(len(u))])
    np.testing.assert_allclose(-flow.mass * flow.force(u), grad,
                               atol=1e-7 * (1 + np.abs(grad).max()))
