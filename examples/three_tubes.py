"""A concentric-tube robot of three pre-curved tubes in the torsional model, written as its
energy: the three-tube case of ``equations/concentric_tubes.py`` (its docstring and
docs/soft-robots.md give the model), for which no closed form of the snap is known.

Three tubes curved over the same length L (curvatures kappa_i, bending stiffnesses EI_i,
torsional GJ_i), each turned at its actuator through a straight transmission of length Lt:
tube 1's base held at 0, tubes 2 and 3 turned by beta2 and beta3. The shared curvature
minimises sum_i EI_i |u - kappa_i e(psi_i)|^2 / 2, which leaves the bending energy per length
(Lagrange's identity, K = EI1 + EI2 + EI3)

    1 / (2 K) sum_{i<j} EI_i EI_j |kappa_i e(psi_i) - kappa_j e(psi_j)|^2,

and with arclength L s::

    E[psi] = int_0^1 ( sum_i GJ_i psi_i'^2 / (2 L)
                       + L / (2 K) sum_{i<j} EI_i EI_j |kappa_i e_i - kappa_j e_j|^2 ) ds
             + (GJ1 psi1(0)^2 + GJ2 (psi2(0) - beta2)^2 + GJ3 (psi3(0) - beta3)^2) / (2 Lt),

every end natural. The states are ``[psi1, psi2, psi3, T1, T2, T3]``, T_i = GJ_i psi_i' / L the
torque in tube i; beta2 and beta3 enter the end term only (``"free"``), their ordinates the
actuators' torques ``torque2`` = -T2(0) and ``torque3`` = -T3(0).

Defaults: three tubes of one material (GJ = EI / 1.3), stiffer outside, less curved:
EI = (1, 0.7, 0.4), kappa = (1, 1.2, 1.5), L = Lt = 1. Turning the innermost tube (beta3) with
beta2 = 0 snaps it through a fold pair near beta3 = pi (docs/soft-robots.md;
tests/test_concentric_tubes.py checks the folds by shooting).
"""

import math

import numpy as np

from elastica_auto import Ordinate
from elastica_auto.energy import derived_names


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param
    s = sp.Symbol("s", real=True)
    beta2, beta3, L, Lt = sp.symbols("beta2 beta3 L Lt", real=True)
    kappa = sp.symbols("kappa1:4", real=True)
    EI = sp.symbols("EI1:4", real=True)
    GJ = sp.symbols("GJ1:4", real=True)
    psi = [sp.Function(f"psi{i}")(s) for i in (1, 2, 3)]
    K = sum(EI)
    twist = sum(g * p.diff(s) ** 2 for g, p in zip(GJ, psi)) / (2 * L)
    bend = L / (2 * K) * sum(
        EI[i] * EI[j] * (kappa[i] ** 2 + kappa[j] ** 2
                         - 2 * kappa[i] * kappa[j] * sp.cos(psi[j] - psi[i]))
        for i in range(3) for j in range(i + 1, 3))
    base = (GJ[0] * psi[0] ** 2 + GJ[1] * (psi[1] - beta2) ** 2
            + GJ[2] * (psi[2] - beta3) ** 2) / (2 * Lt)
    tube = {}
    for i, (k0, b0) in enumerate(((1.0, 1.0), (1.2, 0.7), (1.5, 0.4))):
        n = i + 1
        tube[kappa[i]] = Param(k0, rf"\kappa_{n}", doc=f"pre-curvature of tube {n}")
        tube[EI[i]] = Param(b0, rf"EI_{n}", doc=f"bending stiffness of tube {n}")
        tube[GJ[i]] = Param(b0 / sp.Rational(13, 10), rf"GJ_{n}",
                            doc=f"torsional stiffness of tube {n}")
    angle = dict(period=2 * sp.pi)
    return Energy(
        density=twist + bend, end0=base,
        s=s, coordinates=psi, momenta=["T1", "T2", "T3"],
        parameters={
            beta2: Param(0.0, r"\beta_2", period_shift={psi[1]: 2 * sp.pi}, ordinate="torque2",
                         doc="actuated base rotation of tube 2", **angle),
            beta3: Param(0.0, r"\beta_3", period_shift={psi[2]: 2 * sp.pi}, ordinate="torque3",
                         doc="actuated base rotation of tube 3", **angle),
            **tube,
            L: Param(1.0, "L", doc="curved length (all three tubes curved over it)"),
            Lt: Param(1.0, r"L_t", doc="straight transmission length (> 0)"),
        })


#: Imported as a Python module, the derived names on first use (`load_problem` gives them).
__getattr__ = derived_names(__name__)


ORDINATES = [
    Ordinate("tip3", r"$\psi_3(1)-\psi_1(1)$", lambda s, y, p: float(y[2, -1] - y[0, -1]),
             None, "rotation of tube 3 relative to tube 1 at the tip"),
]


def exact_start(s, p):
    """The tubes unturned along their length, psi_i = beta_i, exact where sin(beta2) =
    sin(beta3) = 0 and sin(beta3 - beta2) = 0 (to 1e-12: every pair of curvatures aligned or
    opposed); None otherwise."""
    b2, b3 = p["beta2"], p["beta3"]
    if max(abs(math.sin(b2)), abs(math.sin(b3))) > 1e-12:
        return None
    zero = np.zeros_like(s)
    return np.vstack((zero, np.full_like(s, b2), np.full_like(s, b3), zero, zero, zero))
