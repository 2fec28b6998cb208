"""Integral conditions and free parameters, carried as extra states.

A module with r boundary conditions more than states and q integral conditions

    int_0^1 phi_j(s, y; p) ds = 0        (j = 1 .. q; AUTO-07p's NINT)

has r + q parameters solved for along with y (the *free* parameters mu_k; AUTO-07p's NBC >
NDIM). The engine solves the equivalent square problem on the states (y, w, mu):

    y'  = f(s, y; p, mu)                 g(y(0), y(1); p, mu) = 0      (n + r conditions)
    w_j' = phi_j(s, y; p, mu)            w_j(0) = 0,  w_j(1) = 0       (2 q conditions)
    mu_k' = 0                                                          (no condition)

n + q + r + q states, n + r + 2 q conditions. The collocation of ``w' = phi`` integrates phi by
Simpson's rule on the collocation cubic (4th order, like the rest of the discretisation), so
``w(1) = 0`` is the discretised integral condition. ``mu' = 0`` holds exactly at every Newton
iterate after the first (its equations are linear and their Jacobian rows exact), so the
module is called with the scalar mu = mu(0) and the Jacobian places d f / d mu at each node's
own copy of mu: on constant mu the two formulations, and their Newton steps, coincide.

Everything else in the engine sees an ordinary problem with more states; ordinates, the
second variation and the stored parameter values see the module's states and the free
parameters' current values.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import ProblemError
from .interface import Wrapper

#: The name of `Wrapper` before the problem interface (the old path
#: ``elastica_auto.augmented.NamesOfBase``, docs/api.md's deprecated paths).
NamesOfBase = Wrapper


class Augmented(Wrapper):
    """``base`` (a :class:`~elastica_auto.model.problem.Problem`) with its integral conditions and
    the free parameters ``free`` as extra states (see the module docstring): its ``solved``
    are ``free``, its starts are solved from (``approximate_start``). It forwards the
    module's drawing and refuses the hooks that read or move the states it adds
    (`REFUSED`)."""

    REFUSED = {
        "shooting": "the shooting scan enumerates the module's states at fixed parameters, "
                    "and the free parameters are solved for",
        "gradient_flow": "the module's dynamics hold every parameter fixed, the free ones too",
        "symmetry": "the group acts on the module's states; the running integrals and the "
                    "free parameters carried as states have no declared image under it",
        "symmetric_values": "they place branch points where the symmetry holds, and the "
                            "symmetry is refused",
        "mirror": "the reflection is declared on the module's states and parameters; the "
                  "running integrals and the free parameters carried as states have no "
                  "declared image under it",
    }
    approximate_start = True

    def __init__(self, base, free):
        free = tuple(free)
        for q in free:
            if q not in base.parameters:
                raise ProblemError(f"{base.source}: free parameter {q!r} is not a parameter; "
                                   f"PARAMETERS are {', '.join(base.parameters)}")
        if len(set(free)) != len(free):
            raise ProblemError(f"{base.source}: free parameters {list(free)} repeat a name")
        if len(free) != base.extra_conditions:
            extra = (f"{base.nbc} boundary conditions for {base.n} states"
                     + (f" and {len(base.integral_names)} integral conditions"
                        if base.integral_names else ""))
            raise ProblemError(f"{base.source}: {extra} need {base.extra_conditions} free "
                               f"parameters, got {len(free)} ({', '.join(free) or 'none'})")
        self.base, self.free = base, free
        self.module, self.source, self.name = base.module, base.source, base.name
        self.parameters, self.ordinates = base.parameters, base.ordinates
        self.n0, self.q = base.n, len(base.integral_names)
        self.states = (*base.states, *(f"int:{w}" for w in base.integral_names),
                       *(f"free:{mu}" for mu in free))
        self.n = self.nbc = len(self.states)
        self._mu = np.arange(self.n0 + self.q, self.n)          # rows of mu in y
        self.integral_names = ()
        self.doc = base.doc
        self.solved = free

    @property
    def extra_conditions(self) -> int:
        return 0

    def with_free(self, free=None):
        return self if free is None or tuple(free) == self.free else self.base.with_free(free)

    # -- the square problem ---------------------------------------------------------------------
    def _p(self, p, y):
        """``p`` with the free parameters' values from the states (their first node)."""
        y = np.asarray(y)
        mu = (y[self._mu, 0] if y.ndim == 2 else y[self._mu]).tolist()
        out = dict(p)
        out.update(zip(self.free, mu))
        return out

    def point_params(self, params, y):
        return self._p(params, y)

    def rhs(self, s, y, p):
        pm = self._p(p, y)
        y0 = y[: self.n0]
        out = np.empty(y.shape)
        out[: self.n0] = self.base.rhs(s, y0, pm)
        if self.q:
            out[self.n0: self.n0 + self.q] = self.base.integrals(s, y0, pm)
        out[self.n0 + self.q:] = 0.0
        return out

    def rhs_jac(self, s, y, p):
        pm = self._p(p, y)
        y0, n0, q = y[: self.n0], self.n0, self.q
        jac = np.zeros((self.n, self.n, y.shape[1]))
        jac[:n0, :n0] = self.base.rhs_jac(s, y0, pm)
        if q:
            jac[n0: n0 + q, :n0] = self.base.integrals_jac(s, y0, pm)
        for k, mu in zip(self._mu, self.free):
            jac[:n0, k] = self.base.rhs_dp(s, y0, pm, mu)
            if q:
                jac[n0: n0 + q, k] = self.base.integrals_dp(s, y0, pm, mu)
        return jac

    def rhs_dp(self, s, y, p, name):
        pm = self._p(p, y)
        y0 = y[: self.n0]
        out = np.zeros(y.shape)
        out[: self.n0] = self.base.rhs_dp(s, y0, pm, name)
        if self.q:
            out[self.n0: self.n0 + self.q] = self.base.integrals_dp(s, y0, pm, name)
        return out

    def bc(self, ya, yb, p):
        pm = self._p(p, ya)
        w = slice(self.n0, self.n0 + self.q)
        return np.concatenate((self.base.bc(ya[: self.n0], yb[: self.n0], pm), ya[w], yb[w]))

    def bc_jac(self, ya, yb, p):
        """The boundary Jacobian. mu is read at s = 0 but equals its value at s = 1 at every
        iterate (``mu' = 0`` is solved exactly), so a condition's derivative in mu may sit
        in either end's column: in the column of the end the module's condition involves
        (s = 0 if it involves y(0)). A condition at s = 1 alone then stays one-sided, and
        the banded system needs no running sum for it (:mod:`elastica_auto.numerics.bordered`)."""
        pm = self._p(p, ya)
        n0, q, nbc = self.n0, self.q, self.base.nbc
        da, db = np.zeros((self.n, self.n)), np.zeros((self.n, self.n))
        ga, gb = self.base.bc_jac(ya[:n0], yb[:n0], pm)
        da[:nbc, :n0], db[:nbc, :n0] = ga, gb
        at_0 = np.any(da[:nbc, :n0] != 0, axis=1)
        for k, mu in zip(self._mu, self.free):
            dmu = self.base.bc_dp(ya[:n0], yb[:n0], pm, mu)
            da[:nbc, k] = np.where(at_0, dmu, 0.0)
            db[:nbc, k] = np.where(at_0, 0.0, dmu)
        for j in range(q):
            da[nbc + j, n0 + j] = 1.0
            db[nbc + q + j, n0 + j] = 1.0
        return da, db

    def bc_dp(self, ya, yb, p, name):
        pm = self._p(p, ya)
        return np.concatenate((self.base.bc_dp(ya[: self.n0], yb[: self.n0], pm, name),
                               np.zeros(2 * self.q)))

    # -- what sees the module's own states ------------------------------------------------------
    def ordinate_values(self, s, y, p, known=None):
        return self.base.ordinate_values(s, y[: self.n0], self._p(p, y), known)

    @property
    def has_second_variation(self) -> bool:
        return self.base.has_second_variation

    def second_variation(self, s, y, p):
        return self.base.second_variation(s, y[: self.n0], self._p(p, y))

    def exact_start(self, s, p):
        """The module's exact start, completed with the running integrals (trapezoidal) and
        the free parameters' values in ``p``; it satisfies the integral conditions only
        approximately, so it is always solved from (see `execution.run.build_start`)."""
        return self.complete(s, self.base.exact_start(s, p), p)

    def guess(self, s, p):
        return self.complete(s, self.base.guess(s, p), p)

    def complete(self, s, y0, p):
        """The states (n, len(s)) from the module's states ``y0``: the running integrals of
        the integrands (trapezoidal) and the free parameters' values, those of the rows
        after the states' where ``y0`` has them (a guess that found them, `Problem.guess`),
        else those in ``p``."""
        if y0 is None:
            return None
        y = np.zeros((self.n, len(s)))
        if len(y0) == self.n0 + len(self.free):
            p = {**p, **dict(zip(self.free, np.asarray(y0)[self.n0:, 0]))}
            y0 = np.asarray(y0)[: self.n0]
        y[: self.n0] = y0
        if self.q:
            phi = self.base.integrals(s, y0, p)
            h = np.diff(s)
            y[self.n0: self.n0 + self.q, 1:] = np.cumsum(h * (phi[:, 1:] + phi[:, :-1]) / 2,
                                                         axis=1)
        y[self._mu] = np.array([p[mu] for mu in self.free])[:, None]
        return y
