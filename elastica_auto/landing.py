"""Where a snap lands: the rod's dynamics from a fold that ends a stable branch.

At such a fold the stable equilibrium stops existing as the parameter moves past it, and the
snap-back scan (`elastica_auto.snaps`) lists every stable equilibrium left at the fold's
parameters. Which one the rod reaches is decided by its dynamics. An equation module supplies
them through the optional hook

``gradient_flow(p, nodes) -> Flow``
    the energy ``E`` of the equilibria at parameters ``p``, discretised on the uniform
    ``nodes`` of [0, 1] (the method of lines) as a function of a configuration vector
    ``u``, with its overdamped dynamics ``u_t = force(u) = -M^{-1} grad E(u)`` (``M`` the
    lumped mass of the nodes). For the elastica u is theta at the nodes but the clamped one,
    and the dynamics is ``theta_t = theta'' + P sin(theta - alpha)`` with the free end's
    condition (the module's docstring).

From the fold: the parameter is moved ``BEYOND`` past the fold's value, to the side where
the stable branch does not go on (the discrete fold lies O(h^2) from the BVP's: at the fold's
own value the discrete system may still have its stable equilibrium, and the rod would return
to it). The start is the fold's solution ``u_f`` pushed along its null vector ``phi`` (the
branch's tangent there, whose parameter component vanishes), ``u_0 = u_f + PUSH phi /
max|phi|``, on the side where the energy there is lower: the one the rod leaves the fold by
(in the saddle-node's normal form ``a_t = mu + a^2``, ``mu > 0`` past the fold, towards
``a > 0`` whichever side it starts). It is integrated (BDF, with the sparse Jacobian) until
``max |force|`` is below ``FORCE_TOL``; along the way the energy decreases monotonically
(``dE/dt = -u_t' M u_t``). The end is identified with the nearest enumerated equilibrium at
the fold (in the max norm of u), which must lie within ``MATCH`` and be stable.

The damped model ``M u_tt + c M u_t = -grad E(u)`` (from rest at ``u_0``) shows what the
dissipation does: its total energy ``E + u_t' M u_t / 2`` decreases, at rate ``c u_t' M
u_t``; with little damping the rod swings past the nearest well and can land elsewhere.
The overdamped flow is its limit of large ``c`` (in the time ``t / c``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

#: Intervals of the uniform grid of the method of lines (the discrete equilibria are within
#: O(h^2) of the BVP's; tests/test_landing.py measures the order).
NODES = 200
#: Size of the push off the fold along its null vector (max norm of u; radians of theta).
PUSH = 1e-2
#: How far past the fold's value the parameter is moved (its own units).
BEYOND = 1e-3
#: The flow has arrived where max |force| (the discrete equilibrium's residual) is below this.
FORCE_TOL = 1e-8
#: The end is an enumerated equilibrium if it is this close to it (max norm of u).
MATCH = 0.05
#: The transit time is when this fraction of the energy released has been released.
TRANSIT_FRACTION = 0.99
#: The longest time integrated (units of the module's dynamics).
T_MAX = 1e4
#: The integrator's tolerances (BDF): tight enough that the energy it reports decreases
#: monotonically from step to step.
RTOL, ATOL = 1e-7, 1e-10
#: The damped model's (Radau): it integrates until settled in a well, within ``SETTLE`` of
#: its equilibrium (Newton step) with kinetic energy below ``SETTLE^2``, then Newton ends it.
DAMPED_RTOL, DAMPED_ATOL = 1e-6, 1e-8
SETTLE = 1e-3


@dataclass
class Flow:
    """A module's energy and overdamped dynamics on ``nodes`` (method of lines).

    ``to_u(y)``: the configuration vector of states ``y`` (n, len(nodes)) given at the nodes;
    ``mass``: the diagonal of the lumped mass ``M``; ``energy(u)``: the discrete energy;
    ``force(u)``: ``-M^{-1} grad E(u)``, the right-hand side of the overdamped dynamics;
    ``jacobian(u)``: its Jacobian (a scipy sparse matrix).
    """

    nodes: np.ndarray
    to_u: Callable[[np.ndarray], np.ndarray]
    mass: np.ndarray
    energy: Callable[[np.ndarray], float]
    force: Callable[[np.ndarray], np.ndarray]
    jacobian: Callable[[np.ndarray], object]


@dataclass
class Landing:
    """Where the dynamics from a fold ended.

    ``target``: position of the equilibrium reached in the list given to `land` (None if the
    end matched none, or an unstable one); ``distance``: max-norm distance of the end to it;
    ``energy_released``: E(start) - E(end) of the discrete energy; ``transit_time``: when
    ``TRANSIT_FRACTION`` of it was released; ``side``: the sign of the push along the
    tangent stored at the fold; ``times``, ``energies``: the energy along the way (the
    integrator's steps; the total energy for the damped model)."""

    target: int | None
    distance: float
    energy_released: float
    transit_time: float
    side: int
    times: np.ndarray
    energies: np.ndarray


def land(problem, state, null, equilibria, parameter: str, beyond: int,
         damping: float | None = None, push: float = PUSH, nodes: int = NODES) -> Landing:
    """Follow the dynamics of ``problem`` from the fold's solution ``state`` pushed along
    its null vector ``null`` (the tangent stored with the LP), with ``parameter`` moved
    `BEYOND` past the fold in the direction ``beyond`` (+1 or -1), to the equilibrium it
    ends at among ``equilibria`` (`elastica_auto.snaps.Equilibrium`, every one at the fold's
    parameters). ``damping``: None for the overdamped flow, else ``c`` of the damped
    model."""
    from scipy.integrate import solve_ivp
    from scipy.sparse import bmat, identity
    from scipy.sparse.linalg import spsolve

    params = dict(state.params)
    params[parameter] += beyond * BEYOND
    s = np.linspace(0.0, 1.0, nodes + 1)
    flow = problem.gradient_flow(params, s)
    u_fold = flow.to_u(state(s))
    phi = flow.to_u(null(s))
    phi = phi / np.max(np.abs(phi))
    side = 1 if flow.energy(u_fold + push * phi) <= flow.energy(u_fold - push * phi) else -1
    u0 = u_fold + side * push * phi
    m = len(u0)
    if damping is None:
        def rhs(t, u):
            return flow.force(u)

        def jac(t, u):
            return flow.jacobian(u)

        z0 = u0

        def residual(z):
            return np.max(np.abs(flow.force(z)))

        def total(z):
            return flow.energy(z)
    else:
        def rhs(t, z):
            return np.concatenate((z[m:], flow.force(z[:m]) - damping * z[m:]))

        def jac(t, z):
            return bmat([[None, identity(m)], [flow.jacobian(z[:m]), -damping * identity(m)]],
                        format="csc")

        z0 = np.concatenate((u0, np.zeros(m)))

        def residual(z):
            # settled: the Newton step to the equilibrium nearby and the kinetic energy both
            # small (the force itself carries the integration error of the fastest modes)
            step = spsolve(flow.jacobian(z[:m]), flow.force(z[:m]))
            kinetic = 0.5 * np.sum(flow.mass * z[m:] ** 2)
            return FORCE_TOL * max(np.max(np.abs(step)) / SETTLE, kinetic / SETTLE ** 2)

        def total(z):
            return flow.energy(z[:m]) + 0.5 * np.sum(flow.mass * z[m:] ** 2)

    def arrived(t, z):
        return residual(z) - FORCE_TOL
    arrived.terminal = True

    # BDF for the flow; Radau (L-stable at every order) for the damped model, whose fast
    # modes oscillate, with the tolerances it needs only to settle (then Newton)
    sol = solve_ivp(rhs, (0.0, T_MAX), z0, method="BDF" if damping is None else "Radau",
                    jac=jac, events=arrived, rtol=RTOL if damping is None else DAMPED_RTOL,
                    atol=ATOL if damping is None else DAMPED_ATOL)
    if sol.status == -1:
        raise RuntimeError(f"the integration failed: {sol.message}")
    energies = np.array([total(z) for z in sol.y.T])
    u_end = sol.y[:m, -1]
    for _ in range(30):   # to the discrete equilibrium the flow has settled by
        if np.max(np.abs(flow.force(u_end))) < FORCE_TOL:
            break
        u_end = u_end - spsolve(flow.jacobian(u_end), flow.force(u_end))
    released = energies[0] - flow.energy(u_end)
    reached = np.flatnonzero(energies[0] - energies >= TRANSIT_FRACTION * released)
    distances = [np.max(np.abs(u_end - flow.to_u(eq.state(s)))) for eq in equilibria]
    j = int(np.argmin(distances)) if distances else None
    target = j if j is not None and distances[j] < MATCH and equilibria[j].index == 0 else None
    return Landing(target, float(distances[j]) if j is not None else np.inf, float(released),
                   float(sol.t[reached[0]]) if len(reached) else float(sol.t[-1]), side,
                   sol.t, energies)
