"""Planar elastica with a rigid lever arm whose end is pinned (nondimensional: K = l = 1),
written as its energy (docs/energy.md; the model: docs/pinned-end.md).

The rod of ``elastica_lever_arm``: clamped at s = 0 (turned by theta0), a rigid lever arm of
length eps at the tip, at angle psi (clockwise) to the tip tangent. Instead of a dead load,
the end of the arm is pinned at a prescribed point R = (X, Y), free to rotate: two
isoperimetric constraints on the centreline's quadratures x' = -sin theta, y' = cos theta,

    E[theta] = int_0^1 theta'^2 / 2 ds,   theta(0) = theta0,  x(0) = y(0) = 0,
    x(1) + eps sin(psi - theta(1)) = X,   y(1) + eps cos(psi - theta(1)) = Y,

the arm a = eps (sin(psi - theta(1)), cos(psi - theta(1))) (from the tip to its end, at angle
theta(1) - psi from the vertical). Their multipliers are the reaction n = (nx, ny), the force
of the pin on the arm, free parameters solved for (``FREE``): the equations are those of the
Lagrangian E - n.(r(1) + a - R). Derived from it: the states ``[theta, kappa, x, y]`` (kappa =
theta'), theta' = kappa, kappa' = nx cos(theta) + ny sin(theta), the pin's two rows and the
arm's moment balance kappa(1) = (a x n).e_z = eps (ny sin(psi - theta(1)) - nx cos(psi -
theta(1))), the second variation int (h'^2 + (ny cos(theta) - nx sin(theta)) h^2) ds + n.a
h(1)^2 on h(0) = 0 restricted to the variations that keep the pin (two constraints
int g_i h ds + d_i h(1) = 0), where each parameter enters and its distinguished ordinate:
m1 = dE/dpsi = kappa(1) (unchanged from the dead-load module), the clamp's reaction m0 =
kappa(0), and for X and Y the reaction's components n_x, n_y (the values of nx and ny).

With n = P (sin alpha, -cos alpha) the moment balance is the dead-load one, kappa' = -P
sin(theta - alpha), and a dead-load equilibrium pinned at its own arm end is an equilibrium
here, with reaction n = the load.

Pin position: the defaults put the pin on the clamp's axis at (X, Y) = (0, 0.4), so that
the rod must buckle (the arm's end is 0.85 closer to the clamp than the straight rod's
would be, for eps = 0.25) with a compressive reaction |n| ~ 20, of the order of the paper's
loads (9 pi^2/4 = 22.2), and the pin stays within reach, |R| + eps < 1, for eps <= 0.5 whatever
psi. The arm end of the stable buckled dead-load rod (P = pi^2/4, eps = 0.25, psi = 0) lies at
|R| = 1.077, out of reach of the rod and arm near psi = pi/2 (1.031): the psi-branch from it
runs to a straight rod in unbounded tension. The straight rod pinned at (0, 1 + eps) would be
degenerate (any axial force holds it), hence a buckled start: ``guess`` finds an equilibrium
and its reaction by shooting (at the defaults: theta'(0) = 6.55, n = (-16.38, -12.65), one of
a mirror pair).

By hand, what the energy does not say: ``guess``, the ordinate ``n_abs`` = |n| and ``draw``
(clamp, centreline, lever arm, the pin at (X, Y) and the reaction n as an arrow ending at
the pin). The hand-written module this one replaces is tests/reference/elastica_pinned.py,
with n as two constant states.
"""

import math

import numpy as np

from elastica_auto import Ordinate
from elastica_auto.energy import derived_names
from elastica_auto.equations.elastica_lever_arm import (ARM_COLOR, CLAMP_COLOR, LINE_WIDTH,
                                                       draw_force, draw_rod)

