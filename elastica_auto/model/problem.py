"""The equation-module protocol and the `Problem` object the engine works with.

An equation module is a plain Python file. It declares

``STATES``
    tuple of state names, e.g. ``("theta", "kappa", "x", "y")``; n = len(STATES).
``PARAMETERS``
    list of :class:`Parameter`: name, default, TeX label, and where it enters the problem:
    ``"fixed"`` (boundary condition at s = 0), ``"free"`` (boundary condition or end term at
    s = 1) or ``"ode"`` (the differential equation). Angles declare ``period=2*pi``, and
    what a period does to the states where it changes them (``period_shift``,
    ``period_flip``: :class:`Parameter`).
``ORDINATES``
    list of :class:`Ordinate`: named output functionals ``fn(s, y, p) -> float`` of a solution.
    Parameter and ordinate names become columns of the branch files, so none may contain
    ``/`` or NUL or be one of :data:`RESERVED_NAMES` (``index``, ``type``, ``label``, ...);
    no name (a state's either) may contain NUL.
``rhs(s, y, p)``
    vectorised right-hand side, ``s`` shape (m,), ``y`` shape (n, m), returns (n, m);
    ``p`` is a ``dict`` of parameter values by name.
``bc(ya, yb, p)``
    the boundary residuals, shape (n,); or (n + r,) with r more conditions than states, for
    as many free parameters (AUTO-07p's NBC > NDIM; below).

and optionally

``rhs_jac(s, y, p)``  -> (n, n, m), ``bc_jac(ya, yb, p)`` -> ((n, n), (n, n)),
``rhs_dp(s, y, p, name)`` -> (n, m), ``bc_dp(ya, yb, p, name)`` -> (n,)
    analytic derivatives; central differences are used for whatever is missing.
``exact_start(s, p)``
    an exact solution on the mesh ``s`` for parameter values ``p``, or ``None`` where the module
    knows none (used by ``start = "trivial"`` in run files).
``guess(s, p)``
    an approximate solution (n, len(s)) at ``p``, or ``None``; where there is no exact start,
    a start from parameter values solves the problem there from this guess first.
``INTEGRALS``, ``integrals(s, y, p)`` -> (q, m)
    names of q integral conditions ``int_0^1 phi_j(s, y; p) ds = 0`` and their integrands
    (AUTO-07p's NINT); optionally ``integrals_jac(s, y, p)`` -> (q, n, m) and
    ``integrals_dp(s, y, p, name)`` -> (q, m).
``FREE``
    the parameters solved for when there are more conditions (r + q) than states: as many
    names as extra conditions. A run may name others (``free = [...]``).
``second_variation(s, y, p)`` -> `SecondVariation`
    the second variation of the energy at the solution ``y`` on the points ``s`` (sorted, from
    0 to 1): ``int_0^1 (h'.A h' + 2 h'.C h + h.B h) ds`` plus end terms, for perturbations
    h(s) in R^k, with the end conditions and constraints that the admissible h satisfy
    (`elastica_auto.model.second_variation`); or the scalar tuple ``(a, b, c)`` for ``int_0^1
    (a h'^2 + b h^2) ds + c h(1)^2`` with ``h(0) = 0``. Enables the stability index (see
    `elastica_auto.numerics.stability`).
``shooting(p)`` -> ``(k_lo, k_hi, initial, residual[, reflection])``
    a shooting formulation: the equilibria at ``p`` are the roots k in [k_lo, k_hi] of
    ``residual(initial(k), y(1))``; enables the scan for snap-back targets (see
    `elastica_auto.analysis.snaps`). ``reflection``: signs S with the roots in pairs k, S k
    at ``p``, or None (`elastica_auto.analysis.equilibria`).
``gradient_flow(p, nodes)`` -> `elastica_auto.analysis.landing.Flow`
    the energy of the equilibria at ``p`` discretised on ``nodes`` (a uniform grid of
    [0, 1]) and its overdamped dynamics; enables where a snap lands (see
    `elastica_auto.analysis.landing`).
``symmetry(s, y, p)`` -> `elastica_auto.model.symmetry.Symmetry` or None
    a continuous symmetry of the problem at ``p`` (None where ``p`` breaks it): the
    generator g(y) of a one-parameter group that maps solutions to solutions and an unfolding
    field b(y) outside the range of the linearisation (the gradient of the conserved quantity
    that goes with the group), each (n, m). A branch that starts at a state the group moves
    is continued with a phase condition and an unfolding parameter (see
    `elastica_auto.model.symmetry`).
``symmetric_values(name, lo, hi, p)`` -> list of floats
    the values of the parameter ``name`` in [lo, hi] at which ``symmetry`` applies, the other
    parameters at ``p`` (needs ``symmetry``). A branch continued in ``name`` that crosses one
    on states the group moves passes a branch point there (the generator is in the kernel):
    the engine places it at that value, with no search (see
    `elastica_auto.branches.stepper`).
``draw(ax, profile, params)``
    draws the configuration of a solution on the matplotlib axes ``ax``: ``profile`` is the
    solution on the branch file's profile grid, shape (n, len(grid)), ``params`` its parameter
    values; enables the configurations in figures (see `elastica_auto.plots.layout`).
``DRAW_PROJECTION``
    the matplotlib projection of the axes ``draw`` gets (``"3d"`` for a spatial
    configuration); default None, plain 2D axes.
``MIRROR``
    a :class:`Mirror`: a reflection that maps the solutions at ``p`` to solutions at ``p``
    with some parameters negated. A branch from a start that is its own mirror image, in a
    parameter the mirror negates, is computed in one direction and mirrored into the other
    (see `elastica_auto.branches.mirror`).

Only equation modules know any physics; everything in `elastica_auto` is generic.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import math
import numbers
import os
import re
import sys
import types
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..core.errors import ProblemError
from .interface import ProblemInterface
from .second_variation import Constraint, SecondVariation  # noqa: F401  (for modules)

ENTERS = ("fixed", "free", "ode")

#: Column names the engine itself uses next to the parameters and ordinates: the columns of a
#: stored branch (`storage.store._write_branch`) and the extra fields of its rows and CSV
#: export (`store.rows`, `store.export_csv`). A parameter or ordinate of the same name would
#: overwrite one of them, so none may be named so; keep this in step with store.py.
RESERVED_NAMES = frozenset({
    "arclength", "ds", "fold_residual", "niter", "nodes", "label", "index", "index_rule",
    "index_direct", "type", "note", "transition", "branch", "pt"})


def _sequence(source, name, value, kind):
    """``value`` as a tuple, checked to be a list or tuple of ``kind`` (not a bare string)."""
    if not isinstance(value, (list, tuple)):
        raise ProblemError(f"{source}: {name} must be a list or tuple of {kind.__name__}, "
                           f"got {type(value).__name__}")
    for i, v in enumerate(value):
        if not isinstance(v, kind):
            raise ProblemError(f"{source}: {name}[{i}] must be a {kind.__name__}, "
                               f"got {type(v).__name__}")
    return tuple(value)


@dataclass(frozen=True)
class Parameter:
    """A named parameter: default value, TeX label, where it enters, optional period.

    A period's effect on the solutions, where it has one (the default is none: the same
    states solve the problem at ``value + period``): ``period_shift`` maps state names to
    what one period adds to them (the clamp turned by a whole turn turns the tangent angle
    ``theta`` by 2 pi: ``{"theta": 2 * math.pi}``), and ``period_flip`` names the states
    one period turns to their negatives (a quaternion of the clamp's frame, a double cover:
    a whole turn is -q)."""

    name: str
    default: float
    tex: str
    enters: str
    period: float | None = None
    doc: str = ""
    period_shift: tuple = ()
    period_flip: tuple = ()

    def __post_init__(self):
        if self.enters not in ENTERS:
            raise ProblemError(
                f"parameter {self.name!r}: enters={self.enters!r}, expected one of {ENTERS}")
        shift = self.period_shift
        pairs = tuple(shift.items()) if isinstance(shift, dict) else tuple(shift)
        if not all(isinstance(k, str) and isinstance(v, numbers.Real)
                   and not isinstance(v, bool) and math.isfinite(v) for k, v in pairs):
            raise ProblemError(f"parameter {self.name!r}: period_shift must map state names "
                               f"to finite numbers, got {shift!r}")
        flip = self.period_flip
        if isinstance(flip, str) or not all(isinstance(k, str) for k in flip):
            raise ProblemError(f"parameter {self.name!r}: period_flip must be a tuple of "
                               f"state names, got {flip!r}")
        if (pairs or flip) and self.period is None:
            raise ProblemError(f"parameter {self.name!r}: period_shift and period_flip need "
                               "a period")
        object.__setattr__(self, "period_shift", pairs)
        object.__setattr__(self, "period_flip", tuple(flip))


@dataclass(frozen=True)
class Mirror:
    """A reflection of the problem: if y solves it at p, then y' solves it at p', where

    * y'[a] = y[b] for each pair ``a: b`` of ``states``, y'[a] = -y[b] for ``a: "-b"``, and
      y'[a] = y[a] for a state not named (a signed permutation, its own inverse);
    * p' is p with the ``parameters`` negated;

    the energy is the same at both, so the stability index is, and the ``ordinates`` are
    negated (the others are the same at both). ``shooting``, if given: the signs s of the
    image's shooting unknowns (the ``shooting`` hook's k -> s k, one sign per unknown), with
    which the equilibria at mirrored parameters are the images of those enumerated. The
    planar elastica's x -> -x, say: ``Mirror({"theta": "-theta", "kappa": "-kappa", "x":
    "-x"}, ("psi", "alpha", "theta0"), ("m1", "mA", "m0"), shooting=(-1,))``."""

    states: tuple = ()
    parameters: tuple = ()
    ordinates: tuple = ()
    shooting: tuple = ()

    def __post_init__(self):
        pairs = self.states
        pairs = tuple(pairs.items()) if isinstance(pairs, dict) else tuple(pairs)
        if not all(isinstance(a, str) and isinstance(b, str) and b.lstrip("-")
                   for a, b in pairs):
            raise ProblemError(f"MIRROR: states must map state names to state names (\"-name\" "
                               f"for the negative), got {self.states!r}")
        for what in ("parameters", "ordinates"):
            names = getattr(self, what)
            if isinstance(names, str) or not all(isinstance(k, str) for k in names):
                raise ProblemError(f"MIRROR: {what} must be a tuple of names, got {names!r}")
            object.__setattr__(self, what, tuple(names))
        object.__setattr__(self, "states", pairs)
        signs = self.shooting
        if isinstance(signs, str) or not all(not isinstance(v, bool) and v in (1, -1)
                                             for v in signs):
            raise ProblemError(f"MIRROR: shooting must be a tuple of signs (1 or -1), got "
                               f"{signs!r}")
        object.__setattr__(self, "shooting", tuple(float(v) for v in signs))


@dataclass(frozen=True)
class Ordinate:
    """A named output functional of a solution, ``fn(s, y, p) -> float``.

    ``parameter`` names the parameter whose distinguished bifurcation diagram uses this ordinate
    (None if it is not one).
    """

    name: str
    tex: str
    fn: Callable
    parameter: str | None = None
    doc: str = ""


def _shape_of(value) -> str:
    shape = getattr(value, "shape", None)
    return f"shape {shape}" if shape is not None else f"a {type(value).__name__}"


def _fd_step(v):
    return 1e-6 * (1.0 + np.abs(v))


class Problem(ProblemInterface):
    """An equation module wrapped with validation and finite-difference fallbacks: the
    module's own problem (`elastica_auto.model.interface`; it refuses no hook).

    Parameters
    ----------
    module : module
        The loaded equation module.
    source : str
        Where it came from (shipped name or file path), for messages and for the HDF5 file.
    """

    #: The module's source text, if it was loaded from a file (`load_problem`): a problem
    #: pickles as that text (see `_from_text`), not as its module object.
    _text: str | None = None
    #: The module derived from its ENERGY, if it has one (`elastica_auto.energy`): it travels
    #: with the text, so that a Dask worker executes it and never derives.
    _generated: str | None = None

    @property
    def generated(self) -> str | None:
        """The source of the module derived from the module's ENERGY (what the cache keeps
        and ``elastica-auto derive`` prints from), or None for a module without one."""
        return self._generated

    def __reduce_ex__(self, protocol):
        if self._text is None:
            return super().__reduce_ex__(protocol)
        return _from_text, (self.source, self.module.__file__, self._text, self._generated)

    def __init__(self, module, source: str):
        self.module = module
        self.source = source
        self.name = Path(source).stem
        for attr in ("STATES", "PARAMETERS", "rhs", "bc"):
            if not hasattr(module, attr):
                raise ProblemError(f"{source}: equation module defines no {attr}")
        self.states = _sequence(source, "STATES", module.STATES, str)
        self.n = len(self.states)
        if self.n == 0:
            raise ProblemError(f"{source}: STATES is empty")
        parameters = _sequence(source, "PARAMETERS", module.PARAMETERS, Parameter)
        ordinates = _sequence(source, "ORDINATES", getattr(module, "ORDINATES", []), Ordinate)
        for q in parameters:
            d = q.default
            if isinstance(d, bool) or not isinstance(d, numbers.Real) or not math.isfinite(d):
                raise ProblemError(f"{source}: parameter {q.name!r}: default must be a finite "
                                   f"number, got {d!r}")
        for what, entries in (("parameter", parameters), ("ordinate", ordinates)):
            for x in entries:
                # HDF5 reads '/' as a group separator and '.' as the group itself, and its
                # names and strings end at a NUL
                if not isinstance(x.name, str) or x.name in ("", ".") or "/" in x.name \
                        or "\0" in x.name or x.name in RESERVED_NAMES:
                    raise ProblemError(
                        f"{source}: {what} name {x.name!r} cannot name a column of the branch "
                        f"files; use a non-empty string other than '.', without '/' or NUL, "
                        f"and none of {', '.join(sorted(RESERVED_NAMES))}")
        for x in self.states:
            if "\0" in x:   # stored in the branch files' strings, which end at a NUL
                raise ProblemError(f"{source}: state name {x!r} contains a NUL character")
        self.parameters = {q.name: q for q in parameters}
        if len(self.parameters) != len(parameters):
            raise ProblemError(f"{source}: duplicate parameter names in PARAMETERS")
        for q in parameters:
            unknown = [k for k, _ in q.period_shift if k not in self.states] + \
                [k for k in q.period_flip if k not in self.states]
            if unknown:
                raise ProblemError(f"{source}: parameter {q.name!r}: period_shift and "
                                   f"period_flip name no state {unknown}; STATES are "
                                   f"{', '.join(self.states)}")
        self.ordinates = {o.name: o for o in ordinates}
        self.mirror = self._checked_mirror(getattr(module, "MIRROR", None))
        clash = set(self.ordinates) & set(self.parameters)
        if clash:
            raise ProblemError(f"{source}: names used both as parameter and ordinate: "
                               f"{sorted(clash)}")
        self.doc = (module.__doc__ or "").strip()
        self._rhs_jac = getattr(module, "rhs_jac", None)
        self._bc_jac = getattr(module, "bc_jac", None)
        self._rhs_dp = getattr(module, "rhs_dp", None)
        self._bc_dp = getattr(module, "bc_dp", None)
        self._exact_start = getattr(module, "exact_start", None)
        self._second_variation = getattr(module, "second_variation", None)
        self._shooting = getattr(module, "shooting", None)
        self._gradient_flow = getattr(module, "gradient_flow", None)
        self._draw = getattr(module, "draw", None)
        self._symmetry = getattr(module, "symmetry", None)
        self._symmetric_values = getattr(module, "symmetric_values", None)
        if self._symmetric_values is not None and self._symmetry is None:
            raise ProblemError(f"{source}: symmetric_values(name, lo, hi, p) needs the hook "
                               "symmetry(s, y, p), the symmetry that holds there")
        if self._draw is not None and not callable(self._draw):
            raise ProblemError(f"{source}: draw must be a function draw(ax, profile, params), "
                               f"got {type(self._draw).__name__}")
        self.draw_projection = getattr(module, "DRAW_PROJECTION", None)
        if self.draw_projection is not None and not isinstance(self.draw_projection, str):
            raise ProblemError(f"{source}: DRAW_PROJECTION must be a matplotlib projection "
                               f"name such as '3d', got {self.draw_projection!r}")
        self._guess = getattr(module, "guess", None)
        self.integral_names = _sequence(source, "INTEGRALS", getattr(module, "INTEGRALS", ()),
                                        str)
        for x in self.integral_names:
            if "\0" in x:   # named in the states of a stored solution (int:NAME)
                raise ProblemError(f"{source}: integral name {x!r} contains a NUL character")
        self._integrals = getattr(module, "integrals", None)
        self._integrals_jac = getattr(module, "integrals_jac", None)
        self._integrals_dp = getattr(module, "integrals_dp", None)
        if bool(self.integral_names) != (self._integrals is not None):
            raise ProblemError(f"{source}: INTEGRALS and integrals(s, y, p) go together; "
                               "define both or neither")
        self.free = _sequence(source, "FREE", getattr(module, "FREE", ()), str)
        unknown = [q for q in self.free if q not in self.parameters]
        if unknown:
            raise ProblemError(f"{source}: FREE names unknown parameters {unknown}; "
                               f"PARAMETERS are {', '.join(self.parameters)}")
        self.nbc = self.n
        self.n0 = self.n
        self._check_shapes()

    def _checked_mirror(self, mirror):
        """``MIRROR`` checked against the names, as (rows, signs, mirror): y' = signs * y[rows]
        (None if the module declares none)."""
        if mirror is None:
            return None
        source = self.source
        if not isinstance(mirror, Mirror):
            raise ProblemError(f"{source}: MIRROR must be a Mirror, got "
                               f"{type(mirror).__name__}")
        unknown = [a for pair in mirror.states for a in (pair[0], pair[1].lstrip("-"))
                   if a not in self.states]
        unknown += [k for k in mirror.parameters if k not in self.parameters]
        unknown += [k for k in mirror.ordinates if k not in self.ordinates]
        if unknown:
            raise ProblemError(f"{source}: MIRROR names {sorted(set(unknown))}, which are not "
                               "states, parameters or ordinates of the module")
        index = {name: i for i, name in enumerate(self.states)}
        rows, signs = np.arange(self.n), np.ones(self.n)
        for a, b in mirror.states:
            rows[index[a]], signs[index[a]] = index[b.lstrip("-")], -1.0 if b[0] == "-" else 1.0
        twice = np.arange(self.n)[rows][rows], (signs * signs[rows])
        if len(set(rows.tolist())) != self.n or not (np.array_equal(twice[0], np.arange(self.n))
                                                     and np.all(twice[1] == 1.0)):
            raise ProblemError(f"{source}: MIRROR: states {dict(mirror.states)} is not a signed "
                               "permutation that is its own inverse (a reflection twice is "
                               "the identity)")
        return rows, signs, mirror

    def mirrored(self, y, params: dict):
        """The mirror image (`Mirror`) of node values ``y`` (states first, any trailing shape)
        and ``params``; rows of ``y`` past the module's states are kept."""
        rows, signs, mirror = self.mirror
        out = np.array(y, dtype=float)
        # (+ 0.0: an image of 0 is 0, not -0.0, whose sign would reach sines and printouts)
        out[: self.n] = signs.reshape((-1,) + (1,) * (out.ndim - 1)) * np.asarray(y)[rows] + 0.0
        return out, {k: -v + 0.0 if k in mirror.parameters else v for k, v in params.items()}

    def mirrored_ordinates(self, ordinates: dict) -> dict:
        """The ordinates of the mirror image of a solution with ``ordinates``: those the
        mirror declares odd negated (0, not -0.0), the others the same."""
        odd = self.mirror[2].ordinates
        return {k: -v + 0.0 if k in odd else v for k, v in ordinates.items()}

    # -- names ---------------------------------------------------------------------------------
    @property
    def parameter_names(self) -> list[str]:
        return list(self.parameters)

    @property
    def ordinate_names(self) -> list[str]:
        return list(self.ordinates)

    def defaults(self) -> dict[str, float]:
        return {k: float(q.default) for k, q in self.parameters.items()}

    # -- the BVP -------------------------------------------------------------------------------
    def rhs(self, s, y, p):
        """f(s, y; p), shape (n, m). Checked on every call (a shape compare): a module that
        misbehaves only on some meshes is named, not left to fail deep in the engine."""
        out = self.module.rhs(s, y, p)
        if getattr(out, "shape", None) != y.shape:
            raise ProblemError(f"{self.source}: rhs(s, y, p) returned {_shape_of(out)}; "
                               f"expected {y.shape} (the shape of y)")
        return out

    def bc(self, ya, yb, p):
        return np.asarray(self.module.bc(ya, yb, p), dtype=float)

    def rhs_jac(self, s, y, p):
        """df/dy, shape (n, n, m): the module's, or central differences."""
        if self._rhs_jac is not None:
            out = self._rhs_jac(s, y, p)
            if getattr(out, "shape", None) != (self.n, self.n, y.shape[1]):
                raise ProblemError(f"{self.source}: rhs_jac(s, y, p) returned "
                                   f"{_shape_of(out)}; expected {(self.n, self.n, y.shape[1])}")
            return out
        jac = np.empty((self.n, self.n, y.shape[1]))
        for j in range(self.n):
            h = _fd_step(y[j])
            yp, ym = y.copy(), y.copy()
            yp[j] += h
            ym[j] -= h
            jac[:, j, :] = (self.rhs(s, yp, p) - self.rhs(s, ym, p)) / (2 * h)
        return jac

    def bc_jac(self, ya, yb, p):
        """(dbc/dya, dbc/dyb), each (nbc, n): the module's, or central differences."""
        if self._bc_jac is not None:
            return self._bc_jac(ya, yb, p)
        da = np.empty((self.nbc, self.n))
        db = np.empty((self.nbc, self.n))
        for j in range(self.n):
            e = np.zeros(self.n)
            e[j] = _fd_step(ya[j])
            da[:, j] = (self.bc(ya + e, yb, p) - self.bc(ya - e, yb, p)) / (2 * e[j])
            e[j] = _fd_step(yb[j])
            db[:, j] = (self.bc(ya, yb + e, p) - self.bc(ya, yb - e, p)) / (2 * e[j])
        return da, db

    def rhs_dp(self, s, y, p, name):
        """df/d(p[name]), shape (n, m)."""
        if self._rhs_dp is not None:
            return self._rhs_dp(s, y, p, name)
        h = _fd_step(p[name])
        return (self.rhs(s, y, {**p, name: p[name] + h})
                - self.rhs(s, y, {**p, name: p[name] - h})) / (2 * h)

    def bc_dp(self, ya, yb, p, name):
        """dbc/d(p[name]), shape (n,)."""
        if self._bc_dp is not None:
            return np.asarray(self._bc_dp(ya, yb, p, name), dtype=float)
        h = _fd_step(p[name])
        return (self.bc(ya, yb, {**p, name: p[name] + h})
                - self.bc(ya, yb, {**p, name: p[name] - h})) / (2 * h)

    def ordinate_values(self, s, y, p, known=None) -> dict[str, float]:
        """The ordinates at the solution ``y`` on the nodes ``s``; those in ``known`` (a
        dict, e.g. the index of each part of the second variation counted at this state:
        `SecondVariation` ``parts``) taken from it instead of computed."""
        known = known or {}
        return {k: float(known[k]) if k in known else float(o.fn(s, y, p))
                for k, o in self.ordinates.items()}

    def point_params(self, params: dict, y) -> dict[str, float]:
        """The parameter values of a solution (free parameters are part of ``y`` in
        `elastica_auto.model.augmented`; here there are none)."""
        return dict(params)

    @property
    def module_problem(self) -> "Problem":
        """This problem: it is the module's own."""
        return self

    # -- integral conditions and free parameters ---------------------------------------------
    @property
    def extra_conditions(self) -> int:
        """Conditions beyond one per state: extra boundary rows plus integral conditions; the
        number of free parameters a continuation needs."""
        return self.nbc - self.n + len(self.integral_names)

    def integrals(self, s, y, p):
        """The integrands phi (q, m) of the conditions int_0^1 phi ds = 0."""
        out = np.asarray(self._integrals(s, y, p), dtype=float)
        if out.shape != (len(self.integral_names), y.shape[1]):
            raise ProblemError(f"{self.source}: integrals(s, y, p) returned shape {out.shape}; "
                               f"expected {(len(self.integral_names), y.shape[1])}")
        return out

    def integrals_jac(self, s, y, p):
        """d phi / dy, shape (q, n, m): the module's, or central differences."""
        if self._integrals_jac is not None:
            return np.asarray(self._integrals_jac(s, y, p), dtype=float)
        jac = np.empty((len(self.integral_names), self.n, y.shape[1]))
        for j in range(self.n):
            h = _fd_step(y[j])
            yp, ym = y.copy(), y.copy()
            yp[j] += h
            ym[j] -= h
            jac[:, j, :] = (self.integrals(s, yp, p) - self.integrals(s, ym, p)) / (2 * h)
        return jac

    def integrals_dp(self, s, y, p, name):
        """d phi / d(p[name]), shape (q, m)."""
        if self._integrals_dp is not None:
            return np.asarray(self._integrals_dp(s, y, p, name), dtype=float)
        h = _fd_step(p[name])
        return (self.integrals(s, y, {**p, name: p[name] + h})
                - self.integrals(s, y, {**p, name: p[name] - h})) / (2 * h)

    def with_free(self, free=None) -> "Problem":
        """The problem the engine solves: this one if it has one condition per state, else
        the one with the integral conditions and the free parameters ``free`` (default the
        module's ``FREE``) carried as extra states (`elastica_auto.model.augmented`).
        ProblemError if the number of free parameters is not the number of extra
        conditions."""
        free = tuple(self.free if free is None else free)
        if not free and not self.extra_conditions:
            return self
        from .augmented import Augmented
        return Augmented(self, free)

    def guess(self, s, p):
        """The module's approximate solution on mesh ``s`` at ``p``, or None. A module with
        free parameters (``FREE``) may give their values too, as constant rows after the
        states' ((n + len(FREE), len(s))): the start is solved from them
        (`elastica_auto.model.augmented.Augmented.complete`), not from ``p``'s."""
        if self._guess is None:
            return None
        y = self._guess(s, p)
        if y is None:
            return None
        y = np.asarray(y, dtype=float)
        if y.shape not in ((self.n, len(s)), (self.n + len(self.free), len(s))):
            raise ProblemError(f"{self.source}: guess(s, p) returned shape {y.shape}; "
                               f"expected {(self.n, len(s))} = (len(STATES), len(s))"
                               + (f", or {(self.n + len(self.free), len(s))} with the free "
                                  "parameters' values" if self.free else ""))
        return y

    @property
    def has_second_variation(self) -> bool:
        return self._second_variation is not None

    def second_variation(self, s, y, p):
        """The module's second variation at ``y`` on ``s``: a `SecondVariation`, or the
        scalar tuple ``(a, b, c[, constraints])``."""
        return self._second_variation(s, y, p)

    @property
    def has_shooting(self) -> bool:
        return self._shooting is not None

    def shooting(self, p):
        """(k_lo, k_hi, initial(k) -> y(0), residual(y(0), y(1))) for enumerating equilibria."""
        return tuple(self._shooting(p))[:4]

    def shooting_reflection(self, p):
        """The signs S (d,) of the shooting box's reflection at ``p`` (the roots k come in
        pairs k, S k): the hook's optional fifth item, checked; None where it gives none."""
        out = tuple(self._shooting(p))
        if len(out) < 5 or out[4] is None:
            return None
        lo, hi, signs = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (*out[:2], out[4]))
        if not (lo.ndim == 1 and len(lo) >= 2 and signs.shape == lo.shape
                and np.all(np.abs(signs) == 1) and np.any(signs < 0)):
            raise ProblemError(f"{self.source}: shooting(p)'s reflection must be {len(lo)} "
                               f"signs (1 or -1, one -1 at least) of a box of two or more "
                               f"unknowns; got {out[4]!r}")
        if np.any((signs < 0) & (lo != -hi)):
            raise ProblemError(f"{self.source}: shooting(p)'s reflection {out[4]!r} flips "
                               "components whose box is not symmetric (k_lo != -k_hi)")
        return signs

    @property
    def has_gradient_flow(self) -> bool:
        return self._gradient_flow is not None

    def gradient_flow(self, p, nodes):
        """The module's `elastica_auto.analysis.landing.Flow` at ``p`` on ``nodes``."""
        return self._gradient_flow(dict(p), np.asarray(nodes, dtype=float))

    @property
    def has_symmetry(self) -> bool:
        return self._symmetry is not None

    def symmetry(self, s, y, p):
        """The module's `Symmetry` at ``y`` on ``s`` (generator and unfolding, each of y's
        shape), or None where ``p`` breaks the symmetry."""
        from .symmetry import Symmetry
        out = self._symmetry(s, y, p)
        if out is None:
            return None
        if not isinstance(out, Symmetry):
            raise ProblemError(f"{self.source}: symmetry(s, y, p) returned "
                               f"{type(out).__name__}; expected a Symmetry(generator, "
                               "unfolding) or None")
        g, b = (np.asarray(v, dtype=float) for v in out)
        for what, v in (("generator", g), ("unfolding", b)):
            if v.shape != y.shape:
                raise ProblemError(f"{self.source}: symmetry(s, y, p).{what} has shape "
                                   f"{v.shape}; expected {y.shape} (the shape of y)")
        return Symmetry(g, b)

    @property
    def has_symmetric_values(self) -> bool:
        return self._symmetric_values is not None

    def symmetric_values(self, name: str, lo: float, hi: float, p) -> list[float]:
        """The module's values of the parameter ``name`` in [lo, hi] at which the symmetry
        applies (the other parameters at ``p``), sorted; ProblemError where it answers with
        anything but finite numbers in [lo, hi]."""
        out = self._symmetric_values(name, float(lo), float(hi), dict(p))
        try:
            values = sorted(float(v) for v in out)
        except (TypeError, ValueError):
            raise ProblemError(f"{self.source}: symmetric_values(name, lo, hi, p) returned "
                               f"{out!r:.60}; expected a list of numbers") from None
        if not all(math.isfinite(v) and lo <= v <= hi for v in values):
            raise ProblemError(f"{self.source}: symmetric_values({name!r}, {lo:.6g}, {hi:.6g}, "
                               f"p) returned {values}, not all finite and in [lo, hi]")
        return values

    @property
    def has_draw(self) -> bool:
        return self._draw is not None

    def draw(self, ax, profile, params):
        """Draw the configuration of ``profile`` (n, len(grid)) at ``params`` on ``ax``. A
        profile with rows after the module's states (a run's running integrals and free
        parameters, whose values are in ``params``; a curve's null vectors) is drawn from
        the module's rows."""
        profile = np.asarray(profile, dtype=float)
        if profile.ndim == 2 and profile.shape[0] > self.n:
            profile = profile[:self.n]
        if profile.ndim != 2 or profile.shape[0] != self.n:
            raise ProblemError(f"{self.source}: draw(ax, profile, params) needs a profile of "
                               f"shape ({self.n}, len(grid)), got {profile.shape}")
        self._draw(ax, profile, dict(params))

    def exact_start(self, s, p):
        """An exact solution on mesh ``s`` for parameters ``p``, or None if the module has none."""
        if self._exact_start is None:
            return None
        y = self._exact_start(s, p)
        if y is None:
            return None
        y = np.asarray(y, dtype=float)
        if y.shape != (self.n, len(s)):
            raise ProblemError(f"{self.source}: exact_start(s, p) returned shape {y.shape}; "
                               f"expected {(self.n, len(s))} = (len(STATES), len(s))")
        return y

    # -- validation ----------------------------------------------------------------------------
    def _check_shapes(self):
        """Call every function once on a small state and check the shapes it returns."""
        n, m = self.n, 3
        s = np.linspace(0.0, 1.0, m)
        y = np.full((n, m), 0.1)
        p = self.defaults()

        def check(what, value, shape):
            arr = np.asarray(value)
            if arr.shape != shape:
                raise ProblemError(f"{self.source}: {what} returned shape {arr.shape}; "
                                   f"expected {shape}")

        calling = ["rhs"]      # the hook being called, for the message if it raises

        def call(hook, fn, *args):
            calling[0] = hook
            return fn(*args)

        try:
            check("rhs(s, y, p) with y of shape (n, 3)", call("rhs", self.rhs, s, y, p), (n, m))
            g = call("bc", self.bc, y[:, 0], y[:, -1], p)
            if g.ndim != 1 or len(g) < n:
                raise ProblemError(f"{self.source}: bc(ya, yb, p) returned shape {g.shape}; "
                                   f"expected ({n},), or more conditions than states")
            self.nbc = nbc = len(g)
            if self._integrals is not None:
                check("integrals(s, y, p)", call("integrals", self.integrals, s, y, p),
                      (len(self.integral_names), m))
            if self._rhs_jac is not None:
                check("rhs_jac(s, y, p)", call("rhs_jac", self._rhs_jac, s, y, p), (n, n, m))
            if self._bc_jac is not None:
                da, db = call("bc_jac", self._bc_jac, y[:, 0], y[:, -1], p)
                check("bc_jac(ya, yb, p)[0]", da, (nbc, n))
                check("bc_jac(ya, yb, p)[1]", db, (nbc, n))
            for name in self.parameters:
                if self._rhs_dp is not None:
                    check(f"rhs_dp(s, y, p, {name!r})",
                          call("rhs_dp", self._rhs_dp, s, y, p, name), (n, m))
                if self._bc_dp is not None:
                    check(f"bc_dp(ya, yb, p, {name!r})",
                          call("bc_dp", self._bc_dp, y[:, 0], y[:, -1], p, name), (nbc,))
            for o in self.ordinates.values():
                v = call(f"ordinate {o.name!r}", o.fn, s, y, p)
                if np.ndim(v) != 0:
                    raise ProblemError(f"{self.source}: ordinate {o.name!r} returned shape "
                                       f"{np.shape(v)}; expected a scalar")
        except ProblemError:
            raise
        except (Exception, SystemExit) as exc:  # a user module raising on valid input
            from ..core.errors import failure_record, module_files
            record = failure_record(exc, module_files(self.module))
            raise ProblemError(f"{self.source}: calling {calling[0]} on a test state (the "
                               f"defaults, y = 0.1) failed: {record['exception']}: "
                               + " ".join(record["error"].split())
                               + f" ({record['where']})") from exc


