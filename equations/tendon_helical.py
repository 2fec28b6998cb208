"""A tendon-driven continuum robot with helical routing: ``tendon_robot``'s backbone and four
tendons, each turning about the backbone k times per unit length (docs/soft-robots.md,
"Helical routing"). Tendon i runs at the body offset

    d_i(s) = delta (cos w_i, sin w_i, 0),   w_i = a_i + 2 pi k s,   a_i = (i - 1) pi / 2,

along the path r + R d_i; its unit length in the body is t_i = v + u x d_i + d_i' (the
derivative of R^T (r + R d_i), R' = R [u]_x), with d_i' = 2 pi k e3 x d_i the offset's
derivative in the body. The energy is ``tendon_robot``'s with this t_i,

    E = int_0^1 ( u.K u / 2 + (v - e3).Kse (v - e3) / 2 + sum_i tau_i |v + u x d_i + d_i'|
                  + g y ) ds + P y(1),

explicit in s through d_i(s); at k = 0 it is ``tendon_robot``'s term for term (a module of
its own so that the parallel robot's derived code keeps the exact zeros of its offsets: the
general offsets cost about 1.2x per evaluation). The momenta, balances and natural
conditions have tendon_robot's form with this t_i and d_i(1) at the tip. The ordinates, the
drawing and the straight start (exact where the tendons are slack or parallel) are
``tendon_robot``'s.
"""

from elastica_auto.energy import derived_names
from elastica_auto.equations import tendon_robot as _parallel
from elastica_auto.equations.kirchhoff_lever_arm import QUATERNION

ANGLES = _parallel.ANGLES
ORDINATES = _parallel.ORDINATES
DRAW_PROJECTION = _parallel.DRAW_PROJECTION
draw = _parallel.draw
exact_start = _parallel.exact_start


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param, Rotation
    s = sp.Symbol("s", real=True)
    taus = sp.symbols("tau1:5", real=True)
    delta, b2, c, S, se, k, g, P = sp.symbols("delta b2 c S se k g P", real=True)
    R = Rotation("R", quaternion=QUATERNION)
    x, y, z = (sp.Function(name)(s) for name in ("x", "y", "z"))
    u = R.strain
    v = R.matrix.T * sp.Matrix([x.diff(s), y.diff(s), z.diff(s)])
    tendons = 0
    for i, tau in enumerate(taus):
        angle = i * sp.pi / 2 + 2 * sp.pi * k * s          # ANGLES[i] turned k s times
        d = delta * sp.Matrix([sp.cos(angle), sp.sin(angle), 0])
        t = v + u.cross(d) + d.diff(s)
        tendons += tau * sp.sqrt((t.T * t)[0])
    gap = v - sp.Matrix([0, 0, 1])
    elastic = (u.T * sp.diag(1, b2, c) * u)[0] + S * (gap.T * sp.diag(1, 1, se) * gap)[0]
    density = elastic / 2 + tendons + g * y
    tension = {tau: Param(0.0, rf"\tau_{i + 1}",
                          doc=f"tension of tendon {i + 1} (at angle {i * 90} deg) l^2 / K1")
               for i, tau in enumerate(taus)}
    return Energy(
        density=density, end1=P * y,
        s=s, coordinates=[x, y, z, R],
        momenta={x: "nx", y: "ny", z: "nz", R: ("mx", "my", "mz")},
        fixed0={R: (1, 0, 0, 0), x: 0, y: 0, z: 0},
        states=("x", "y", "z", *QUATERNION, "mx", "my", "mz", "nx", "ny", "nz"),
        parts={"index_in": [y, z, R[0]], "index_out": [x, R[1], R[2]]},
        parameters={
            **tension,
            delta: Param(0.05, r"\delta", doc="tendons' offset from the centreline / l"),
            b2: Param(1.0, "b_2", doc="bending stiffness about d2 / about d1"),
            c: Param(1 / sp.Float(1.3), "c", doc="torsional stiffness / bending stiffness"),
            S: Param(1000.0, "S", doc="shear stiffness l^2 / K1"),
            se: Param(1.0, "s_e", doc="extension stiffness / shear stiffness"),
            k: Param(0.0, "k", doc="tendons' turns about the backbone per length l (0: parallel)"),
            g: Param(0.0, "g", doc="weight per unit length l^3 / K1, along -e_y"),
            P: Param(0.0, "P", doc="dead weight at the tip l^2 / K1, along -e_y"),
        })


#: Imported as a Python module, the derived names (rhs, second_variation, PARAMETERS, ...)
#: on first use; `load_problem` gives them itself.
__getattr__ = derived_names(__name__)
