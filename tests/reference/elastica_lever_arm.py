"""End-loaded planar elastica with a rigid lever arm (nondimensional: K = l = 1).

State ``[theta, kappa, x, y]`` on s in [0, 1]; theta is the tangent angle from the vertical,
kappa = theta' the bending moment m.e_z, (x, y) the centreline. Moment balance, with the
contact force n equal to the load F = P (sin alpha, -cos alpha)::

    theta' = kappa,  kappa' = -P sin(theta - alpha),  x' = -sin theta,  y' = cos theta.

Clamp: theta(0) = theta0, x(0) = y(0) = 0. Free end (moment balance of the lever arm)::

    kappa(1) + eps P sin(psi + alpha - theta(1)) = 0.

The lever arm points at angle theta(1) - psi from the vertical (psi measured clockwise from
the tip tangent). Reduced energy, whose Euler-Lagrange equations are the system above::

    E[theta] = int_0^1 (kappa^2/2 + P cos(theta - alpha)) ds + eps P cos(psi + alpha - theta(1)).

P and alpha appear in the reduced ODE, but in the paper's formulation (positions with Lagrange
multipliers n) they enter only the free-end term, so they are declared ``enters="free"``.

``draw`` draws a configuration for the figures: clamp, centreline, lever arm and load.
"""

import math

import numpy as np

from elastica_auto import Flow, Mirror, Ordinate, Parameter

STATES = ("theta", "kappa", "x", "y")

PARAMETERS = [
    Parameter("P", math.pi ** 2 / 4, r"P", "free", doc="load |F| l^2 / K; negative reverses F"),
    Parameter("eps", 0.25, r"\epsilon", "free", doc="lever-arm length / l; negative flips it"),
    Parameter("psi", 0.0, r"\psi", "free", period=2 * math.pi,
              doc="arm angle to the tip tangent, clockwise"),
    Parameter("alpha", 0.0, r"\alpha", "free", period=2 * math.pi,
              doc="load direction from the vertical"),
    Parameter("theta0", 0.0, r"\theta_0", "fixed", period=2 * math.pi,
              period_shift={"theta": 2 * math.pi}, doc="rotation of the clamp"),
]


def _arm_angle(yb, p):
    """psi + alpha - theta(1), the angle in the free-end moment eps P sin(.)."""
    return p["psi"] + p["alpha"] - yb[0]


def rhs(s, y, p):
    """theta' = kappa, kappa' = -P sin(theta - alpha), x' = -sin theta, y' = cos theta,
    filled row by row (np.vstack of the rows costs twice as much at the engine's sizes)."""
    theta = y[0]
    out = np.empty(y.shape)
    out[0] = y[1]
    out[1] = -p["P"] * np.sin(theta - p["alpha"])
    out[2] = -np.sin(theta)
    out[3] = np.cos(theta)
    return out


def rhs_jac(s, y, p):
    theta = y[0]
    jac = np.zeros((4, 4, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -p["P"] * np.cos(theta - p["alpha"])
    jac[2, 0] = -np.cos(theta)
    jac[3, 0] = -np.sin(theta)
    return jac


def rhs_dp(s, y, p, name):
    out = np.zeros_like(y)
    if name == "P":
        out[1] = -np.sin(y[0] - p["alpha"])
    elif name == "alpha":
        out[1] = p["P"] * np.cos(y[0] - p["alpha"])
    return out


def bc(ya, yb, p):
    return np.array((ya[0] - p["theta0"], ya[2], ya[3],
                     yb[1] + p["eps"] * p["P"] * np.sin(_arm_angle(yb, p))))


def bc_jac(ya, yb, p):
    da = np.zeros((4, 4))
    db = np.zeros((4, 4))
    da[0, 0] = da[1, 2] = da[2, 3] = 1.0
    db[3, 1] = 1.0
    db[3, 0] = -p["eps"] * p["P"] * np.cos(_arm_angle(yb, p))
    return da, db


def bc_dp(ya, yb, p, name):
    out = np.zeros(4)
    a = _arm_angle(yb, p)
    if name == "theta0":
        out[0] = -1.0
    elif name == "eps":
        out[3] = p["P"] * np.sin(a)
    elif name == "P":
        out[3] = p["eps"] * np.sin(a)
    elif name in ("psi", "alpha"):
        out[3] = p["eps"] * p["P"] * np.cos(a)
    return out


def _m1(s, y, p):
    return y[1, -1]


def _beta(s, y, p):
    return p["P"] * np.cos(_arm_angle(y[:, -1], p))


def _m_alpha(s, y, p):
    x1, y1, a = y[2, -1], y[3, -1], p["alpha"]
    return y[1, -1] - p["P"] * (x1 * np.cos(a) + y1 * np.sin(a))


def _gamma(s, y, p):
    x1, y1, a = y[2, -1], y[3, -1], p["alpha"]
    return -x1 * np.sin(a) + y1 * np.cos(a) + p["eps"] * np.cos(_arm_angle(y[:, -1], p))


def _m0(s, y, p):
    return y[1, 0]


ORDINATES = [
    Ordinate("m1", r"$m(1)\cdot e_z$", _m1, "psi", "tip moment kappa(1); ordinate for psi"),
    Ordinate("beta", r"$\beta$", _beta, "eps", "P cos(psi + alpha - theta(1)); ordinate for eps"),
    Ordinate("mA", r"$(m + r\times n)\cdot e_z$", _m_alpha, "alpha",
             "kappa(1) - P (x(1) cos alpha + y(1) sin alpha) = kappa(0); ordinate for alpha"),
    Ordinate("gamma", r"$\gamma$", _gamma, "P",
             "-x(1) sin alpha + y(1) cos alpha + eps cos(alpha + psi - theta(1)); ordinate for P"),
    Ordinate("m0", r"$m(0)\cdot e_z$", _m0, "theta0", "clamp moment kappa(0); ordinate for theta0"),
]

#: The reflection x -> -x of the plane: theta -> -theta turns the rod, its arm, the clamp and
#: the load into their mirror images (psi, alpha, theta0 -> their negatives), kappa = theta'
#: and x = -int sin(theta) with them; the moments m1, mA and m0 change sign, beta and gamma
#: (cosines of mirrored angles) do not; the shooting unknown theta'(0) changes sign.
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


def second_variation(s, y, p):
    """delta^2 E[h] = int_0^1 (h'^2 - P cos(theta - alpha) h^2) ds - eps P cos(psi + alpha -
    theta(1)) h(1)^2 with h(0) = 0 (docs/design.md, "Second variation and the natural end
    condition"): a = 1, b = -P cos(theta - alpha), c = -eps P cos(psi + alpha - theta(1));
    natural end condition h'(1) = eps P cos(.) h(1)."""
    return (1.0, -p["P"] * np.cos(y[0] - p["alpha"]),
            -p["eps"] * p["P"] * np.cos(_arm_angle(y[:, -1], p)))


def shooting(p):
    """Equilibria are the roots k = theta'(0) of the free-end residual kappa(1) + eps P
    sin(psi + alpha - theta(1)). The first integral kappa^2/2 - P cos(theta - alpha) = const
    and |kappa(1)| <= |eps P| bound |k| <= sqrt((eps P)^2 + 4 |P|) (docs/design.md,
    "Enumerating all equilibria")."""
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
