"""Energy-first equation modules: write the energy, get the equations, the index and the rule.

An equation module may define, instead of the protocol's functions
(`elastica_auto.model.problem`), a function ``ENERGY()`` that returns an :class:`Energy`::

    E[zeta] = int_0^1 L(zeta, zeta', s; p) ds + B0(zeta(0); p) + B1(zeta(1); p)

with essential (Dirichlet) end values, passive quadratures and isoperimetric constraints.
`load_problem` derives from it the states (the coordinates, their momenta m = dL/dzeta',
the quadratures), ``rhs``, ``bc`` with the natural end conditions, their Jacobians and
parameter derivatives, the second variation in the engine's form, every parameter's
``enters`` and its distinguished ordinate (the fold rule's), the energy as an ordinate and
the gradient flow (where a snap lands). Whatever the module defines by hand takes precedence.
docs/energy.md is the full account.

The layers, one concern each:

``declare``  :class:`Energy` and :class:`Param`, what the user writes (no sympy here: it is
             imported by the user's ``ENERGY()``, called only when the cache misses)
``derive``   the calculus of variations in sympy: from an Energy to the expressions
``codegen``  the expressions as a plain numpy module (readable, the cache's content)
``runtime``  the numerics the generated modules share (Legendre inverse by Newton,
             quadratures, the gradient flow); numpy only
``cache``    the generated source on disk, keyed by what it was derived from
``loader``   the hook of `load_problem`: the module's own names first, then the derived
"""

from .loader import derived_names

__all__ = ["Energy", "Param", "Rotation", "compose", "derived_names", "rotation_about"]

#: the names `declare` defines, imported on first use: a warm load of a derived module (the
#: cache's code, through `loader`) uses none of them, and declaring them (dataclasses) was a
#: few milliseconds of every run's start
_DECLARED = ("Energy", "Param", "Rotation", "compose", "rotation_about")


def __getattr__(name):
    if name in _DECLARED:
        from . import declare
        return getattr(declare, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
