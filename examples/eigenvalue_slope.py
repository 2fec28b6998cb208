"""A nonlinear eigenvalue problem solved for its eigenvalue: u'' + p u (1 + u^2) = 0 with

    u(0) = 0,  u(1) = 0,  u'(0) = a,

three boundary conditions for two states (AUTO-07p's NBC > NDIM), so p is solved for
(``FREE``) as the slope a is continued. As a -> 0 the solution is a sin(pi x) / pi with
p -> pi^2; as a grows the restoring force stiffens and p falls. There is no exact start: the
module gives a guess, which the engine solves from. First-order state ``[u, v]``, v = u'.
"""

import numpy as np

from elastica_auto import Ordinate, Parameter

STATES = ("u", "v")

PARAMETERS = [
    Parameter("p", np.pi ** 2, r"p", "ode", doc="the eigenvalue, solved for"),
    Parameter("a", 0.1, r"a", "fixed", doc="the slope u'(0)"),
]

FREE = ("p",)


def rhs(s, y, p):
    u = y[0]
    return np.vstack((y[1], -p["p"] * u * (1 + u * u)))


def bc(ya, yb, p):
    return np.array((ya[0], yb[0], ya[1] - p["a"]))


def guess(s, p):
    """The linear mode with slope a at x = 0."""
    return np.vstack((p["a"] * np.sin(np.pi * s) / np.pi, p["a"] * np.cos(np.pi * s)))


ORDINATES = [
    Ordinate("amplitude", r"$\max |u|$", lambda s, y, p: float(np.max(np.abs(y[0]))), "a",
             "largest |u| on the mesh nodes"),
]
