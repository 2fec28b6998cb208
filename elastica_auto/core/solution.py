"""Solutions and directions on a mesh: values and derivatives at the nodes, a cubic between.

Every solution the engine handles is a C1 piecewise cubic on a mesh ``s`` (m nodes on [0, 1]):
its values ``y`` (n, m) and derivatives ``yp`` (n, m) at the nodes fix the cubic Hermite
interpolant on each interval, the interpolant of the 4th-order Lobatto IIIA collocation that
both correctors use (``yp = f(s, y)`` at the nodes).

Directions in the space of (y, lam) -- tangents, secants, null vectors -- are measured with

    <u, v> = int_0^1 u.y . v.y ds + u.lam v.lam

by the trapezoidal rule on the mesh: the inner product of the pseudo-arclength condition, of
tangent normalisation and of the angle between successive tangents.
"""

from __future__ import annotations

import numpy as np


def hermite(s, y, yp, x, nu: int = 0):
    """The cubic Hermite interpolant of ``y``, ``yp`` on the mesh ``s`` (``nu = 0``) or its
    derivative (``nu = 1``) at the points ``x`` in [s_0, s_{m-1}]; shape (n, len(x))."""
    i = np.minimum(np.searchsorted(s, x, side="right") - 1, len(s) - 2)
    s0, h = s.take(i), s.take(i + 1) - s.take(i)
    y0, y1, d0, d1 = y.take(i, axis=1), y.take(i + 1, axis=1), yp.take(i, axis=1), \
        yp.take(i + 1, axis=1)
    slope = (y1 - y0) / h
    c3 = (d0 + d1 - 2 * slope) / (h * h)
    c2 = (slope - d0) / h - c3 * h
    t = x - s0
    if nu == 0:
        return y0 + t * (d0 + t * (c2 + t * c3))
    return d0 + t * (2 * c2 + 3 * t * c3)


def at_fractions(s, y, yp, fractions, derivative: bool = False):
    """The cubic Hermite interpolant at the points ``s_i + tau h_i`` of every interval, for
    each tau in ``fractions``: shape (n, len(fractions), m-1) (and the derivatives there).
    Fixed fractions make the Hermite basis constants: a few array operations in all."""
    h = s[1:] - s[:-1]
    y0, y1, d0, d1 = y[:, :-1], y[:, 1:], yp[:, :-1] * h, yp[:, 1:] * h
    values = np.empty((len(y), len(fractions), len(h)))
    for j, t in enumerate(fractions):
        t2 = t * t
        values[:, j] = ((2 * t2 * t - 3 * t2 + 1) * y0 + (t2 * t - 2 * t2 + t) * d0
                        + (3 * t2 - 2 * t2 * t) * y1 + (t2 * t - t2) * d1)
    if not derivative:
        return values
    slopes = np.empty_like(values)
    for j, t in enumerate(fractions):
        t2 = t * t
        slopes[:, j] = ((6 * t2 - 6 * t) * (y0 - y1) + (3 * t2 - 4 * t + 1) * d0
                        + (3 * t2 - 2 * t) * d1) / h
    return values, slopes


def simpson(s, y, yp, f) -> float:
    """int_0^1 f(y) ds by Simpson's rule on each interval of the mesh ``s``, ``y`` at the
    midpoints from its cubic Hermite interpolant (``yp`` its derivatives): 4th order, like the
    solution itself. ``f`` maps values (n, q) to (q,); for ordinates that are integrals."""
    s = np.asarray(s, dtype=float)
    fy, fm = f(y), f(at_fractions(s, y, yp, (0.5,))[:, 0])
    return float(np.sum(np.diff(s) * (fy[:-1] + 4 * fm + fy[1:])) / 6)


def trapezoid_weights(s):
    """Weights of the trapezoidal rule on the mesh ``s``."""
    h = np.diff(np.asarray(s, dtype=float))
    w = np.zeros(len(h) + 1)
    w[:-1] += h / 2
    w[1:] += h / 2
    return w


class Curve:
    """Values ``y`` (n, m) and derivatives ``yp`` (n, m) on a mesh ``s`` (m,), evaluated
    anywhere by cubic Hermite interpolation."""

    def __init__(self, s, y, yp):
        self.s = np.asarray(s, dtype=float)
        self.y = np.asarray(y, dtype=float)
        self.yp = np.asarray(yp, dtype=float)

    def __call__(self, x):
        """Values at the points ``x`` (the node values themselves on the own mesh)."""
        if x is self.s:
            return self.y
        return hermite(self.s, self.y, self.yp, x)

    def derivative(self, x):
        if x is self.s:
            return self.yp
        return hermite(self.s, self.y, self.yp, x, 1)


class State(Curve):
    """A solution of the BVP together with all its parameter values."""

    def __init__(self, s, y, yp, params: dict[str, float]):
        super().__init__(s, y, yp)
        self.params = dict(params)

    @classmethod
    def from_values(cls, problem, s, y, params):
        """A State from node values, with derivatives from the right-hand side."""
        s = np.asarray(s, dtype=float)
        y = np.asarray(y, dtype=float)
        return cls(s, y, problem.rhs(s, y, params), params)


class Tangent(Curve):
    """A direction ``(ydot(s), lamdot)`` in the space (y, lam) (a tangent, secant or null
    vector); ``yp`` is the derivative of ``ydot``."""

    def __init__(self, s, y, yp, lam: float):
        super().__init__(s, y, yp)
        self.lam = float(lam)

    def on(self, s) -> "Tangent":
        """The same direction with its values on the mesh ``s``."""
        if s is self.s or (len(s) == len(self.s) and np.array_equal(s, self.s)):
            return self
        return Tangent(s, self(s), self.derivative(s), self.lam)

    def scaled(self, c: float) -> "Tangent":
        return Tangent(self.s, c * self.y, c * self.yp, c * self.lam)


def inner(a: Curve, b: Curve, s=None) -> float:
    """``<a, b> = int a.y . b.y ds + a.lam b.lam`` by the trapezoidal rule on ``s`` (default:
    a's mesh); a Curve without ``lam`` counts as lam = 0."""
    x = a.s if s is None else s
    lam = getattr(a, "lam", 0.0) * getattr(b, "lam", 0.0)
    return float(np.sum(trapezoid_weights(x) * np.sum(a(x) * b(x), axis=0)) + lam)


def norm(a: Curve, s=None) -> float:
    return float(np.sqrt(max(inner(a, a, s), 0.0)))


def difference(b: State, a: State, name: str, s=None) -> Tangent:
    """``b - a`` in (y, lam) on the mesh ``s`` (default: b's)."""
    x = b.s if s is None else s
    return Tangent(x, b(x) - a(x), b.derivative(x) - a.derivative(x),
                   b.params[name] - a.params[name])


def secant(a: State, b: State, name: str) -> tuple[Tangent, float]:
    """The unit secant from ``a`` to ``b`` in (y, lam), on b's mesh, and the distance."""
    d = difference(b, a, name)
    dist = norm(d)
    return d.scaled(1.0 / dist), dist