#: The default pin position (module docstring).
PIN_X, PIN_Y = 0.0, 0.4


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s = sp.Symbol("s", real=True)
    eps, psi, theta0, X, Y, nx, ny = sp.symbols("eps psi theta0 X Y nx ny", real=True)
    theta, x, y = (sp.Function(name)(s) for name in ("theta", "x", "y"))
    arm = eps * sp.Matrix([sp.sin(psi - theta), sp.cos(psi - theta)])
    return Energy(
        density=theta.diff(s) ** 2 / 2,
        s=s, coordinates=[theta], momenta={theta: "kappa"},
        quadratures={x: -sp.sin(theta), y: sp.cos(theta)},
        fixed0={theta: theta0, x: 0, y: 0},
        fixed1={x: X - arm[0], y: Y - arm[1]},        # the pin: r(1) + a = (X, Y)
        multipliers={x: -nx, y: -ny},                 # E - n.(r(1) + a - R)
        parameters={
            eps: Param(0.25, r"\epsilon", doc="lever-arm length / l; negative flips it"),
            psi: Param(0.0, r"\psi", period=2 * sp.pi, ordinate="m1",
                       doc="arm angle to the tip tangent, clockwise"),
            theta0: Param(0.0, r"\theta_0", period=2 * sp.pi, period_shift={theta: 2 * sp.pi},
                          ordinate="m0", doc="rotation of the clamp"),
            X: Param(PIN_X, "X", ordinate="n_x", doc="pin abscissa (the arm's end), / l"),
            Y: Param(PIN_Y, "Y", ordinate="n_y", doc="pin ordinate (the arm's end), / l"),
            nx: Param(0.0, "n_x", doc="the pin's reaction on the arm, x (solved for)"),
            ny: Param(0.0, "n_y", doc="the pin's reaction on the arm, y (solved for)"),
        })


#: Imported as a Python module, the derived names on first use (`load_problem` gives them).
__getattr__ = derived_names(__name__)


ORDINATES = [
    Ordinate("n_abs", r"$|n|$", lambda s, y, p: math.hypot(p["nx"], p["ny"]), None,
             "reaction magnitude |n|"),
]


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
    """The three conditions at s = 1 for the batch ``z`` (B, 3): the pin's two and the arm's
    moment balance, (B, 3)."""
    theta, kappa, x, y = _shoot(z, p)[:, -1]
    nx, ny = z[:, 1], z[:, 2]
    u, eps = p["psi"] - theta, p["eps"]
    return np.array((x + eps * np.sin(u) - p["X"], y + eps * np.cos(u) - p["Y"],
                     kappa - eps * (ny * np.sin(u) - nx * np.cos(u)))).T


def guess(s, p):
    """An equilibrium at ``p`` by shooting: Newton's method (differenced Jacobian, steps
    limited to length 2) on the three pin conditions at s = 1 for (theta'(0), n_x, n_y), from
    each of ``SHOOTING_STARTS`` at once; of the roots found, the one of least bending energy
    int kappa^2/2 (stable, if it is the global minimum of the constrained energy), and its
    reaction (nx, ny) as two constant rows after the states (the free parameters' values to
    solve the start from). None if none converges."""
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
    the reaction n (the solved-for nx, ny) as an arrow ending at the pin, its length fixed
    whatever |n|."""
    draw_rod(ax, profile, p)
    pin, h = np.array((p["X"], p["Y"])), PIN_SIZE
    tri = pin + np.array(((0.0, 0.0), (-h, -1.6 * h), (h, -1.6 * h), (0.0, 0.0)))
    ax.fill(tri[:, 0], tri[:, 1], facecolor="white", edgecolor=CLAMP_COLOR, lw=0.8, zorder=5,
            gid="pin")
    ax.plot((pin[0] - 1.5 * h, pin[0] + 1.5 * h), (pin[1] - 1.6 * h,) * 2, color=CLAMP_COLOR,
            lw=0.8, zorder=5)
    ax.plot(*pin, "o", ms=LINE_WIDTH * 2.2, markerfacecolor="white", markeredgecolor=ARM_COLOR,
            zorder=6)
    n = np.array((p["nx"], p["ny"]))
    if math.hypot(*n) > 0:
        draw_force(ax, pin, n, "reaction")
