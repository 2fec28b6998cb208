"""The second variation an equation module returns: a quadratic form in a perturbation h(s).

The hook ``second_variation(s, y, p)`` of an equation module gets the points ``s`` (sorted,
``s[0] = 0``, ``s[-1] = 1``), the solution ``y`` there and the parameter values, and returns
a :class:`SecondVariation`, the form ::

    d2E[h] = int_0^1 ( h'.A h' + 2 h'.C h + h.B h ) ds + h(0).E0 h(0) + h(1).E1 h(1)

for perturbations h(s) in R^k, on the h that satisfy

* the essential end conditions ``G0 h(0) = 0`` and ``G1 h(1) = 0`` (``fixed0``, ``fixed1``:
  component indices held fixed, or a matrix G of linear combinations; every other direction is
  natural, its end condition the one the form implies), and
* the linear constraints ``int_0^1 g.h ds + d0.h(0) + d1.h(1) = 0`` (:class:`Constraint`):
  linearised isoperimetric constraints (a pinned end: the reaction is their multiplier), or
  orthogonality to a known kernel field z (``Constraint(z)``), which removes a symmetry's zero
  mode from the count.

A must be symmetric positive definite at every point (the Legendre condition: without it the
form has infinitely many negative eigenvalues and no index), B, E0 and E1 symmetric, C any.
The engine (`elastica_auto.numerics.stability`) counts the negative eigenvalues of the form on that
space: its stability index.

The scalar tuple ``(a, b, c)`` of the first version of the hook, with an optional fourth element
``[(g, d), ...]``, is the form with k = 1, A = a, B = b, E1 = c, h(0) = 0 and the constraints
``int g h ds + d h(1) = 0`` (:func:`as_second_variation`).
"""

from __future__ import annotations

import copy
import functools
from typing import NamedTuple

import numpy as np

from ..core.errors import ProblemError

#: Relative asymmetry above which A, B, E0 or E1 is refused as not symmetric: several rounding
#: errors of a product of a few terms, far below any modelling asymmetry.
SYMMETRY_TOL = 1e-10
#: A form decouples along its parts (:meth:`SecondVariation.split`) where no coefficient that
#: couples two parts exceeds this, relative to the form's largest coefficient, and each end
#: direction and constraint lies in one part to this, relative to its own largest entry: a
#: continuation keeps the coupling of a symmetric state (the spatial rod's out-of-plane rows
#: at a planar one) at rounding level, seen below 1e-12.
DECOUPLED = 1e-9


class Constraint(NamedTuple):
    """The linear constraint ``int_0^1 g.h ds + d0.h(0) + d1.h(1) = 0``: ``g`` of shape (k, m)
    on the points (or (k,) constant; for k = 1 also a scalar or (m,)), ``d0``, ``d1`` of shape
    (k,) (a scalar: that value in every component). ``kernel``: g is a zero mode of the form
    (a symmetry's generator), removed from the count, not a Lagrange constraint; the kernel's
    dimension (`stability.kernel_dimension`) is counted without it, since the zero eigenvalue
    it removes is one that the branch's eigenvalues cross where the symmetry holds."""

    g: object
    d1: object = 0.0
    d0: object = 0.0
    kernel: bool = False


def _fail(msg: str):
    raise ProblemError(f"SecondVariation: {msg}")


@functools.lru_cache(maxsize=8)
def _identity(k):
    eye = np.eye(k)
    eye.flags.writeable = False
    return eye


def _matrix_field(name, value, k):
    """``value`` as an array (m', k, k), point by point, with m' the number of points or 1
    (constant): a scalar or (m,) array is that multiple of the identity, (k, k) a constant
    matrix, (k, k, m) the hook's layout (as ``rhs_jac``)."""
    v = np.asarray(value, dtype=float)
    if v.ndim == 0:
        return (float(v) * _identity(k))[None] if k > 1 else v.reshape(1, 1, 1)
    if v.ndim == 1:
        return v[:, None, None] * _identity(k) if k > 1 else v[:, None, None]
    if v.ndim == 2 and v.shape == (k, k):
        return v[None]
    if v.ndim == 3 and v.shape[:2] == (k, k):
        return v.transpose(2, 0, 1)
    _fail(f"{name} has shape {v.shape}; expected a scalar, (m,), ({k}, {k}) or ({k}, {k}, m) "
          f"for k = {k} components")


