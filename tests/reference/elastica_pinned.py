"""Planar elastica with a rigid lever arm whose end is pinned (nondimensional: K = l = 1).

The rod of ``elastica_lever_arm``: clamped at s = 0 (turned by theta0), a rigid lever arm of
length eps at the tip, at angle psi (clockwise) to the tip tangent. Instead of a dead load,
the end of the arm is pinned at a prescribed point R = (X, Y), free to rotate; the reaction
n = (n_x, n_y), the force of the pin on the arm, is an unknown constant of the solution.

State ``[theta, kappa, x, y, nx, ny]`` on s in [0, 1]; theta is the tangent angle from the
vertical, kappa = theta' the bending moment m.e_z, (x, y) the centreline, (nx, ny) = n::

    theta' = kappa,  kappa' = n_x cos(theta) + n_y sin(theta),
    x' = -sin(theta),  y' = cos(theta),  n_x' = n_y' = 0.

With n = P (sin alpha, -cos alpha) the moment balance is the dead-load one,
kappa' = -P sin(theta - alpha). The arm is a = eps (sin(psi - theta(1)), cos(psi - theta(1)))
(from the tip to its end, at angle theta(1) - psi from the vertical). End conditions::

    theta(0) = theta0,  x(0) = y(0) = 0,
    x(1) + eps sin(psi - theta(1)) = X,  y(1) + eps cos(psi - theta(1)) = Y,
    kappa(1) = (a x n).e_z = eps (n_y sin(psi - theta(1)) - n_x cos(psi - theta(1))),

the last the moment balance of the arm about the tip: with n = P (sin alpha, -cos alpha) it is
the dead-load module's kappa(1) + eps P sin(psi + alpha - theta(1)) = 0, so a dead-load
equilibrium pinned at its own arm end is an equilibrium here, with reaction n = the load.
These are the Euler-Lagrange equations of the Lagrangian

    L = int_0^1 kappa^2/2 ds - n . (r(1) + a - R),   r(1) = int_0^1 (-sin theta, cos theta) ds,

n the multiplier of the pin. The distinguished ordinate of a parameter xi is dL/dxi at the
equilibrium: for psi, -n . da/dpsi = (a x n).e_z = kappa(1), the ordinate ``m1`` (unchanged
from the dead-load module); for theta0 (the fixed end) kappa(0), ``m0`` with the fixed-end
sign; for X and Y, n_x and n_y. The second variation is the dead-load one with the load
replaced by n, restricted to the variations that keep the pin (``second_variation``).

Pin position: the defaults put the pin on the clamp's axis at (X, Y) = (0, 0.4), so that
the rod must buckle (the arm's end is 0.85 closer to the clamp than the straight rod's
would be, for eps = 0.25) with a compressive reaction |n| ~ 20, of the order of the paper's
loads (9 pi^2/4 = 22.2), and the pin stays within reach, |R| + eps < 1, for eps <= 0.5 whatever
psi. The arm end of the stable buckled dead-load rod (P = pi^2/4, eps = 0.25, psi = 0) lies at
|R| = 1.077, out of reach of the rod and arm near psi = pi/2 (1.031): the psi-branch from it
runs to a straight rod in unbounded tension. The straight rod pinned at (0, 1 + eps) would be
degenerate (any axial force holds it), hence a buckled start: ``guess`` finds an equilibrium
by shooting (at the defaults: theta'(0) = 6.55, n = (-16.38, -12.65), one of a mirror pair).

``draw`` draws a configuration: clamp, centreline, lever arm, the pin at (X, Y) and the
reaction n as an arrow ending at the pin.
"""

import math

import numpy as np

from elastica_auto.equations.elastica_lever_arm import (ARM_COLOR, CLAMP_COLOR, LINE_WIDTH,
                                                       draw_force, draw_rod)
from elastica_auto import Ordinate, Parameter

STATES = ("theta", "kappa", "x", "y", "nx", "ny")

#: The default pin position (module docstring).
PIN_X, PIN_Y = 0.0, 0.4

PARAMETERS = [
    Parameter("eps", 0.25, r"\epsilon", "free", doc="lever-arm length / l; negative flips it"),
    Parameter("psi", 0.0, r"\psi", "free", period=2 * math.pi,
              doc="arm angle to the tip tangent, clockwise"),
    Parameter("theta0", 0.0, r"\theta_0", "fixed", period=2 * math.pi,
              period_shift={"theta": 2 * math.pi}, doc="rotation of the clamp"),
    Parameter("X", PIN_X, r"X", "free", doc="pin abscissa (the arm's end), / l"),
    Parameter("Y", PIN_Y, r"Y", "free", doc="pin ordinate (the arm's end), / l"),
]


def _u(yb, p):
    """psi - theta(1): the arm is eps (sin u, cos u)."""
    return p["psi"] - yb[0]