def shipped_equations() -> list[str]:
    """Names of the equation modules shipped in ``equations/``. (importlib.resources is
    imported here, for a shipped module: a module given by its path does without it.)"""
    from importlib.resources import files
    root = files("elastica_auto.equations")
    return sorted(p.name[:-3] for p in root.iterdir()
                  if p.name.endswith(".py") and not p.name.startswith("_"))


def periods_applied(problem, name: str, y, k: int, derivative: bool = False):
    """The node values ``y`` (states x points) of a solution at ``value`` turned into those
    of the same solution at ``value + k period`` of parameter ``name`` (its
    ``period_shift`` and ``period_flip``): each shifted state plus k times its shift (not
    for ``derivative``, the states' derivatives, which a shift leaves alone), each flipped
    state times (-1)^k. Rows past the module's states (a phase condition's) are kept.
    ``y`` itself where the period changes no state."""
    par = problem.parameters[name]
    if k == 0 or not (par.period_flip or (par.period_shift and not derivative)):
        return y
    out = np.array(y, dtype=float)
    rows = {state: i for i, state in enumerate(problem.states)}
    if not derivative:
        for state, shift in par.period_shift:
            out[rows[state]] += k * shift
    if k % 2:
        for state in par.period_flip:
            out[rows[state]] *= -1.0
    return out