def _end_matrix(name, value, k):
    v = np.asarray(value, dtype=float)
    if v.ndim == 0:
        return float(v) * _identity(k)
    if v.shape != (k, k):
        _fail(f"{name} has shape {v.shape}; expected a scalar or ({k}, {k})")
    return v


def _vector(name, value, k, points: bool):
    """``value`` as (k,) (``points`` False) or (k, m') (``points`` True, m' = m or 1)."""
    v = np.asarray(value, dtype=float)
    if points:
        if v.ndim == 0 and k == 1:
            return v.reshape(1, 1)
        if v.ndim == 1 and k == 1:
            return v[None, :]
        if v.ndim == 1 and v.shape == (k,):
            return v[:, None]
        if v.ndim == 2 and v.shape[0] == k:
            return v
        _fail(f"{name} has shape {v.shape}; expected ({k},) or ({k}, m)"
              + (", a scalar or (m,)" if k == 1 else ""))
    if v.ndim == 0:
        return np.full(k, float(v))
    if v.shape != (k,):
        _fail(f"{name} has shape {v.shape}; expected ({k},) or a scalar")
    return v


def _parts(parts, k) -> dict[str, np.ndarray]:
    """``parts`` as {name: component indices (array)}, refused unless the names are strings
    and the indices partition 0..k-1 (every component in exactly one part)."""
    if parts is None:
        return {}
    if not isinstance(parts, dict) or not all(isinstance(n, str) for n in parts):
        _fail(f"parts must be a dict {{name: [component indices]}}, got {parts!r:.80}")
    out, seen = {}, []
    for name, comps in parts.items():
        c = np.atleast_1d(np.asarray(comps))
        if c.ndim != 1 or not c.size or c.dtype.kind not in "iu":
            _fail(f"parts[{name!r}] = {comps!r:.60}: expected a non-empty list of component "
                  "indices")
        out[name] = c.astype(int)
        seen.extend(out[name].tolist())
    if sorted(seen) != list(range(k)):
        _fail(f"parts {dict((n, c.tolist()) for n, c in out.items())} do not partition the "
              f"components 0..{k - 1} (each in exactly one part)")
    return out


def _parts_of(columns, label, tol) -> np.ndarray:
    """The part (a value of ``label``, the part of each component) of each of the
    ``columns`` (k, c): the one part of the components where the column is non-zero
    (relative to its own largest entry), -1 where it is zero or lies in more than one part."""
    size = np.abs(columns)
    big = size > tol * size.max(axis=0, initial=0.0)
    lo = np.where(big, label[:, None], len(label)).min(axis=0, initial=len(label))
    hi = np.where(big, label[:, None], -1).max(axis=0, initial=-1)
    return np.where(lo == hi, lo, -1)


@functools.lru_cache(maxsize=16)
def _layout(parts, k):
    """(label, across, index) of the parts (tuples of component indices) of k components:
    the part of each component, the (k, k) mask of the entries that couple two parts, and
    each part's index (a slice where its components are consecutive: a view, not a copy)."""
    label = np.empty(k, dtype=int)
    for j, comps in enumerate(parts):
        label[list(comps)] = j
    across = label[:, None] != label[None, :]
    index = [slice(c[0], c[-1] + 1) if list(c) == list(range(c[0], c[-1] + 1))
             else np.array(c) for c in parts]
    for v in (label, across):
        v.flags.writeable = False
    return label, across, index


