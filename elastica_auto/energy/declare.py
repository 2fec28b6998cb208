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

    def __init__(self, density, *, s, coordinates, parameters, fixed0=None, fixed1=None,
                 end0=0, end1=0, quadratures=None, multipliers=None, momenta=None,
                 parts=None):
        values = dict(density=density, s=s, coordinates=tuple(coordinates),
                      parameters=dict(parameters), fixed0=dict(fixed0 or {}),
                      fixed1=dict(fixed1 or {}), end0=end0, end1=end1,
                      quadratures=dict(quadratures or {}), multipliers=dict(multipliers or {}),
                      momenta=momenta, parts=dict(parts or {}))
        for key, value in values.items():
            object.__setattr__(self, key, value)