def load_problem(name_or_path: str | os.PathLike, base_dir: Path | None = None, *,
                 cache: bool = True) -> Problem:
    """Load an equation module by shipped name (``elastica_lever_arm``) or by ``.py`` path.

    Relative paths are resolved against ``base_dir`` (the run file's folder) first, then the
    current directory. A module that defines ``ENERGY()`` gets the names derived from its
    energy that it does not define itself (`elastica_auto.energy`), from the cache of
    generated code unless ``cache`` is False (or ``ELASTICA_AUTO_ENERGY_CACHE=off``).
    """
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise ProblemError(f"load_problem: expected a module name or a path to a .py file, "
                           f"got {name_or_path!r}")
    name_or_path = os.fspath(name_or_path)
    if name_or_path.endswith(".py"):
        candidates = [Path(name_or_path)]
        if base_dir is not None and not Path(name_or_path).is_absolute():
            candidates.insert(0, Path(base_dir) / name_or_path)
        path = next((c for c in candidates if c.is_file()), None)
        if path is None:
            raise ProblemError(f"equation module file not found: {name_or_path}")
        source = str(path)
    else:
        if name_or_path not in shipped_equations():
            raise ProblemError(f"unknown equation module {name_or_path!r}; shipped modules: "
                               f"{', '.join(shipped_equations())}, or give a path to a .py file")
        from importlib.resources import files
        root = files("elastica_auto.equations")
        path = Path(str(root / f"{name_or_path}.py"))
        source = name_or_path
    spec = importlib.util.spec_from_file_location(f"elastica_auto_eq_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    text = path.read_text(encoding="utf-8")
    try:
        with _folder_first(path.parent):
            spec.loader.exec_module(module)
    except Exception as exc:
        raise ProblemError(f"{source}: importing the module failed: "
                           f"{type(exc).__name__}: {exc}") from exc
    except SystemExit as exc:  # else the command would end, with status 0, having done nothing
        raise ProblemError(f"{source}: importing the module called sys.exit({exc.code!r}); "
                           "put script code under if __name__ == \"__main__\":") from exc
    generated = None
    if hasattr(module, "ENERGY"):
        from ..energy.loader import attach
        # the cache of generated code is keyed by the text ENERGY() comes from: the module's
        # own and that of the files beside it that it imported (an energy built from them)
        generated = attach(module, source, text + _sibling_texts(text, path), cache=cache)
    problem = Problem(module, source)
    problem._text, problem._generated = text, generated
    return problem


@contextlib.contextmanager
def _folder_first(folder: Path):
    """The module's own folder first on ``sys.path`` while its top level runs, so that it can
    import a file beside it (``import helpers``) as ``python mine.py`` could; taken off again
    afterwards, so that a user's file named like a library does not shadow it for the rest of
    the command. A worker executes the module's text under its file name and finds the same
    files where that folder exists on its machine (a local cluster); a remote worker without
    them fails to import, as the module's error."""
    entry = str(folder)
    if not folder.is_dir():
        yield
        return
    sys.path.insert(0, entry)
    try:
        yield
    finally:
        try:
            sys.path.remove(entry)
        except ValueError:      # the module took it off itself
            pass


#: an import statement's modules and names: ``import a.b as c, d`` or ``from a.b import (c, d``
_IMPORT = re.compile(r"^[ \t]*(?:import[ \t]+([\w., \t]+)|from[ \t]+([\w.]+)[ \t]+import"
                     r"[ \t]+\(?([\w, \t]*))", re.MULTILINE)


def _sibling_texts(text: str, path: Path) -> str:
    """The texts of the files beside ``path`` that its ``text`` imports (``import helpers``,
    ``from helpers import K``, ``from package import helpers`` where the package is this
    folder: a dotted name's last part, or an imported name, that is a ``.py`` file here; not
    itself), each after its file name, in the order of their names ('' where there are none):
    what its ENERGY() may be built from. Read from the text, so the same for the same files
    whatever this process has loaded before."""
    names = set()
    for plain, package, members in _IMPORT.findall(text):
        for part in (plain.split(",") if plain else [package, *members.split(",")]):
            words = part.split()
            if words:
                names.add(words[0].rsplit(".", 1)[-1])
    texts = []
    for name in sorted(names - {path.stem, "__init__"}):
        file = path.parent / f"{name}.py"
        if file.is_file():
            texts.append(f"\n# {file.name}\n{file.read_text(encoding='utf-8')}")
    return "".join(texts)


@functools.lru_cache(maxsize=8)
def _from_text(source: str, filename: str, text: str, generated: str | None = None) -> Problem:
    """A problem from its module's source text (how a problem travels to a Dask worker): the
    module is executed under its own file name, so tracebacks and diagnostics name its lines
    as on the machine it came from, whether or not the file exists here. ``generated``: the
    module derived from its ENERGY, executed as it is (the worker does not derive).

    Cached: every task of a run carries the same text, and executing it again for each
    (3 ms for the elastica) was half the scheduling cost of a 0.1 s branch. A problem is not
    changed once built, so the tasks of a worker share it as the branches of one process do.
    """
    module = types.ModuleType(f"elastica_auto_eq_{Path(filename).stem}")
    module.__file__ = filename
    with warnings.catch_warnings(), _folder_first(Path(filename).parent):
        # (warnings: the command that sent it has shown them once already)
        warnings.simplefilter("ignore", DeprecationWarning)
        exec(compile(text, filename, "exec"), module.__dict__)
    if generated is not None:
        from ..energy.loader import merge
        merge(module, source, generated)
    problem = Problem(module, source)
    problem._text, problem._generated = text, generated
    return problem