def _end_parts(free, fixed, label, parts) -> list | None:
    """The free and fixed directions (orthonormal bases) of an end within each of the
    ``parts`` (component indices; ``label`` the part of each component), or None where the
    fixed directions are not the direct sum of their parts' (a condition that ties two parts).
    Bases of components given as indices are columns of the identity and are sliced; a
    general G's fixed space decouples where its projection on each part lies in it, the
    projections' ranks adding up to its own."""
    where = _parts_of(np.hstack((free, fixed)), label, DECOUPLED)
    if np.all(where >= 0):
        nf = free.shape[1]
        return [(free[comps][:, where[:nf] == j], fixed[comps][:, where[nf:] == j])
                for j, comps in enumerate(parts)]
    out, rank = [], 0
    for comps in parts:
        u, sv, _ = np.linalg.svd(fixed[comps], full_matrices=True)
        if np.any((sv > DECOUPLED) & (sv < 1.0 - DECOUPLED)):
            return None
        r = int(np.count_nonzero(sv >= 1.0 - DECOUPLED))
        out.append((u[:, r:], u[:, :r]))
        rank += r
    return out if rank == fixed.shape[1] else None


def _end_parts_of(free, fixed, layout) -> list | None:
    """:func:`_end_parts` of the bases ``free`` and ``fixed`` for the parts ``layout`` (tuples
    of component indices), worked out once for each of their values: a module's end
    conditions are the same at every point of a branch, and their parts cost (in numpy calls
    on 3 x 3 arrays) half of what `SecondVariation.split` does at a point of the spatial rod.
    The bases returned are read-only, shared by every form that asks."""
    return _end_parts_cached(layout, free.shape, free.tobytes(), fixed.shape, fixed.tobytes())


@functools.lru_cache(maxsize=256)
def _end_parts_cached(layout, free_shape, free_bytes, fixed_shape, fixed_bytes):
    free = np.frombuffer(free_bytes).reshape(free_shape)
    fixed = np.frombuffer(fixed_bytes).reshape(fixed_shape)
    label = _layout(layout, free_shape[0])[0]
    out = _end_parts(free, fixed, label, [np.array(c) for c in layout])
    for v in () if out is None else (v for pair in out for v in pair):
        v.flags.writeable = False
    return out


def _check_symmetric(name, m):
    """Refuse a matrix field (m', k, k) that is not symmetric at some point."""
    if m.shape[-1] == 1 or np.array_equal(m, m.transpose(0, 2, 1)):
        return      # (a derived module's fields are symmetric exactly: one comparison)
    gap = np.abs(m - m.transpose(0, 2, 1))
    if gap.max() > SYMMETRY_TOL * (1.0 + np.abs(m).max()):
        q, i, j = np.unravel_index(np.argmax(gap), gap.shape)
        _fail(f"{name} is not symmetric: {name}[{i}, {j}] - {name}[{j}, {i}] = "
              f"{m[q, i, j] - m[q, j, i]:.3g} at point {q}")


def _end_basis(name, fixed, k):
    """(N, R): orthonormal bases of the free directions (the null space of G) and of the
    fixed ones (its row space) at an end, from component indices or a matrix G (r, k)."""
    if isinstance(fixed, (list, tuple)) and all(isinstance(i, int) for i in fixed):
        return _selection(name, tuple(fixed), k)
    g = np.asarray(fixed)
    if g.ndim == 2:
        if g.shape[1] != k or g.shape[0] > k:
            _fail(f"{name} has shape {g.shape}; expected a matrix (r, {k}) with r <= {k}, or a "
                  "list of component indices")
        if g.shape[0] == 0:
            return np.eye(k), np.zeros((k, 0))
        _, sv, vt = np.linalg.svd(g.astype(float))
        r = g.shape[0]
        if sv[-1] <= 1e-12 * sv[0]:
            _fail(f"{name}: the rows of G are linearly dependent (rank {np.sum(sv > 1e-12 * sv[0])}"
                  f" < {r})")
        return vt[r:].T, vt[:r].T
    return _selection(name, tuple(np.atleast_1d(g).tolist()), k)


