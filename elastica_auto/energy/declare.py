"""What a user writes: the :class:`Energy` of a model and the metadata of its parameters.

Nothing here imports sympy: a module's ``ENERGY()`` imports it and builds the expressions,
and is called only when the cache of the generated code misses (`elastica_auto.energy.cache`).
The declarations are checked where they are derived (`elastica_auto.energy.derive`), which says
what is wrong in one line.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Param:
    """A parameter's default value and what the paper says about it.

    ``tex``: its label in plots (default: sympy's LaTeX of the symbol); ``period``: e.g.
    ``2*pi`` for an angle, with ``period_shift`` (coordinate or state -> what one period
    adds to it: ``{theta: 2*pi}`` for a clamp angle) and ``period_flip`` (states one period
    negates), as `elastica_auto.model.problem.Parameter`; ``doc``: one line; ``ordinate``:
    the name of the parameter's distinguished ordinate (default ``dE_d<name>``, or
    ``R_<name>`` for a reaction); ``enters``: where it enters, only to override the derived
    label (``"fixed"``, ``"free"``, ``"ode"``); the ordinate is dE/dxi for ``"free"`` and
    ``"ode"`` and the reaction -dE/dxi for ``"fixed"`` whichever label is given, so that the
    fold rule stays right."""

    default: float = 0.0
    tex: str | None = None
    period: object = None
    doc: str = ""
    ordinate: str | None = None
    enters: str | None = None
    period_shift: dict = field(default_factory=dict)
    period_flip: tuple = ()


@dataclass(frozen=True, init=False)
class Energy:
    """The energy of a model on s in [0, 1]::

        E[zeta] = int_0^1 L(zeta, zeta', s; p) ds + B0(zeta(0); p) + B1(zeta(1); p)

    Parameters
    ----------
    density : sympy expression
        L, in ``s``, the coordinates ``theta = sympy.Function("theta")(s)``, their first
        derivatives ``theta.diff(s)`` and the parameters. It must be strictly convex in the
        derivatives (the Legendre condition).
    s : sympy Symbol
        The arclength, in [0, 1].
    coordinates : list
        The coordinates zeta, each ``sympy.Function(name)(s)``.
    parameters : dict
        ``{symbol: default}`` or ``{symbol: Param(default, ...)}``.
    fixed0, fixed1 : dict, optional
        Essential end values ``{coordinate: value}`` at s = 0 and s = 1, in the parameters;
        every other coordinate's end is natural (-m(0) + dB0/dzeta = 0, m(1) + dB1/dzeta =
        0). A quadrature's initial value (required) is given in ``fixed0``; its final value
        in ``fixed1`` is an isoperimetric constraint, whose multiplier ``multipliers`` names.
    end0, end1 : sympy expression, optional
        The end terms B0 and B1, in the coordinates (their end values: write ``theta`` or
        ``theta.subs(s, 1)``) and the parameters; B1 may contain the quadratures' final values
        linearly, with coefficients in the parameters only (a dead load on a position).
    quadratures : dict, optional
        ``{x: rate}``: passive states ``x' = rate(zeta, zeta', s)`` (positions), which the
        energy contains only through their end values.
    multipliers : dict, optional
        ``{x: mu}``: the multiplier of the constraint x(1) = fixed1[x], a parameter solved
        for (``FREE``); it enters as E + mu (x(1) - fixed1[x]).
    momenta : dict or list, optional
        The momenta's state names, ``{theta: "kappa"}`` or one per coordinate in order;
        default ``m_<coordinate>``.
    parts : dict, optional
        ``{name: [coordinates]}``: groups of the second variation's perturbation
        components counted each on its own where the form decouples along them
        (`elastica_auto.model.second_variation.SecondVariation`); each becomes an ordinate.
        A rotation's components are ``R[0]``, ``R[1]``, ``R[2]`` (``R`` for all three).
    states : list, optional
        The states' names in another order than the derived one (coordinates, momenta,
        quadratures): every derived state exactly once. For a module that must read the
        branch files of a hand-written predecessor with that order.

    A coordinate is a scalar function of s or a :class:`Rotation` (a frame in SO(3)).
    """

    density: object
    s: object
    coordinates: tuple
    parameters: dict
    fixed0: dict
    fixed1: dict
    end0: object
    end1: object
    quadratures: dict
    multipliers: dict
    momenta: object
    parts: dict
    states: tuple | None

    def __init__(self, density, *, s, coordinates, parameters, fixed0=None, fixed1=None,
                 end0=0, end1=0, quadratures=None, multipliers=None, momenta=None,
                 parts=None, states=None):
        values = dict(density=density, s=s, coordinates=tuple(coordinates),
                      parameters=dict(parameters), fixed0=dict(fixed0 or {}),
                      fixed1=dict(fixed1 or {}), end0=end0, end1=end1,
                      quadratures=dict(quadratures or {}), multipliers=dict(multipliers or {}),
                      momenta=momenta, parts=dict(parts or {}),
                      states=None if states is None else tuple(states))
        for key, value in values.items():
            object.__setattr__(self, key, value)


class Rotation:
    """A frame R(s) in SO(3) as a coordinate of an :class:`Energy` (docs/energy.md, "Rotation
    coordinates").

    The energy is written in its body strains ``R.strain`` (u = (R^T R')^vee, a column of
    three symbols: R' = R [u]_x) and the frame itself, ``R.matrix`` (3 x 3, body to space)
    or its directors ``R.d1``, ``R.d2``, ``R.d3`` (its columns); in an end term these stand
    for the frame at that end. The frame is stored as a quaternion q, four states named
    ``quaternion`` (default ``<name>_q0`` .. ``<name>_q3``, scalar first), R = R(q / |q|)
    and q' = q (x) (0, u) / 2, which keeps |q|; its momentum is the spatial moment
    m = R dL/du (three states). A clamp is ``fixed0={R: q_c}`` with q_c a quaternion in
    the parameters (:func:`rotation_about`, :func:`compose`). Its perturbations are spatial
    rotations w in R^3, R -> exp([w]_x) R: three components of the second variation,
    ``R[0]``, ``R[1]``, ``R[2]``, after the scalar coordinates'.

    Built inside ``ENERGY()`` (it creates sympy symbols, named ``<name>.u1``,
    ``<name>.R11`` and so on).
    """

    def __init__(self, name, quaternion=None):
        import sympy as sp
        self.name = name
        self.quaternion = tuple(quaternion) if quaternion is not None else \
            tuple(f"{name}_q{i}" for i in range(4))
        self.strain = sp.Matrix([sp.Symbol(f"{name}.u{i + 1}", real=True) for i in range(3)])
        self.matrix = sp.Matrix(3, 3, lambda a, b: sp.Symbol(f"{name}.R{a + 1}{b + 1}",
                                                             real=True))

    @property
    def d1(self):
        return self.matrix[:, 0]

    @property
    def d2(self):
        return self.matrix[:, 1]

    @property
    def d3(self):
        return self.matrix[:, 2]

    def __getitem__(self, i):
        if i not in (0, 1, 2):
            raise IndexError(f"{self.name}[{i!r}]: a rotation's components are 0, 1, 2")
        return RotationComponent(self, i)

    def __repr__(self):
        return f"Rotation({self.name!r}, quaternion={self.quaternion!r})"


@dataclass(frozen=True)
class RotationComponent:
    """``R[i]``: the i-th component of a rotation's perturbation (a spatial rotation about
    e_i), to name in ``parts``."""

    rotation: Rotation
    index: int


def rotation_about(axis, angle):
    """The unit quaternion (a sympy column of 4, scalar first) of the rotation by ``angle``
    about the unit vector ``axis``."""
    import sympy as sp
    axis = list(axis)
    return sp.Matrix([sp.cos(angle / 2)] + [sp.sin(angle / 2) * a for a in axis])


def compose(*quaternions):
    """The Hamilton product of quaternions (columns of 4, scalar first), left to right: the
    rotation of the last one, then the one before, ..."""
    import sympy as sp
    out = sp.Matrix(quaternions[0])
    for b in quaternions[1:]:
        a0, a1, a2, a3 = out
        b0, b1, b2, b3 = list(b)
        out = sp.Matrix([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                         a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                         a0 * b2 + a2 * b0 + a3 * b1 - a1 * b3,
                         a0 * b3 + a3 * b0 + a1 * b2 - a2 * b1])
    return out
