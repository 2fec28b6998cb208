"""A naturally curved heavy column, written as its energy (docs/energy.md; the model, its
snap and the runs: docs/soft-robots.md, "Heavy and pre-curved rods").

Greenhill's heavy column (``examples/heavy_column.py``: a rod clamped upright at s = 0, free
at s = 1, under its own weight q per length, in EI / l^3 units) made of a rod that is
naturally curved, with the constant curvature k0 in its unstressed state (k0 > 0 curls it
to the left, the sense of positive theta). theta is the tangent's angle from the vertical,
the bending moment m = theta' - k0, and the weight of the rod above s acts at s (the reduced
energy: the potential q int y ds, by parts)::

    E[theta] = int_0^1 ( (theta' - k0)^2 / 2 + q (1 - s) cos(theta) ) ds,   theta(0) = 0,

the upper end natural: m(1) = theta'(1) - k0 = 0. Derived from it: the states ``[theta, m]``,
theta' = m + k0, m' = -q (1 - s) sin(theta), the second variation int (h'^2 - q (1 - s)
cos(theta) h^2) ds on h(0) = 0 (the same as the straight column's: k0 enters only the
equilibrium), q and k0 entering the density (``"ode"``) with the ordinates dE_dq = int (1 - s)
cos(theta) ds and dE_dk0 = -int m ds.

At k0 = 0 it is Greenhill's column, which buckles at q_c = (3 j / 2)^2 = 7.8373 (j the first
zero of J_{-1/3}). A natural curvature unfolds that pitchfork: loaded beyond q_c, the
column leaning against its curvature (theta < 0 for k0 > 0) is stable only while k0 is below
a critical curvature k_f(q), where it snaps over to the side it curls to; the fold curve
k_f(q) ends in a cusp at (k0, q) = (0, q_c) (docs/soft-robots.md;
tests/test_curved_heavy_column.py checks the folds by shooting and the cusp against q_c).

By hand: the starts (the unloaded rod theta = k0 s at q = 0, the straight column at k0 = 0),
the mirror theta -> -theta, k0 -> -k0, the ordinates ``theta1`` (the tip's angle) and
``m0`` (the clamp's moment), and the drawing.
"""

import numpy as np

from elastica_auto import Mirror, Ordinate
from elastica_auto.energy import derived_names


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s, q, k0 = sp.symbols("s q k0", real=True)
    theta = sp.Function("theta")(s)
    return Energy(density=(theta.diff(s) - k0) ** 2 / 2 + q * (1 - s) * sp.cos(theta),
                  s=s, coordinates=[theta], momenta={theta: "m"}, fixed0={theta: 0},
                  parameters={q: Param(0.0, "q", doc="weight per length, q l^3 / EI"),
                              k0: Param(0.0, r"\kappa_0", doc="natural curvature, k0 l")})


#: Imported as a Python module, the derived names on first use (`load_problem` gives them).
__getattr__ = derived_names(__name__)


ORDINATES = [
    Ordinate("theta1", r"$\theta(1)$", lambda s, y, p: float(y[0, -1]), None, "tip angle"),
    Ordinate("m0", r"$m(0)$", lambda s, y, p: float(y[1, 0]), None, "moment at the clamp"),
]

#: The reflection x -> -x: theta, m and k0 change sign, and with them the ordinates that are
#: odd in theta (the energy, dE_dq, are even).
MIRROR = Mirror({"theta": "-theta", "m": "-m"}, ("k0",), ("dE_dk0", "theta1", "m0"))


def exact_start(s, p):
    """The unloaded rod in its natural shape, theta = k0 s, at q = 0; the straight column
    theta = 0 at k0 = 0 for every q; None otherwise."""
    if p["k0"] == 0 or p["q"] == 0:
        return np.vstack((p["k0"] * s, np.zeros_like(s)))
    return None


def draw(ax, profile, p):
    """The centreline x' = -sin(theta), y' = cos(theta) from the clamp at the origin
    (trapezoidal rule on the profile grid), and the clamp."""
    theta = profile[0]
    s = np.linspace(0.0, 1.0, len(theta))
    ds = np.diff(s)
    x = np.concatenate(([0.0], np.cumsum(-0.5 * ds * (np.sin(theta[1:]) + np.sin(theta[:-1])))))
    y = np.concatenate(([0.0], np.cumsum(0.5 * ds * (np.cos(theta[1:]) + np.cos(theta[:-1])))))
    ax.plot((-0.15, 0.15), (0.0, 0.0), color="0.2", lw=1.3, solid_capstyle="butt")
    ax.plot(x, y, color="black", lw=1.4, solid_capstyle="round", gid="rod")