@functools.lru_cache(maxsize=64)
def _selection(name, comps, k):
    """:func:`_end_basis` for component indices: columns of the identity."""
    if not all(isinstance(i, int) and 0 <= i < k for i in comps) or len(set(comps)) != len(comps):
        _fail(f"{name} = {list(comps)!r}: expected distinct component indices in 0..{k - 1}, "
              f"or a matrix (r, {k})")
    eye = np.eye(k)
    free = [i for i in range(k) if i not in comps]
    return eye[:, free], eye[:, sorted(comps)]


class SecondVariation:
    """The quadratic form ``int_0^1 (h'.A h' + 2 h'.C h + h.B h) ds + h(0).E0 h(0) +
    h(1).E1 h(1)`` on perturbations h in R^k with essential conditions at the ends and linear
    constraints (module docstring).

    Parameters
    ----------
    A, B : array_like
        Symmetric (k, k) coefficients on the points: (k, k, m), or constant (k, k), or a
        scalar or (m,) array times the identity. A must be positive definite (the engine
        refuses a point where it is not). k is read from the first of A, B, C, E0, E1 given
        as a matrix (k = 1 if none is).
    C : array_like, optional
        Any (k, k) coupling of h' and h, laid out like A. Default 0.
    E0, E1 : array_like, optional
        Symmetric (k, k) end terms at s = 0 and s = 1 (or scalars times the identity).
    fixed0, fixed1 : sequence of int or array_like, optional
        The essential conditions at s = 0 and s = 1: the indices of the components held fixed
        (``h_i(end) = 0``), or a matrix G (r, k) of full row rank, ``G h(end) = 0``. Default:
        none (every direction natural).
    constraints : sequence of Constraint or tuples (g, d1[, d0]), optional
        ``int_0^1 g.h ds + d0.h(0) + d1.h(1) = 0`` for each.
    parts : dict, optional
        Named groups of components that partition 0..k-1, e.g. ``{"index_in": [2],
        "index_out": [0, 1]}``: where the form decouples along them (:meth:`split`; a
        symmetric state), the engine counts each part's index on its own, reports it under
        its name and gives their sum as the index. A module ordinate of the same name takes
        that count at every point of a branch (the module computes it where asked
        elsewhere, e.g. with `elastica_auto.numerics.stability.count_form`).
    """

    def __init__(self, A, B, C=0.0, *, E0=0.0, E1=0.0, fixed0=(), fixed1=(), constraints=(),
                 parts=None):
        k = next((np.shape(v)[0] for v in (A, B, C, E0, E1) if np.ndim(v) >= 2), 1)
        self.k = int(k)
        self.A = _matrix_field("A", A, k)
        self.B = _matrix_field("B", B, k)
        self.C = _matrix_field("C", C, k)
        self.E0 = _end_matrix("E0", E0, k)
        self.E1 = _end_matrix("E1", E1, k)
        for name, v in (("A", self.A), ("B", self.B), ("E0", self.E0[None]),
                        ("E1", self.E1[None])):
            _check_symmetric(name, v)
        self.free0, self.fixed0 = _end_basis("fixed0", fixed0, k)
        self.free1, self.fixed1 = _end_basis("fixed1", fixed1, k)
        try:
            items = [c if isinstance(c, Constraint) else Constraint(*c) for c in constraints]
        except TypeError:
            _fail(f"constraints must be a sequence of Constraint(g, d1, d0) or tuples (g, d1[, "
                  f"d0]), got {constraints!r:.80}")
        self.constraints = [Constraint(_vector(f"constraints[{i}].g", c.g, k, True),
                                       _vector(f"constraints[{i}].d1", c.d1, k, False),
                                       _vector(f"constraints[{i}].d0", c.d0, k, False),
                                       bool(c.kernel))
                            for i, c in enumerate(items)]
        self.parts = _parts(parts, self.k)

    def split(self) -> dict[str, SecondVariation] | None:
        """The form on each of its ``parts`` where it decouples along them, else None: where
        A, B, C, E0 and E1 couple no two parts (to DECOUPLED of their largest entry) and each
        free and fixed end direction and each constraint lies in one part. The index is then
        the sum of the parts' indices (the form is the direct sum of theirs)."""
        if not self.parts:
            return None
        layout = tuple(tuple(c) for c in self.parts.values())
        label, across, index = _layout(layout, self.k)
        # every coefficient's entries as one array: one pass over them, not five
        sizes = np.abs(np.concatenate((self.A, self.B, self.C, self.E0[None], self.E1[None])))
        if sizes[:, across].max(initial=0.0) > DECOUPLED * sizes.max():
            return None
        comps = list(self.parts.values())
        ends = [_end_parts_of(free, fixed, layout)
                for free, fixed in ((self.free0, self.fixed0), (self.free1, self.fixed1))]
        if None in ends:
            return None
        kept = []
        if self.constraints:
            # each constraint's size in each component: its largest value there, g or d
            kept = _parts_of(np.array([np.maximum(np.abs(c.g).max(axis=1),
                                                  np.maximum(np.abs(c.d0), np.abs(c.d1)))
                                       for c in self.constraints]).T, label, DECOUPLED)
            if np.any(kept < 0):
                return None
        out = {}
        for j, (name, ix) in enumerate(zip(self.parts, index)):
            part = copy.copy(self)
            part.k, part.parts = len(comps[j]), {}
            rows = ix if isinstance(ix, slice) else ix[:, None]     # one gather, not two
            part.A, part.B, part.C = (m[:, rows, ix] for m in (self.A, self.B, self.C))
            part.E0, part.E1 = (m[rows, ix] for m in (self.E0, self.E1))
            (part.free0, part.fixed0), (part.free1, part.fixed1) = ends[0][j], ends[1][j]
            part.constraints = [Constraint(c.g[ix], c.d1[ix], c.d0[ix], c.kernel)
                                for c, where in zip(self.constraints, kept) if where == j]
            out[name] = part
        return out

    def without_kernel_modes(self) -> SecondVariation:
        """The same form with the constraints that remove a zero mode (``kernel``) left out:
        on the whole space, where that mode is an eigenvector of eigenvalue zero."""
        out = copy.copy(self)
        out.constraints = [c for c in self.constraints if not c.kernel]
        return out

    def fields(self, m: int):
        """A, B, C as (m, k, k) arrays on the m points and the constraints' g as (r, m, k);
        ProblemError if a field is laid out on another number of points."""
        def on(name, v):
            if len(v) == m:
                return v
            if len(v) != 1:
                _fail(f"{name} is given on {len(v)} points; the hook was called on {m}")
            return np.broadcast_to(v, (m, *v.shape[1:]))

        g = [on(f"constraints[{i}].g", c.g.T) for i, c in enumerate(self.constraints)]
        g = np.array(g).reshape(len(g), m, self.k)
        return on("A", self.A), on("B", self.B), on("C", self.C), g


def as_second_variation(value, source: str) -> SecondVariation:
    """The hook's result as a :class:`SecondVariation`: itself, or the scalar tuple ``(a, b,
    c[, [(g, d), ...]])`` as the form with k = 1, h(0) = 0, E1 = c and the constraints
    ``int g h ds + d h(1) = 0``."""
    if isinstance(value, SecondVariation):
        return value
    if not isinstance(value, tuple) or len(value) not in (3, 4):
        raise ProblemError(f"{source}: second_variation(s, y, p) returned "
                           f"{type(value).__name__}; expected a SecondVariation or a tuple "
                           "(a, b, c) with an optional fourth element, the constraints")
    a, b, c, *rest = value
    if np.ndim(c) != 0:
        raise ProblemError(f"{source}: second_variation(s, y, p): the end coefficient c has "
                           f"shape {np.shape(c)}; expected a scalar")
    return SecondVariation(a, b, E1=float(c), fixed0=[0],
                           constraints=[Constraint(g, d) for g, d in (rest[0] if rest else ())])
