"""End-loaded planar elastica with a rigid lever arm (nondimensional: K = l = 1), written as its
energy (docs/energy.md; the model: docs/design.md, "The elastica with a lever arm").

A rod clamped at s = 0 (turned by theta0) carries a rigid arm of length eps welded to its tip
at the angle psi (clockwise from the tip tangent), and a dead load F = P (sin alpha,
-cos alpha) at the arm's end. theta is the tangent angle from the vertical, the centreline
(x, y) the quadratures x' = -sin theta, y' = cos theta, and the load's potential -F.r_A is an
end term at s = 1, linear in x(1), y(1)::

    E[theta] = int_0^1 theta'^2 / 2 ds - F.(r(1) + eps (sin(psi - theta(1)), cos(psi - theta(1)))),
    theta(0) = theta0,  x(0) = y(0) = 0.

Derived from it (`load_problem`, `elastica-auto derive`): the states ``[theta, kappa, x, y]``
(kappa = theta', the bending moment m.e_z), the system theta' = kappa, kappa' = -P sin(theta -
alpha), x' = -sin theta, y' = cos theta, the free end's natural condition kappa(1) + eps P
sin(psi + alpha - theta(1)) = 0, their Jacobians, the second variation int (h'^2 - P cos(theta
- alpha) h^2) ds - eps P cos(psi + alpha - theta(1)) h(1)^2 on h(0) = 0, where each parameter
enters (P and alpha only in the end term: ``"free"``, as the paper has them; theta0 only in
the essential value: ``"fixed"``), the distinguished ordinates named as the paper names them
(gamma = dE/dP, beta = dE/deps, m1 = dE/dpsi, mA = dE/dalpha and the clamp's reaction m0 =
-dE/dtheta0 = kappa(0)) and the energy E.

By hand, what the energy does not say: the straight start, the mirror x -> -x, the shooting
scan, the drawing (shared with the modules of this rod under other end conditions), and the
gradient flow: the paper's landings were computed with its trapezoidal potential (the derived
flow, the midpoint rule, lands on the same equilibria, its released energies within the
discretisation: tests/test_energy_loading.py). The hand-written module this one replaces is
tests/reference/elastica_lever_arm.py.
"""

import math

import numpy as np

from elastica_auto import Flow, Mirror
from elastica_auto.energy import derived_names

def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s = sp.Symbol("s", real=True)
    P, eps, psi, alpha, theta0 = sp.symbols("P eps psi alpha theta0", real=True)
    theta, x, y = (sp.Function(name)(s) for name in ("theta", "x", "y"))
    load = sp.Matrix([P * sp.sin(alpha), -P * sp.cos(alpha)])
    arm_end = sp.Matrix([x, y]) + eps * sp.Matrix([sp.sin(psi - theta), sp.cos(psi - theta)])
    angle = dict(period=2 * sp.pi)
    return Energy(
        density=theta.diff(s) ** 2 / 2,
        end1=-(load.T * arm_end)[0],
        s=s, coordinates=[theta], momenta={theta: "kappa"},
        quadratures={x: -sp.sin(theta), y: sp.cos(theta)},
        fixed0={theta: theta0, x: 0, y: 0},
        parameters={
            P: Param(sp.pi ** 2 / 4, "P", ordinate="gamma",
                     doc="load |F| l^2 / K; negative reverses F"),
            eps: Param(0.25, r"\epsilon", ordinate="beta",
                       doc="lever-arm length / l; negative flips it"),
            psi: Param(0.0, r"\psi", ordinate="m1", **angle,
                       doc="arm angle to the tip tangent, clockwise"),
            alpha: Param(0.0, r"\alpha", ordinate="mA", **angle,
                         doc="load direction from the vertical"),
            theta0: Param(0.0, r"\theta_0", ordinate="m0", period_shift={theta: 2 * sp.pi},
                          doc="rotation of the clamp", **angle),
        })


#: Imported as a Python module, the derived names (rhs, second_variation, PARAMETERS, ...)
#: on first use; `load_problem` gives them itself.
__getattr__ = derived_names(__name__)


