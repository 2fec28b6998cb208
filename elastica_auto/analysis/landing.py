"""Where a snap lands: the rod's dynamics from a fold that ends a stable branch.

At such a fold the stable equilibrium stops existing as the parameter moves past it, and the
snap-back scan (`elastica_auto.analysis.snaps`) lists every stable equilibrium left at the fold's
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
|phi|`` (``|phi|`` its max norm, or the flow's ``size``: the largest angle a frame turns by
along it), on the side where the energy there is lower: the one the rod leaves the fold by
(in the saddle-node's normal form ``a_t = mu + a^2``, ``mu > 0`` past the fold, towards
``a > 0`` whichever side it starts). It is integrated (BDF, with the sparse Jacobian) until
``max |force|`` is below ``FORCE_TOL``; along the way the energy decreases monotonically
(``dE/dt = -u_t' M u_t``). The end is identified with the nearest enumerated equilibrium at
the fold (in the max norm of u, or the flow's ``distance``: angles for frames), which must lie
within ``MATCH`` and be stable.

The damped model ``M u_tt + c M u_t = -grad E(u)`` (from rest at ``u_0``) shows what the
dissipation does: its total energy ``E + u_t' M u_t / 2`` decreases, at rate ``c u_t' M
u_t``; with little damping the rod swings past the nearest well and can land elsewhere.
The overdamped flow is its limit of large ``c`` (in the time ``t / c``). Its well is decided
once the total energy is below every saddle's (`lowest_saddle`); the overdamped flow then
finishes. `damping_sweep` runs it from folds of a run for a list of ``c``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..core.errors import ENGINE, failure_record, module_files

#: Intervals of the uniform grid of the method of lines (the discrete equilibria are within
#: O(h^2) of the BVP's; tests/test_landing.py measures the order).
NODES = 200
#: Size of the push off the fold along its null vector (max norm of u, or the flow's
#: ``size``; radians of theta, of a frame's turn).
PUSH = 1e-2
#: How far past the fold's value the parameter is moved (its own units).
BEYOND = 1e-3
#: The flow has arrived where max |force| (the discrete equilibrium's residual) is below this.
FORCE_TOL = 1e-8
#: The end is an enumerated equilibrium if it is this close to it (max norm of u, or the
#: flow's ``distance``).
MATCH = 0.05
#: The transit time is when this fraction of the energy released has been released.
TRANSIT_FRACTION = 0.99
#: The longest time integrated (units of the module's dynamics).
T_MAX = 1e4
#: The integrator's tolerances (BDF): tight enough that the energy it reports decreases
#: monotonically from step to step.
RTOL, ATOL = 1e-7, 1e-10
#: The damped model's (Radau): it integrates until its well is decided (``BARRIER_MARGIN``)
#: or it has settled in one, within ``SETTLE`` of its equilibrium (Newton step) with kinetic
#: energy below ``SETTLE^2``. The landing is the same with both divided by 100 (tested);
#: these take a third of the steps of 1e-6, 1e-8.
DAMPED_RTOL, DAMPED_ATOL = 1e-4, 1e-6
SETTLE = 1e-3
#: The damped model's well is decided once its total energy is below the lowest saddle's
#: by this much (relative): the lowest saddle's energy is a discrete equilibrium's, found by
#: Newton, so the margin covers only the integrator's error in the total energy.
BARRIER_MARGIN = 1e-6
#: An enumerated unstable equilibrium this close to the fold (max norm of u) is the fold's
#: own partner, gone past the fold.
FOLD_PARTNER = 0.2


@dataclass
class Flow:
    """A module's energy and overdamped dynamics on ``nodes`` (method of lines).

    ``to_u(y)``: the configuration vector of states ``y`` (n, len(nodes)) given at the nodes;
    ``mass``: the diagonal of the lumped mass ``M``; ``energy(u)``: the discrete energy;
    ``force(u)``: ``-M^{-1} grad E(u)``, the right-hand side of the overdamped dynamics;
    ``jacobian(u)``: its Jacobian (a scipy sparse matrix). Where u is no vector of angles
    and lengths (a frame's quaternions: `elastica_auto.energy.frame_flow`), ``size(u, du)``
    is the size of a displacement du at u and ``distance(u, v)`` how far apart two
    configurations are, in those units (the angle a frame turns by); by default the max norms
    ``max |du|`` and ``max |u - v|``.
    """

    nodes: np.ndarray
    to_u: Callable[[np.ndarray], np.ndarray]
    mass: np.ndarray
    energy: Callable[[np.ndarray], float]
    force: Callable[[np.ndarray], np.ndarray]
    jacobian: Callable[[np.ndarray], object]
    size: Callable[[np.ndarray, np.ndarray], float] | None = None
    distance: Callable[[np.ndarray, np.ndarray], float] | None = None

    def size_of(self, u, du) -> float:
        """The size of the displacement ``du`` at ``u`` (``size``, or the max norm)."""
        return float(self.size(u, du) if self.size is not None else np.max(np.abs(du)))

    def distance_of(self, u, v) -> float:
        """How far apart ``u`` and ``v`` are (``distance``, or the max norm)."""
        return float(self.distance(u, v) if self.distance is not None
                     else np.max(np.abs(u - v)))


@dataclass
class Landing:
    """Where the dynamics from a fold ended.

    ``target``: position of the equilibrium reached in the list given to `land` (None if the
    end matched none, or an unstable one); ``distance``: max-norm distance of the end to it;
    ``energy_released``: E(start) - E(end) of the discrete energy; ``transit_time``: when
    ``TRANSIT_FRACTION`` of it was released; ``side``: the sign of the push along the
    tangent stored at the fold; ``times``, ``energies``: the energy along the way (the
    integrator's steps; the total energy for the damped model); ``end``: the configuration u
    where it ended (the discrete equilibrium, the flow's ``to_u`` of a state)."""

    target: int | None
    distance: float
    energy_released: float
    transit_time: float
    side: int
    times: np.ndarray
    energies: np.ndarray
    end: np.ndarray | None = None


def land(problem, state, null, equilibria, parameter: str, beyond: int,
         damping: float | None = None, push: float = PUSH, nodes: int = NODES) -> Landing:
    """Follow the dynamics of ``problem`` from the fold's solution ``state`` pushed along
    its null vector ``null`` (the tangent stored with the LP), with ``parameter`` moved
    `BEYOND` past the fold in the direction ``beyond`` (+1 or -1), to the equilibrium it
    ends at among ``equilibria`` (`analysis.equilibria.Equilibrium`, every one at the fold's
    parameters). ``damping``: None for the overdamped flow, else ``c`` of the damped
    model."""
    params = dict(state.params)
    params[parameter] += beyond * BEYOND
    s = np.linspace(0.0, 1.0, nodes + 1)
    flow = problem.gradient_flow(params, s)
    u_fold = flow.to_u(state(s))
    phi = flow.to_u(null(s))
    phi = phi / flow.size_of(u_fold, phi)
    side = 1 if flow.energy(u_fold + push * phi) <= flow.energy(u_fold - push * phi) else -1
    u0 = u_fold + side * push * phi
    if damping is None:
        times, energies, u_end = overdamped_path(flow, u0)
    else:
        barrier = lowest_saddle(flow, [flow.to_u(eq.state(s)) for eq in equilibria
                                        if eq.index > 0], u_fold)
        times, energies, u_end = _damped(flow, u0, damping, barrier)
    u_end = _newton(flow, u_end)
    if u_end is None:
        raise RuntimeError("Newton's method did not reach the equilibrium the dynamics "
                           "settled by")
    released = energies[0] - flow.energy(u_end)
    reached = np.flatnonzero(energies[0] - energies >= TRANSIT_FRACTION * released)
    distances = [flow.distance_of(u_end, flow.to_u(eq.state(s))) for eq in equilibria]
    j = int(np.argmin(distances)) if distances else None
    target = j if j is not None and distances[j] < MATCH and equilibria[j].index == 0 else None
    return Landing(target, float(distances[j]) if j is not None else np.inf, float(released),
                   float(times[reached[0]]) if len(reached) else float(times[-1]), side,
                   times, energies, u_end)


def _newton(flow, u, iterations: int = 30):
    """The discrete equilibrium (``max |force| < FORCE_TOL``) Newton's method reaches from
    ``u``, or None."""
    from scipy.sparse.linalg import spsolve
    for _ in range(iterations):
        if np.max(np.abs(flow.force(u))) < FORCE_TOL:
            return u
        u = u - spsolve(flow.jacobian(u), flow.force(u))
        if not np.all(np.isfinite(u)):
            return None
    return u if np.max(np.abs(flow.force(u))) < FORCE_TOL else None


def overdamped_path(flow, u0, t0: float = 0.0):
    """``u_t = force(u)`` from ``u0`` (BDF) until ``max |force| < FORCE_TOL``: the times,
    the energies ``E_h`` and the end."""
    from scipy.integrate import BDF
    solver = BDF(lambda t, u: flow.force(u), t0, u0, t0 + T_MAX, rtol=RTOL, atol=ATOL,
                 jac=lambda t, u: flow.jacobian(u))
    return _steps(solver, lambda u, e: np.max(np.abs(flow.force(u))) < FORCE_TOL, flow.energy)


def _steps(solver, done, total):
    """Step ``solver`` until ``done(y, total(y))`` after a step (or ``T_MAX``): the times,
    ``total(y)`` at each and the end. (Checked step by step, not located as an event: where
    it happens to within a step is enough, and an event's root finding on the dense output
    fails when the check is not continuous in time, as the settling test below is not.)"""
    times, energies = [solver.t], [total(solver.y)]
    while not done(solver.y, energies[-1]):
        solver.step()
        if solver.status == "failed":
            raise RuntimeError(f"the integration failed at t = {solver.t:.4g}")
        times.append(solver.t)
        energies.append(total(solver.y))
        if solver.status == "finished":
            raise RuntimeError(f"the dynamics did not settle by t = {T_MAX:g}")
    return np.array(times), np.array(energies), solver.y


def lowest_saddle(flow, unstable, u_fold) -> float:
    """The lowest ``E_h`` of the discrete equilibria of index >= 1, each found by Newton
    from an enumerated unstable equilibrium ``unstable`` (their nodal values). Below it a
    component of the sublevel set ``{E_h < e}`` holds a single minimum (components join
    only at saddles): a rod whose total energy has fallen below it can no longer leave its
    well. The fold's own unstable partner has gone past the fold (Newton fails near
    ``u_fold``); any other failure leaves the bound unknown: -inf."""
    lowest = np.inf
    for u in unstable:
        there = _newton(flow, u)
        if there is None or flow.distance_of(there, u) > MATCH:
            if flow.distance_of(u, u_fold) < FOLD_PARTNER:
                continue
            return -np.inf
        lowest = min(lowest, flow.energy(there))
    return lowest


def _damped(flow, u0, damping: float, barrier: float):
    """``M u_tt + c M u_t = -grad E_h`` from rest at ``u0`` (Radau): the times, total
    energies and the end. Stops once the total energy is below ``barrier`` (the well is
    decided; the overdamped flow from there, which keeps ``E_h`` below it too, ends in the
    same well's minimum and is appended) or once settled in a well."""
    from scipy.integrate import Radau
    from scipy.sparse import bmat, identity
    from scipy.sparse.linalg import spsolve
    m = len(u0)
    below = barrier - BARRIER_MARGIN * (1 + abs(barrier))

    def rhs(t, z):
        return np.concatenate((z[m:], flow.force(z[:m]) - damping * z[m:]))

    def jac(t, z):
        return bmat([[None, identity(m)], [flow.jacobian(z[:m]), -damping * identity(m)]],
                    format="csc")

    def total(z):
        return flow.energy(z[:m]) + 0.5 * np.sum(flow.mass * z[m:] ** 2)

    def done(z, energy):
        """``energy``: ``total(z)``, which `_steps` records at every step anyway."""
        if energy < below:
            return True
        # settled: the kinetic energy and the Newton step to the equilibrium nearby both
        # small (the force itself carries the integration error of the fastest modes); the
        # step, a sparse solve, only once the rod has all but stopped (checked at every
        # step of the integration, it was half the cost of a landing)
        if 0.5 * np.sum(flow.mass * z[m:] ** 2) >= SETTLE ** 2:
            return False
        step = spsolve(flow.jacobian(z[:m]), flow.force(z[:m]))
        return bool(np.max(np.abs(step)) < SETTLE)

    solver = Radau(rhs, 0.0, np.concatenate((u0, np.zeros(m))), T_MAX, rtol=DAMPED_RTOL,
                   atol=DAMPED_ATOL, jac=jac)
    times, energies, z = _steps(solver, done, total)
    if energies[-1] < below:
        t_more, e_more, u_end = overdamped_path(flow, z[:m], times[-1])
        return (np.concatenate((times, t_more[1:])), np.concatenate((energies, e_more[1:])),
                u_end)
    return times, energies, z[:m]


def damping_sweep(problem, branches, damping, folds=None, warnings: list | None = None,
                  on_landing: Callable | None = None, mapper: Callable | None = None,
                  failures: list | None = None) -> list[dict]:
    """Where the damped model lands from folds of ``branches``, for each ``c`` in
    ``damping``: one row per (fold, c), in fold then ``damping`` order.

    ``folds``: the labels of the folds (each one ending a stable branch; the others get a
    line in ``warnings``), default every fold ending a stable branch. A row has the fold's
    ``lp``, ``branch`` (1-based), ``parameter`` and its ``value``, ``damping``, ``landed``
    (1 if the end is a stable equilibrium at the fold's parameters, found by the shooting
    scan; else 0, a line in ``warnings`` and NaN below), that equilibrium's ``k``,
    ``target_<ordinate>`` values and ``energy_released``, and the ``transit_time``.
    ``on_landing(done, total, row)`` is called after each landing. A landing whose dynamics
    failed (`landing_task`) is also added to ``failures`` (a list, if given).

    The landings are independent tasks (`landing_task`): ``mapper(function, args_list,
    on_done)`` computes them (default one after the other here; a default run's
    `execution.run` shares them between this process and its cluster), returns their
    results in order and calls ``on_done(i, result)`` as each is done. The rows are the same
    whoever computed them.
    """
    from .equilibria import beyond_fold, enumerate_equilibria, snap_lps
    warnings = warnings if warnings is not None else []
    found = [(nb, br, p, side) for nb, br in enumerate(branches, start=1)
             for p, side in snap_lps(br) if folds is None or p.name in folds]
    for name in [] if folds is None else [f for f in folds
                                          if f not in {p.name for _, _, p, _ in found}]:
        warnings.append(f"{name}: not a fold ending a stable branch; no damping sweep")
    heads, tasks = [], []
    for nb, br, p, side in found:
        equilibria = enumerate_equilibria(problem, p.params)
        beyond = beyond_fold(br, p, side)
        for c in damping:
            heads.append((nb, br.parameter, p, equilibria, float(c)))
            tasks.append((problem, p.state, p.tangent, equilibria, br.parameter, beyond,
                          float(c)))
    rows: list[dict | None] = [None] * len(tasks)
    lines: list[list[str]] = [[] for _ in tasks]
    done = 0

    def row_of(i, result):
        nonlocal done
        nb, name, p, equilibria, c = heads[i]
        row = {"lp": p.name, "branch": nb, "parameter": name, "value": p.params[name],
               "damping": c, "landed": 0, "k": np.nan,
               **{f"target_{o}": np.nan for o in problem.ordinate_names},
               "energy_released": np.nan, "transit_time": np.nan}
        if isinstance(result, dict):
            lines[i].append(f"{p.name}, damping {c:g}: the dynamics failed: "
                            f"{result['message']}")
            if failures is not None:
                failures.append({**result, "message": lines[i][-1]})
        elif result.target is None:
            lines[i].append(f"{p.name}, damping {c:g}: the dynamics ended at no enumerated "
                            f"stable equilibrium (the nearest is {result.distance:.3g} away)")
        else:
            eq = equilibria[result.target]
            row.update(landed=1, k=eq.k, energy_released=result.energy_released,
                       transit_time=result.transit_time,
                       **{f"target_{o}": v for o, v in eq.ordinates.items()})
        rows[i] = row
        done += 1
        if on_landing is not None:
            on_landing(done, len(tasks), row)

    (mapper or one_by_one)(landing_task, tasks, row_of)
    warnings.extend(line for group in lines for line in group)
    return rows


def one_by_one(function, args_list, on_done) -> list:
    """The mapper of a run without workers: ``function(*args)`` for each of ``args_list``
    here, in order, ``on_done(i, result)`` after each; the results."""
    out = []
    for i, args in enumerate(args_list):
        out.append(function(*args))
        on_done(i, out[-1])
    return out


def landing_task(problem, state, null, equilibria, parameter, beyond, damping
                 ) -> Landing | dict:
    """`land` with ``damping``, as a task of `damping_sweep`: the `Landing`, or, where the
    module's hook fails (or the dynamics fail numerically), that landing only, the failure
    (`elastica_auto.core.errors.failure_record`, with its one-line ``message``). An internal
    error of the engine is raised: the landings as a whole have failed."""
    try:
        return land(problem, state, null, equilibria, parameter, beyond, damping=damping)
    except (Exception, SystemExit) as exc:
        record = failure_record(exc, module_files(problem.module))
        if record["kind"] == ENGINE:
            raise
        record["message"] = (f"{record['exception']}: " + " ".join(record["error"].split())
                             + f" ({record['where']})")
        return record