def rhs(s, y, p):
    """The elastica's four rows (the contact force (nx, ny) in kappa') and nx' = ny' = 0,
    filled row by row (np.vstack of the rows costs twice as much at the engine's sizes)."""
    theta, nx, ny = y[0], y[4], y[5]
    out = np.empty(y.shape)
    out[0] = y[1]
    out[1] = nx * np.cos(theta) + ny * np.sin(theta)
    out[2] = -np.sin(theta)
    out[3] = np.cos(theta)
    out[4:] = 0.0
    return out


def rhs_jac(s, y, p):
    theta, nx, ny = y[0], y[4], y[5]
    c, sn = np.cos(theta), np.sin(theta)
    jac = np.zeros((6, 6, y.shape[1]))
    jac[0, 1] = 1.0
    jac[1, 0] = -nx * sn + ny * c
    jac[1, 4] = c
    jac[1, 5] = sn
    jac[2, 0] = -c
    jac[3, 0] = -sn
    return jac


def rhs_dp(s, y, p, name):
    return np.zeros_like(y)


def bc(ya, yb, p):
    u, eps = _u(yb, p), p["eps"]
    return np.array((ya[0] - p["theta0"], ya[2], ya[3],
                     yb[2] + eps * np.sin(u) - p["X"],
                     yb[3] + eps * np.cos(u) - p["Y"],
                     yb[1] - eps * (yb[5] * np.sin(u) - yb[4] * np.cos(u))))


def bc_jac(ya, yb, p):
    u, eps = _u(yb, p), p["eps"]
    su, cu = np.sin(u), np.cos(u)
    da = np.zeros((6, 6))
    db = np.zeros((6, 6))
    da[0, 0] = da[1, 2] = da[2, 3] = 1.0
    db[3, 2] = db[4, 3] = db[5, 1] = 1.0
    db[3, 0] = -eps * cu
    db[4, 0] = eps * su
    db[5, 0] = eps * (yb[5] * cu + yb[4] * su)
    db[5, 4] = eps * cu
    db[5, 5] = -eps * su
    return da, db


def bc_dp(ya, yb, p, name):
    u, eps = _u(yb, p), p["eps"]
    su, cu = np.sin(u), np.cos(u)
    out = np.zeros(6)
    if name == "theta0":
        out[0] = -1.0
    elif name == "eps":
        out[3:] = su, cu, -(yb[5] * su - yb[4] * cu)
    elif name == "psi":
        out[3:] = eps * cu, -eps * su, -eps * (yb[5] * cu + yb[4] * su)
    elif name == "X":
        out[3] = -1.0
    elif name == "Y":
        out[4] = -1.0
    return out


ORDINATES = [
    Ordinate("m1", r"$m(1)\cdot e_z$", lambda s, y, p: y[1, -1], "psi",
             "tip moment kappa(1) = (a x n).e_z = dL/dpsi; ordinate for psi"),
    Ordinate("m0", r"$m(0)\cdot e_z$", lambda s, y, p: y[1, 0], "theta0",
             "clamp moment kappa(0); ordinate for theta0"),
    Ordinate("n_x", r"$n_x$", lambda s, y, p: y[4, 0], "X",
             "reaction n_x = dL/dX; ordinate for X"),
    Ordinate("n_y", r"$n_y$", lambda s, y, p: y[5, 0], "Y",
             "reaction n_y = dL/dY; ordinate for Y"),
    Ordinate("n_abs", r"$|n|$", lambda s, y, p: math.hypot(y[4, 0], y[5, 0]), None,
             "reaction magnitude |n|"),
]


def second_variation(s, y, p):
    """The dead-load second variation with the load replaced by the reaction n, on the
    variations h (h(0) = 0) that keep the pin::

        delta^2 L[h] = int_0^1 (h'^2 + b h^2) ds + c h(1)^2,
        b = n_y cos(theta) - n_x sin(theta),  c = n . a = eps (n_x sin u + n_y cos u),

    u = psi - theta(1); the linearised pin, delta (r(1) + a) = 0, is two constraints
    ``int g_i h ds + d_i h(1) = 0``: delta x(1) = -int cos(theta) h, delta y(1) =
    -int sin(theta) h, and d a / d theta(1) = eps (-cos u, sin u)::

        g_1 = -cos(theta), d_1 = -eps cos u;   g_2 = -sin(theta), d_2 = eps sin u.
    """
    theta, nx, ny = y[0], y[4], y[5]
    u, eps = _u(y[:, -1], p), p["eps"]
    b = ny * np.cos(theta) - nx * np.sin(theta)
    c = eps * (nx[-1] * np.sin(u) + ny[-1] * np.cos(u))
    return (1.0, b, float(c), [(-np.cos(theta), -eps * math.cos(u)),
                               (-np.sin(theta), eps * math.sin(u))])


#: Starting values (theta'(0), n_x, n_y) tried by ``guess``: buckled either way, compressed
#: like the dead-load runs, and a few others.
SHOOTING_STARTS = np.array([(k, 0.0, -q) for q in (math.pi ** 2 / 4, 9 * math.pi ** 2 / 4, 1.0)
                            for k in (2.5, -2.5, 1.0, -1.0, 6.0, -6.0)])