#: The reflection x -> -x of the plane: theta -> -theta turns the rod, its arm, the clamp and
#: the load into their mirror images (psi, alpha, theta0 -> their negatives), kappa = theta'
#: and x = -int sin(theta) with them; the moments m1, mA and m0 change sign, beta, gamma and
#: the energy E do not; the shooting unknown theta'(0) changes sign.
MIRROR = Mirror({"theta": "-theta", "kappa": "-kappa", "x": "-x"}, ("psi", "alpha", "theta0"),
                ("m1", "mA", "m0"), shooting=(-1,))


def exact_start(s, p):
    """The straight rod theta = theta0 along the load line, exact when theta0 = alpha and
    sin(psi) = 0 (mod 2 pi); None otherwise. Both to 1e-12: a fold located at psi = 5e-13
    (the fold curves' meeting with the critical loads) is on the straight rod, whose end
    moment residual eps P sin(psi) is then far below every tolerance."""
    if (abs(math.remainder(p["theta0"] - p["alpha"], 2 * math.pi)) > 1e-12
            or abs(math.sin(p["psi"])) > 1e-12):
        return None
    t = p["theta0"]
    return np.vstack((np.full_like(s, t), np.zeros_like(s), -s * math.sin(t), s * math.cos(t)))


def shooting(p):
    """Equilibria are the roots k = theta'(0) of the free-end residual kappa(1) + eps P
    sin(psi + alpha - theta(1)). The first integral kappa^2/2 - P cos(theta - alpha) = const
    and |kappa(1)| <= |eps P| bound |k| <= sqrt((eps P)^2 + 4 |P|) (docs/design.md,
    "Searching for the equilibria")."""
    bound = math.sqrt((p["eps"] * p["P"]) ** 2 + 4 * abs(p["P"]))

    def initial(k):
        k = np.asarray(k, dtype=float)
        return np.vstack((np.full_like(k, p["theta0"]), k, np.zeros_like(k), np.zeros_like(k)))

    def residual(ya, yb):
        return yb[1] + p["eps"] * p["P"] * np.sin(p["psi"] + p["alpha"] - yb[0])

    return -bound, bound, initial, residual


def gradient_flow(p, nodes):
    """The overdamped dynamics theta_t = -dE/dtheta = theta'' + P sin(theta - alpha) with
    theta(0) = theta0 and the free-end condition theta'(1) + eps P sin(psi + alpha - theta(1))
    = 0, by the method of lines on ``nodes`` (for `elastica_auto.analysis.landing`).

    u is theta at the nodes s_1..s_N (theta_0 = theta0 is clamped). The energy of the
    docstring, discretised with differences for kappa and the trapezoidal rule::

        E_h(u) = sum_j (theta_{j+1} - theta_j)^2 / (2 h_j) + sum_j w_j P cos(theta_j - alpha)
                 + eps P cos(psi + alpha - theta_N),

    w_j the trapezoidal weights (the lumped mass), and u_t = -grad E_h / w: at interior
    nodes of a uniform grid, (theta_{j+1} - 2 theta_j + theta_{j-1}) / h^2 + P sin(theta_j -
    alpha); at s = 1 the end condition enters through the half cell, second-order accurate.
    Its equilibria are the second-order finite-difference solutions of the BVP."""
    from scipy.sparse import diags

    from elastica_auto import trapezoid_weights
    h = np.diff(nodes)
    weights = trapezoid_weights(nodes)
    w = weights[1:]
    big_p, a, eps, t0 = p["P"], p["alpha"], p["eps"], p["theta0"]

    def full(u):
        return np.concatenate(([t0], u))

    def energy(u):
        th = full(u)
        return float(np.sum(np.diff(th) ** 2 / (2 * h))
                     + np.sum(weights * big_p * np.cos(th - a))
                     + eps * big_p * np.cos(p["psi"] + a - th[-1]))

    def gradient(u):
        th = full(u)
        flux = np.diff(th) / h                     # theta' on each interval
        g = -w * big_p * np.sin(u - a)
        g += flux
        g[:-1] -= flux[1:]
        g[-1] += eps * big_p * np.sin(p["psi"] + a - u[-1])
        return g

    def jacobian(u):
        d = 1 / h + np.append(1 / h[1:], 0.0) - w * big_p * np.cos(u - a)
        d[-1] -= eps * big_p * np.cos(p["psi"] + a - u[-1])
        off = -1 / h[1:]
        return -diags([off / w[1:], d / w, off / w[:-1]], [-1, 0, 1], format="csc")

    return Flow(nodes, lambda y: np.asarray(y)[0, 1:], w, energy, lambda u: -gradient(u) / w,
                jacobian)


#: Colours and sizes of the drawn configurations.
ROD_COLOR, ARM_COLOR, LOAD_COLOR, CLAMP_COLOR = "black", "#555555", "#e66101", "0.2"
LINE_WIDTH, CLAMP_HALF_WIDTH, ARROW_LENGTH = 1.4, 0.16, 0.42


def arm_end(profile, p):
    """The end of the lever arm (where the load acts) of a profile ``[theta, kappa, x, y,
    ...]`` on the grid (n, m): the arm leaves the tip at angle theta(1) - psi from the
    vertical."""
    theta1, x1, y1 = profile[0, -1], profile[2, -1], profile[3, -1]
    return np.array((x1 + p["eps"] * np.sin(p["psi"] - theta1),
                     y1 + p["eps"] * np.cos(p["psi"] - theta1)))


def draw(ax, profile, p):
    """Draw the configuration on ``ax``: the clamp (hatched, turned by theta0), the centreline,
    the lever arm and the load arrow F = P (sin alpha, -cos alpha) ending at the arm's end."""
    _, end = draw_rod(ax, profile, p)
    ax.plot(*end, "o", ms=LINE_WIDTH * 1.8, color=ARM_COLOR, zorder=5)
    if p["P"] != 0:
        a = p["alpha"]
        draw_force(ax, end, np.sign(p["P"]) * np.array((np.sin(a), -np.cos(a))), "load")


def draw_rod(ax, profile, p):
    """The clamp (hatched, turned by theta0), the centreline and the lever arm of ``profile``
    (rows theta, kappa, x, y, ...) on ``ax``; the rod's tip and the arm's end. Shared with
    the modules of this rod under other end conditions (elastica_pinned)."""
    t0 = p["theta0"]
    tangent = np.array((-np.sin(t0), np.cos(t0)))
    normal = np.array((np.cos(t0), np.sin(t0)))
    wall = np.outer(normal, (-CLAMP_HALF_WIDTH, CLAMP_HALF_WIDTH))
    ax.plot(wall[0], wall[1], color=CLAMP_COLOR, lw=LINE_WIDTH * 0.9, solid_capstyle="butt",
            zorder=3)
    for u in np.linspace(-CLAMP_HALF_WIDTH, CLAMP_HALF_WIDTH, 5):
        a = u * normal
        b = a - 0.09 * tangent - 0.07 * normal
        ax.plot((a[0], b[0]), (a[1], b[1]), color="0.35", lw=0.6, zorder=3)
    x, y = profile[2], profile[3]
    tip, end = np.array((x[-1], y[-1])), arm_end(profile, p)
    ax.plot(x, y, color=ROD_COLOR, lw=LINE_WIDTH, zorder=4, solid_capstyle="round", gid="rod")
    ax.plot((tip[0], end[0]), (tip[1], end[1]), color=ARM_COLOR, lw=LINE_WIDTH * 0.7, zorder=4,
            solid_capstyle="round", gid="lever arm")
    ax.plot(*tip, "o", ms=LINE_WIDTH * 1.3, color=ROD_COLOR, zorder=5)
    return tip, end


def draw_force(ax, head, direction, gid: str):
    """A force on ``ax``: an arrow along ``direction`` ending at ``head``, its length
    ARROW_LENGTH whatever the force's size."""
    tail = head - ARROW_LENGTH * np.asarray(direction) / np.hypot(*direction)
    ax.annotate("", xy=head, xytext=tail, zorder=6, gid=gid,
                arrowprops=dict(arrowstyle="-|>", color=LOAD_COLOR, lw=LINE_WIDTH * 0.75,
                                mutation_scale=6 + 2 * LINE_WIDTH, shrinkA=0,
                                shrinkB=LINE_WIDTH * 1.2))
    ax.update_datalim([tail])