#: RK4 steps of the shooting; the guess is refined by the engine's first corrector solve.
SHOOTING_STEPS = 400


def _shoot(z, p):
    """RK4 from s = 0 to 1 for a batch of unknowns ``z`` (B, 3) = (theta'(0), n_x, n_y):
    [theta, kappa, x, y] on the grid, (4, SHOOTING_STEPS + 1, B)."""
    nx, ny = z[:, 1], z[:, 2]
    y = np.array([np.full(len(z), float(p["theta0"])), z[:, 0], np.zeros(len(z)),
                  np.zeros(len(z))])
    h = 1.0 / SHOOTING_STEPS

    def f(y):
        c, sn = np.cos(y[0]), np.sin(y[0])
        return np.array((y[1], nx * c + ny * sn, -sn, c))

    out = [y]
    for _ in range(SHOOTING_STEPS):
        k1 = f(y)
        k2 = f(y + 0.5 * h * k1)
        k3 = f(y + 0.5 * h * k2)
        k4 = f(y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(y)
    return np.stack(out, axis=1)


def _pin_residual(z, p):
    """The three conditions at s = 1 for the batch ``z`` (B, 3): (B, 3)."""
    yb = np.concatenate((_shoot(z, p)[:, -1], z[:, 1:].T))
    return bc(np.zeros((6, len(z))), yb, p)[3:].T


def guess(s, p):
    """An equilibrium at ``p`` by shooting: Newton's method (differenced Jacobian, steps
    limited to length 2) on the three pin conditions at s = 1 for (theta'(0), n_x, n_y), from
    each of ``SHOOTING_STARTS`` at once; of the roots found, the one of least bending energy
    int kappa^2/2 (stable, if it is the global minimum of the constrained energy). None if
    none converges."""
    z = SHOOTING_STARTS.copy()
    step = 1e-7
    for _ in range(40):
        batch = np.concatenate([z] + [z + step * e for e in np.eye(3)])
        with np.errstate(all="ignore"):
            r = _pin_residual(batch, p).reshape(4, len(z), 3)
        jac = np.stack([(r[j + 1] - r[0]) / step for j in range(3)], axis=2)
        ok = np.all(np.isfinite(jac), axis=(1, 2)) & np.all(np.isfinite(r[0]), axis=1)
        z, r0, jac = z[ok], r[0][ok], jac[ok]
        if len(z) == 0:
            return None
        if np.max(np.abs(r0)) < 1e-11:
            break
        try:
            dz = np.linalg.solve(jac, -r0[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            return None
        size = np.linalg.norm(dz, axis=1, keepdims=True)
        z = z + dz * np.minimum(1.0, 2.0 / np.maximum(size, 1e-300))
    res = np.max(np.abs(_pin_residual(z, p)), axis=1)
    z = z[res < 1e-9]
    if len(z) == 0:
        return None
    traj = _shoot(z, p)
    energy = np.sum(0.5 * (traj[1, 1:] ** 2 + traj[1, :-1] ** 2) / 2, axis=0) / SHOOTING_STEPS
    best = int(np.argmin(energy))
    grid = np.linspace(0.0, 1.0, SHOOTING_STEPS + 1)
    s = np.asarray(s, dtype=float)
    y = np.array([np.interp(s, grid, traj[i, :, best]) for i in range(4)])
    return np.vstack((y, np.full(len(s), z[best, 1]), np.full(len(s), z[best, 2])))


#: Size of the drawn pin (the rest is drawn as ``elastica_lever_arm`` draws it).
PIN_SIZE = 0.07


def draw(ax, profile, p):
    """Draw the configuration on ``ax``: the clamp, centreline and lever arm (as
    ``elastica_lever_arm`` draws them), the pin (a triangle with its hinge) at (X, Y), and
    the reaction n as an arrow ending at the pin, its length fixed whatever |n|."""
    draw_rod(ax, profile, p)
    pin, h = np.array((p["X"], p["Y"])), PIN_SIZE
    tri = pin + np.array(((0.0, 0.0), (-h, -1.6 * h), (h, -1.6 * h), (0.0, 0.0)))
    ax.fill(tri[:, 0], tri[:, 1], facecolor="white", edgecolor=CLAMP_COLOR, lw=0.8, zorder=5,
            gid="pin")
    ax.plot((pin[0] - 1.5 * h, pin[0] + 1.5 * h), (pin[1] - 1.6 * h,) * 2, color=CLAMP_COLOR,
            lw=0.8, zorder=5)
    ax.plot(*pin, "o", ms=LINE_WIDTH * 2.2, markerfacecolor="white", markeredgecolor=ARM_COLOR,
            zorder=6)
    n = profile[4:6, -1]
    if math.hypot(*n) > 0:
        draw_force(ax, pin, n, "reaction")
