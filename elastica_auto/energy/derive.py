"""The calculus of variations, in sympy: from an :class:`~elastica_auto.energy.Energy` to the
expressions of its equation module.

For ``E[zeta] = int_0^1 L(zeta, zeta', s) ds + B0(zeta(0)) + B1(zeta(1))`` (the parameters p
everywhere), with passive quadratures ``x' = g(zeta, zeta', s)``, ``x(0) = x0(p)``:

* A quadrature enters B1 linearly, ``B1 = B1'(zeta(1)) + c1(p).x(1)``, and an isoperimetric
  constraint ``x(1) = c(p)`` adds ``mu (x(1) - c)``. Since ``x(1) = x0 + int g``, both are
  the integrand ``lam.g`` with ``lam = c1 + mu``: the equations are those of
  ``L_eff = L + lam.g`` (the Lagrangian), whose momenta ``m = dL_eff/dzeta'`` are states.
* States: the coordinates zeta (k), their momenta m (k), the quadratures x. The system is
  ``zeta' = V(zeta, m, s)`` (the inverse of the Legendre map ``v -> dL_eff/dv``), ``m' =
  dL_eff/dzeta`` at ``zeta' = V``, ``x' = g`` at ``zeta' = V``. V is a symbolic linear solve
  where L_eff is quadratic in zeta' (its Hessian A free of zeta'), else computed per point by
  Newton's method (`elastica_auto.energy.runtime.legendre_inverse`); never a branch guessed by
  ``sympy.solve``.
* Ends: an essential coordinate gives ``zeta(0) - zeta0(p)``, a natural one ``-m(0) +
  dB0/dzeta = 0`` at s = 0 and ``m(1) + dB1/dzeta = 0`` at s = 1; a quadrature
  ``x(0) - x0(p)``, and a constrained one the extra row ``x(1) - c(p)`` (its multiplier is
  ``FREE``).
* Second variation: ``A = L_eff_vv``, ``C = L_eff_vz`` (rows zeta', columns zeta), ``B =
  L_eff_zz``, ``E0 = B0_zz``, ``E1 = B1_zz``; the essential coordinates are the fixed
  components; a constraint ``x(1) = c`` linearises to ``int (g_z.h + g_v.h') ds = 0``, and
  by parts along the solution to ``int (g_z - (g_v)').h ds - g_v(0).h(0) + g_v(1).h(1) = 0``.
  A constraint's value may depend on the end values at s = 1, ``x(1) = c(zeta(1))`` (a
  pinned lever arm): ``-mu c`` is then an end term of the Lagrangian (in the natural
  condition and E1) and the linearised constraint has ``-c_zeta.h(1)`` besides. A multiplier
  may be given as minus a parameter, ``E - n (x(1) - c)``, n the reaction.
* The distinguished ordinate of a parameter xi is the total derivative of E along the
  equilibria (the envelope theorem, as the Lagrangian is stationary there)::

      dE/dxi = int (L_xi + lam.g_xi) ds + B0_xi + B1_xi + lam.x0_xi - mu.c_xi
               - m(0).zeta0_xi + m(1).zeta1_xi

  xi ``enters`` ``"ode"`` where L or an active rate contains it, ``"free"`` where only end
  terms (or a constrained or energetic quadrature's end data) do, ``"fixed"`` where only the
  essential values do: that one's ordinate is the reaction -dE/dxi (the fold rule's sign,
  docs/stability.md). A parameter only in passive quadratures has dE/dxi = 0 and no ordinate.

A rotation coordinate R (`elastica_auto.energy.Rotation`, docs/energy.md) is a frame in SO(3):

* L is written in the body strains u = (R^T R')^vee and in R itself; R is stored as a
  quaternion q (four states, R = R(q / |q|), ``q' = q (x) (0, u) / 2``), and its momentum is
  the spatial moment m = R L_u (three states): the Legendre transform is on the Lie algebra,
  ``m_b = R^T m = L_u``, symbolic where L is quadratic in the strains and derivatives, else
  by Newton's method per point at the frame R(q) (the system then in (states, v), its
  Jacobians by the implicit function theorem: `codegen.Module.rotation_newton_system`);
* spatial variations R_e = exp(e [w]_x) R give ``u_e = u + e R^T w' - (e^2 / 2) R^T (w x
  w')``, so ``m' = tau``, ``tau_c = D_c L`` with ``D_c f = d/de f(exp(e E_c) R)`` at e = 0
  (``E_c = [e_c]_x``), the natural ends ``-m(0) + D B0 = 0``, ``m(1) + D B1 = 0``, and the
  second variation in w: ``A = R L_uu R^T``, ``C = R G - [m]_x / 2`` (``G_ic = D_c (L_u)_i``),
  ``B = sym(D_i D_c L)``, end terms likewise; mixed with the scalar coordinates through the
  same derivatives (``w'`` acts on the strains as ``R^T w'``);
* a clamp ``R(0) = R(q_c(p))`` gives the four rows ``q(0) - q_c`` and fixes w(0) = 0; a
  natural end at s = 0 gives ``-m(0) + D B0`` and ``|q(0)|^2 - 1`` (the scale of q, which no
  other condition fixes), a clamp at s = 1 the three rows ``Im(conj(q_c) (x) q(1))``; a
  clamp parameter's part of dE/dxi is ``-m(0).w_xi`` (``+m(1).w_xi`` at s = 1) with
  ``w_xi = 2 Im(dq_c/dxi (x) conj(q_c)) / |q_c|^2``, the clamp's turn per unit xi;
* a constraint's rate with strains: ``g_v`` along w' is ``R g_u``, and its total derivative
  along the solution takes (zeta'', u') from the momentum equations differentiated along
  it, ``d/ds L_u = R^T tau - u x L_u`` (`_rotation_total`).

Everything is built on sympy ``Dummy`` symbols: the user's names never meet the generated
code's, and appear in it only as string literals (`elastica_auto.energy.codegen`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef, UndefinedFunction

from ..core.errors import ProblemError
from .declare import Energy, Param, Rotation, RotationComponent

ENTERS = ("fixed", "free", "ode")


@dataclass
class ParameterInfo:
    """A parameter of the derived module: its declaration and where it enters."""

    name: str
    symbol: sp.Symbol               # the internal (Dummy) symbol
    default: float
    tex: str
    enters: str
    period: float | None
    doc: str
    period_shift: dict
    period_flip: tuple
    ordinate: str | None = None     # its distinguished ordinate's name, if it has one
    sign: int = 1                   # that ordinate is sign * dE/dxi
    where: str = ""                 # in words, for the generated module's comments
    multiplier: bool = False


def _hamilton(a, b):
    """The Hamilton product of two quaternions (sequences of 4, scalar first)."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return [a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 + a2 * b0 + a3 * b1 - a1 * b3,
            a0 * b3 + a3 * b0 + a1 * b2 - a2 * b1]


def _cross_matrix(v):
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


#: E_c = [e_c]_x, the generators of spatial rotations.
_GENERATORS = [_cross_matrix([1 if i == c else 0 for i in range(3)]) for c in range(3)]


def _quadratic_form(q):
    """Q(q), the rotation matrix of q times |q|^2 (quadratic in q)."""
    w, x, y, z = q
    return sp.Matrix([[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]])


class Frame:
    """A rotation's frame R = Q(q) / |q|^2 where it is evaluated (the nodes, or an end): its
    nine entries as symbols ``R``, computed from the quaternion symbols ``q``; ``inv`` is
    1 / |q|^2 and ``dR[a][b][j]`` the entries of dR/dq_j = (dQ/dq_j - 2 q_j R) / |q|^2. The
    derived expressions keep R as symbols (small, quick to differentiate and print); the
    generated code computes it once (`definitions`) and chains derivatives in q through it
    (`total`)."""

    def __init__(self, q, tag):
        self.q = list(q)
        self.tag = tag
        self.R = sp.Matrix(3, 3, lambda a, b: sp.Dummy(f"R{tag}{a}{b}", real=True))
        self.inv = sp.Dummy(f"n{tag}", positive=True)
        self.dR = [[[sp.Dummy(f"dR{tag}{a}{b}{j}", real=True) for j in range(4)]
                    for b in range(3)] for a in range(3)]
        self.entries = list(self.R)

    def names(self) -> dict:
        """The printed names of its symbols in the generated code."""
        out = {self.inv: f"n{self.tag}"}
        out.update({self.R[a, b]: f"R{self.tag}_{a}{b}" for a in range(3) for b in range(3)})
        out.update({self.dR[a][b][j]: f"dR{self.tag}_{a}{b}_{j}" for a in range(3)
                    for b in range(3) for j in range(4)})
        return out

    def definitions(self) -> list[tuple]:
        """(symbol, expression) for 1/|q|^2 and R, in that order."""
        q = self.q
        form = _quadratic_form(q)
        out = [(self.inv, 1 / (q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2))]
        out += [(self.R[a, b], form[a, b] * self.inv) for a in range(3) for b in range(3)]
        return out

    def derivative_definitions(self) -> list[tuple]:
        """(symbol, expression) of dR/dq_j, each in q, R and 1/|q|^2."""
        if not hasattr(self, "_derivatives"):
            form = _quadratic_form(self.q)
            self._derivatives = [(self.dR[a][b][j], (sp.diff(form[a, b], self.q[j])
                                                     - 2 * self.q[j] * self.R[a, b]) * self.inv)
                                 for a in range(3) for b in range(3) for j in range(4)]
        return self._derivatives

    def rotate(self, expr, c):
        """D_c expr = d/de expr(exp(e E_c) R) at e = 0: the derivative along the spatial
        rotation about e_c."""
        turned = _GENERATORS[c] * self.R
        return sp.Add(*[sp.diff(expr, self.R[a, b]) * turned[a, b]
                        for a in range(3) for b in range(3) if turned[a, b] != 0])

    def total(self, expr, x):
        """d expr / dx for a state x, R taken as R(q) (the chain rule through dR/dq)."""
        out = sp.diff(expr, x)
        if x in self.q:
            j = self.q.index(x)
            out += sp.Add(*[sp.diff(expr, self.R[a, b]) * self.dR[a][b][j]
                            for a in range(3) for b in range(3)])
        return out


@dataclass
class RotationInfo:
    """A rotation coordinate: its names, state symbols and frames."""

    name: str
    quaternion: tuple                # the quaternion's state names
    momenta: tuple                   # the spatial moment's state names
    user: Rotation
    Q: list                          # the quaternion's state symbols (4)
    Mr: list                         # the spatial moment's state symbols (3)
    U: list                          # the body strains (3)
    MB: list                         # the body moment R^T m (3): the Legendre map's value
    node: Frame | None = None
    start: Frame | None = None       # at s = 0 (the quaternion's rows of YA)
    end: Frame | None = None         # at s = 1
    offset: int = 0                  # its first component in the perturbations


@dataclass
class Derived:
    """The derived expressions, in the internal symbols: ``S`` (s), ``Z``, ``V``, ``M``, ``X``
    (scalar coordinates, their derivatives, momenta, quadratures), ``rotations`` (each with
    its quaternion ``Q``, strains ``U``, spatial moment ``Mr`` and frames), ``P``
    (parameters, by name), ``rows`` (the state symbols in the states' order), ``YA``, ``YB``
    (the states at s = 0 and s = 1, in that order) and ``W`` (zeta'' along the solution)."""

    coordinates: list                # the scalar coordinates' names
    momenta: list
    quadratures: list
    parameters: list
    S: sp.Symbol
    Z: list
    V: list
    M: list
    X: list
    W: list
    YA: list
    YB: list
    P: dict
    linear: bool                     # the Legendre inverse is the symbolic ``velocity``
    velocity: list | None            # V(Z, M, S) where linear (then the strains U, in MB)
    lagrangian: sp.Expr              # L_eff in (Z, V, S, P)
    density: sp.Expr                 # the user's L in (Z, V, S, P)
    rates: list                      # g in (Z, V, S, P)
    rhs: list                        # in the rows' order; in (states, S, P) where linear
    bc: list                         # in (YA, YB, P)
    A: list
    C: list
    B: list
    E0: list                         # in YA
    E1: list                         # in YB
    fixed0: list
    fixed1: list
    constraints: list                # (field in Z, V, W, S, P; g_v in Z, V, S, P; the end
                                     # part -dc/dzeta(1) of x(1) = c(zeta(1)), in YB)
    ordinates: list                  # (name, tex, doc, parameter, sign, integrand, end part)
    energy_integrand: sp.Expr
    energy_ends: sp.Expr
    free: tuple
    parts: dict
    ends: dict                       # B0, B1' in Z (the gradient flow), essential values,
                                     # clamps
    rows: list = field(default_factory=list)
    names: tuple = ()                # the states' names in the rows' order
    rotations: list = field(default_factory=list)
    summary: list = field(default_factory=list)   # lines for the generated module's header
    user: object = None              # expr -> text with the user's names (`_Names.user`)

    @property
    def k(self) -> int:
        """The number of scalar coordinates."""
        return len(self.Z)

    @property
    def components(self) -> int:
        """The perturbations' components: the scalar coordinates', then 3 per rotation."""
        return len(self.Z) + 3 * len(self.rotations)

    @property
    def states(self) -> tuple:
        return self.names

    @property
    def labels(self) -> list:
        """The perturbations' components in words."""
        return [*self.coordinates, *(f"{r.name}[{c}]" for r in self.rotations for c in range(3))]

    @property
    def velocities(self) -> list:
        """zeta' then each rotation's strains: what the Legendre transform inverts."""
        return [*self.V, *(u for r in self.rotations for u in r.U)]

    @property
    def frames(self) -> list:
        return [f for r in self.rotations for f in (r.node, r.start, r.end)]

    def row(self, x) -> int:
        """The row of the state symbol x."""
        return self.rows.index(x)


def _fail(message: str):
    raise ProblemError(f"ENERGY: {message}")


# Functions that jump where their argument crosses a value: in the density or a rate, with s
# in the argument, they put a jump (or a delta) at an interior point of the rod.
_JUMPS = (sp.Heaviside, sp.DiracDelta, sp.Piecewise, sp.sign, sp.floor, sp.ceiling, sp.frac,
          sp.Min, sp.Max)


def _check_smooth_in_s(expr, what, s) -> None:
    """Refuse a density or rate that jumps in s inside the rod (a point load at mid-span
    written ``F Heaviside(1/2 - s) ...``). The solutions are collocation polynomials on
    the mesh intervals, C^1 across the nodes (the cubic scheme), and the step control asks
    their residual to fall below ``tol`` on every interval: a jump in y' at s = c leaves a
    residual of the jump's size on the interval that holds c however the mesh is refined,
    and the branch ends MX at its first step ("error estimate ... > tol"), which does not
    say why. The two pieces are written instead as two halves folded onto [0, 1], where
    the point is an end of both (docs/energy.md, a load inside the rod)."""
    for f in sorted(expr.atoms(*_JUMPS), key=sp.default_sort_key):
        # s in the argument itself, not only through a coordinate theta(s) (a kink in the
        # state, a one-sided foundation Max(theta, 0), is the model's own, at no fixed point)
        fields = {g: sp.Dummy() for g in (*f.atoms(sp.Derivative), *f.atoms(AppliedUndef))}
        if s in f.xreplace(fields).free_symbols:
            _fail(f"{what} contains {f}, which jumps in {s} inside the rod: the collocation "
                  "cannot resolve a jump at an interior point (the branch would end MX at its "
                  f"first step); write each piece of the rod as a coordinate of its own on "
                  f"{s} in [0, 1], the point where they meet an end of both (a load inside "
                  "the rod, docs/energy.md)")


def _name_of(obj) -> str | None:
    """The name a user's key stands for: a coordinate or quadrature given as ``theta(s)``,
    ``theta(1)``, the function ``theta`` or the string ``"theta"``; a symbol's name; a
    rotation's name."""
    if isinstance(obj, str):
        return obj
    if isinstance(obj, AppliedUndef):
        return obj.func.__name__
    if isinstance(obj, UndefinedFunction):
        return obj.__name__
    if isinstance(obj, sp.Symbol):
        return obj.name
    if isinstance(obj, Rotation):
        return obj.name
    return None


def _checked_name(name, what) -> str:
    if not isinstance(name, str) or not name or not name.isprintable() or "/" in name \
            or name.strip() != name:
        _fail(f"{what} name {name!r}: use a non-empty printable name without '/' or spaces "
              "at its ends")
    return name


def _number(value, what) -> float:
    try:
        out = float(sp.sympify(value))
    except (TypeError, ValueError, sp.SympifyError):
        _fail(f"{what} must be a number, got {value!r}")
    if not math.isfinite(out):
        _fail(f"{what} must be finite, got {value!r}")
    return out


class _Names:
    """The user's coordinates, quadratures and parameters, mapped to internal symbols."""

    def __init__(self, energy: Energy):
        s = energy.s
        if not isinstance(s, sp.Symbol):
            _fail(f"s must be a sympy Symbol, got {s!r}")
        self.s = s
        self.S = sp.Dummy("s", real=True)
        self.functions = {}                    # name -> (kind, index)
        self.coordinates, self.quadratures, self.rotations = [], [], []
        self.order = []                        # the coordinates in declaration order
        for i, f in enumerate(energy.coordinates):
            if isinstance(f, Rotation):
                name = _checked_name(f.name, "rotation")
                self._claim(name, "rotation")
                self.functions[name] = ("rotations", len(self.rotations))
                self.order.append(("rotations", len(self.rotations)))
                self.rotations.append(f)
                continue
            if not (isinstance(f, AppliedUndef) and f.args == (s,)):
                _fail(f"coordinates[{i}] = {f!r}: expected a function of s, "
                      f"sympy.Function(name)({s}), or a Rotation")
            name = _checked_name(f.func.__name__, "coordinate")
            self._claim(name, "coordinate")
            self.functions[name] = ("coordinates", len(self.coordinates))
            self.order.append(("coordinates", len(self.coordinates)))
            self.coordinates.append(name)
        for i, f in enumerate(energy.quadratures):
            if not (isinstance(f, AppliedUndef) and f.args == (s,)):
                _fail(f"quadratures[{i}] = {f!r}: expected a function of s, "
                      f"sympy.Function(name)({s})")
            name = _checked_name(f.func.__name__, "quadrature")
            self._claim(name, "quadrature")
            self.functions[name] = ("quadratures", len(self.quadratures))
            self.quadratures.append(name)
        if not self.order:
            _fail("coordinates is empty: the energy needs at least one coordinate")
        k, nq = len(self.coordinates), len(self.quadratures)
        self.Z = [sp.Dummy(f"z{i}", real=True) for i in range(k)]
        self.V = [sp.Dummy(f"v{i}", real=True) for i in range(k)]
        self.M = [sp.Dummy(f"m{i}", real=True) for i in range(k)]
        self.W = [sp.Dummy(f"w{i}", real=True) for i in range(k)]
        self.X = [sp.Dummy(f"x{j}", real=True) for j in range(nq)]
        self.momenta, rotation_momenta = self._momenta(energy.momenta)
        self.rot = []
        for j, r in enumerate(self.rotations):
            quaternion = tuple(_checked_name(q, "quaternion state") for q in r.quaternion)
            if len(quaternion) != 4:
                _fail(f"rotation {r.name}: quaternion names {len(quaternion)} states, not 4")
            for q in quaternion:
                self._claim(q, "quaternion state")
            self.rot.append(RotationInfo(
                r.name, quaternion, rotation_momenta[j], r,
                Q=[sp.Dummy(f"q{j}{i}", real=True) for i in range(4)],
                Mr=[sp.Dummy(f"mr{j}{i}", real=True) for i in range(3)],
                U=[sp.Dummy(f"u{j}{i}", real=True) for i in range(3)],
                MB=[sp.Dummy(f"mb{j}{i}", real=True) for i in range(3)]))
        # the states: coordinates, momenta (declaration order), quadratures
        coord_states, momentum_states = [], []
        coord_names, momentum_names = [], []
        for kind, i in self.order:
            if kind == "coordinates":
                coord_states.append(self.Z[i])
                coord_names.append(self.coordinates[i])
                momentum_states.append(self.M[i])
                momentum_names.append(self.momenta[i])
            else:
                r = self.rot[i]
                coord_states += r.Q
                coord_names += r.quaternion
                momentum_states += r.Mr
                momentum_names += r.momenta
        canonical = [*coord_states, *momentum_states, *self.X]
        names = [*coord_names, *momentum_names, *self.quadratures]
        if energy.states is not None:
            given = [_name_of(x) for x in energy.states]
            if sorted(map(str, given)) != sorted(names) or len(set(given)) != len(given):
                _fail(f"states {given!r} is not an order of the derived states "
                      f"({', '.join(names)}): name each exactly once")
            perm = [names.index(x) for x in given]
        else:
            perm = list(range(len(names)))
        self.rows = [canonical[i] for i in perm]
        self.names = tuple(names[i] for i in perm)
        n = len(self.rows)
        self.YA = [sp.Dummy(f"ya{i}", real=True) for i in range(n)]
        self.YB = [sp.Dummy(f"yb{i}", real=True) for i in range(n)]
        self.at0 = dict(zip(self.rows, self.YA))
        self.at1 = dict(zip(self.rows, self.YB))
        offset = k
        for j, r in enumerate(self.rot):
            r.node = Frame(r.Q, f"{j}")
            r.start = Frame([self.at0[q] for q in r.Q], f"{j}a")
            r.end = Frame([self.at1[q] for q in r.Q], f"{j}b")
            r.offset = offset
            offset += 3
        self.params, self.P, self.user_symbols = [], {}, {}
        for sym, value in energy.parameters.items():
            if not isinstance(sym, sp.Symbol) or sym == s:
                _fail(f"parameter {sym!r}: expected a sympy Symbol other than s")
            name = _checked_name(sym.name, "parameter")
            self._claim(name, "parameter")
            decl = value if isinstance(value, Param) else Param(value)
            self.params.append((name, sym, decl))
            self.P[name] = sp.Dummy(name, real=True)
            self.user_symbols[sym] = self.P[name]
        self.rotation_symbols = {}
        for r in self.rot:
            for a in range(3):
                for b in range(3):
                    self.rotation_symbols[r.user.matrix[a, b]] = ("R", r, a, b)
            for i in range(3):
                self.rotation_symbols[r.user.strain[i]] = ("u", r, i, None)
        clash = sorted(x.name for x in self.rotation_symbols if x.name in self.P)
        if clash:
            _fail(f"the name {clash[0]!r} is used twice (parameter and a rotation's symbol)")

    _kinds: dict

    def _claim(self, name, what):
        kinds = self.__dict__.setdefault("_kinds", {})
        if name in kinds:
            _fail(f"the name {name!r} is used twice ({kinds[name]} and {what}); every "
                  "coordinate, momentum, quadrature and parameter needs its own")
        kinds[name] = what

    def _momenta(self, momenta):
        """The scalar coordinates' momentum names, and each rotation's three."""
        scalar = {c: f"m_{c}" for c in self.coordinates}
        rotation = {r.name: tuple(f"m_{r.name}{i + 1}" for i in range(3))
                    for r in self.rotations}
        if momenta is None:
            pass
        elif isinstance(momenta, dict):
            for key, value in momenta.items():
                name = _name_of(key)
                if name in scalar:
                    scalar[name] = _name_of(value)
                elif name in rotation:
                    rotation[name] = self._three(value, name)
                else:
                    _fail(f"momenta: {key!r} is not a coordinate; coordinates are "
                          f"{', '.join(self._declared())}")
        else:
            values = list(momenta)
            if len(values) != len(self.order):
                _fail(f"momenta names {len(values)} states for {len(self.order)} coordinates")
            for (kind, i), value in zip(self.order, values):
                if kind == "coordinates":
                    scalar[self.coordinates[i]] = _name_of(value)
                else:
                    rotation[self.rotations[i].name] = self._three(value,
                                                                   self.rotations[i].name)
        names = [scalar[c] for c in self.coordinates]
        for name in names:
            self._claim(_checked_name(name, "momentum"), "momentum")
        out = [rotation[r.name] for r in self.rotations]
        for three in out:
            for name in three:
                self._claim(_checked_name(name, "momentum"), "momentum")
        return names, out

    @staticmethod
    def _three(value, name):
        if isinstance(value, str) or len(list(value)) != 3:
            _fail(f"momenta[{name}]: a rotation's moment is three states; give three names")
        return tuple(_name_of(v) for v in value)

    def _declared(self):
        return [(self.coordinates[i] if kind == "coordinates" else self.rotations[i].name)
                for kind, i in self.order]

    def coordinate(self, key, what) -> tuple[str, int]:
        """(kind, index) of a key naming a coordinate, a rotation or a quadrature."""
        name = _name_of(key)
        if name not in self.functions:
            known = ", ".join(self._declared() + self.quadratures)
            _fail(f"{what}: {key!r} is not a declared coordinate or quadrature (declared: "
                  f"{known})")
        return self.functions[name]

    def convert(self, expr, what, *, end=None, derivatives=True, quadratures=False,
                state=True, s_allowed=True):
        """``expr`` in the internal symbols, refused with one line where it contains
        anything else. ``end``: 0 or 1 for an end term (coordinates stand for their end
        values there)."""
        try:
            expr = sp.sympify(expr)
        except (sp.SympifyError, TypeError):
            _fail(f"{what} is not a sympy expression: {expr!r:.80}")
        if isinstance(expr, (sp.MatrixBase, sp.MatrixExpr)):
            # sympy's immutable matrices are Exprs too: without this a column of terms, or a
            # quadratic form u.T K u (a 1 x 1 matrix), fails deep in the derivation
            rows, cols = expr.shape
            _fail(f"{what} is a {rows} x {cols} matrix, not a scalar expression"
                  + (": take its entry, [0]" if (rows, cols) == (1, 1) else
                     ": an energy is one number; add its terms"))
        if not isinstance(expr, sp.Expr):
            _fail(f"{what} is not a scalar expression: {expr!r:.80}")
        s = self.s
        if end is None:
            _check_smooth_in_s(expr, what, s)
        subs = {}
        for d in sorted(expr.atoms(sp.Derivative), key=sp.default_sort_key):
            f = d.expr
            name = _name_of(f) if isinstance(f, AppliedUndef) else None
            if name not in self.functions or f.args != (s,):
                _fail(f"{what} contains the derivative {d}: only coordinates' first "
                      "derivatives in s may appear")
            kind, i = self.functions[name]
            if d.derivative_count != 1 or d.variables != (s,):
                _fail(f"{what} contains {d}: the energy may contain first derivatives only "
                      "(a first-order Lagrangian)")
            if kind == "quadratures":
                _fail(f"{what} contains {d}: a quadrature's derivative is its rate; write "
                      "the rate")
            if not derivatives or not state:
                _fail(f"{what} contains the derivative {d}: "
                      + ("end terms depend on the end values only" if state
                         else "it may depend on the parameters only"))
            subs[d] = self.V[i]
        expr = expr.xreplace(subs)
        subs = {}
        for f in sorted(expr.atoms(AppliedUndef), key=sp.default_sort_key):
            name = f.func.__name__
            if name not in self.functions or len(f.args) != 1 \
                    or self.functions[name][0] == "rotations":
                _fail(f"{what} contains {f}, which is neither a coordinate nor a quadrature "
                      f"(declared: {', '.join(self._declared() + self.quadratures)})")
            kind, i = self.functions[name]
            arg = f.args[0]
            if not state:
                _fail(f"{what} contains {f}: it may depend on the parameters only")
            if end is None and arg != s:
                _fail(f"{what} contains {f}: the density is written in {name}({s}), not in "
                      "its values at a point")
            if end is not None and arg not in (s, sp.Integer(end)):
                _fail(f"{what} contains {f}: an end term at s = {end} contains the "
                      f"coordinates at s = {end} only")
            if kind == "quadratures" and not quadratures:
                _fail(f"{what} contains the quadrature {f}"
                      + (": a quadrature enters only the end terms (linearly); in the "
                         "density its second variation would need the perturbations to obey "
                         "the pointwise constraint x' = g, which the engine's form "
                         "cannot express: make it a coordinate, its rate x' = g then an "
                         "energy term (a shear stiffness G (x' - g)^2 / 2, as the foundation "
                         "column's), since a coordinate alone is free of g" if end is None else
                         ": at s = 0 a quadrature is its initial value; use the parameters"))
            subs[f] = (self.Z if kind == "coordinates" else self.X)[i]
        expr = expr.xreplace(subs)
        subs = dict(self.user_symbols)
        for x in expr.free_symbols & set(self.rotation_symbols):
            kind, r, a, b = self.rotation_symbols[x]
            if not state:
                _fail(f"{what} contains {x}: it may depend on the parameters only")
            if kind == "u":
                if not derivatives:
                    _fail(f"{what} contains the strain {x}: end terms depend on the end "
                          "values only (the frame, not its strains)")
                subs[x] = r.U[a]
            else:
                frame = r.node if end is None else (r.start if end == 0 else r.end)
                subs[x] = frame.R[a, b]
        if s in expr.free_symbols:
            if end is not None:
                subs[s] = sp.Integer(end)
            elif not s_allowed:
                _fail(f"{what} contains {s}: it may depend on the parameters only")
            else:
                subs[s] = self.S
        expr = expr.xreplace(subs)
        known = {self.S, *self.Z, *self.V, *self.X, *self.P.values()}
        for r in self.rot:
            known |= {*r.U, *r.node.entries, *r.start.entries, *r.end.entries}
        unknown = sorted((str(x) for x in expr.free_symbols - known))
        if unknown:
            _fail(f"{what} contains {', '.join(unknown)}, not a parameter; declare it in "
                  "parameters")
        if expr.has(sp.I) or expr.has(sp.zoo) or expr.has(sp.nan) or expr.has(sp.oo):
            _fail(f"{what} is not a finite real expression: {expr}")
        return expr

    def user(self, expr):
        """``expr`` with the user's names, for comments and messages."""
        back = {self.S: self.s}
        back.update({z: sp.Symbol(c) for z, c in zip(self.Z, self.coordinates)})
        back.update({v: sp.Symbol(c + "'") for v, c in zip(self.V, self.coordinates)})
        back.update({m: sp.Symbol(c) for m, c in zip(self.M, self.momenta)})
        back.update({x: sp.Symbol(c) for x, c in zip(self.X, self.quadratures)})
        back.update({p: sp.Symbol(name) for name, p in self.P.items()})
        for r in self.rot:
            back.update({u: sp.Symbol(f"{r.name}.u{i + 1}") for i, u in enumerate(r.U)})
            back.update({m: sp.Symbol(c) for m, c in zip(r.Mr, r.momenta)})
            back.update({m: sp.Symbol(f"({r.name}^T m)_{i + 1}") for i, m in enumerate(r.MB)})
            back.update({q: sp.Symbol(c) for q, c in zip(r.Q, r.quaternion)})
            for frame, where in ((r.node, ""), (r.start, "(0)"), (r.end, "(1)")):
                back.update({frame.R[a, b]: sp.Symbol(f"{r.name}{a + 1}{b + 1}{where}")
                             for a in range(3) for b in range(3)})
        back.update({y: sp.Symbol(f"{c}(0)") for y, c in zip(self.YA, self.names)})
        back.update({y: sp.Symbol(f"{c}(1)") for y, c in zip(self.YB, self.names)})
        back.update({w: sp.Symbol(c + "''") for w, c in zip(self.W, self.coordinates)})
        if isinstance(expr, (list, tuple)):
            return "[" + ", ".join(self.user(e) for e in expr) + "]"
        return " ".join(sp.sstr(sp.sympify(expr).xreplace(back)).split())


def _gradient(expr, symbols):
    return [sp.diff(expr, x) for x in symbols]


def _hessian(expr, rows, cols):
    return [[sp.diff(expr, r, c) for c in cols] for r in rows]


class _Directions:
    """The perturbations' components (the scalar coordinates', then 3 per rotation) as
    derivatives of an expression: along the configuration (``conf``: d/dzeta_i, or D_c for a
    rotation) and along the velocities (``vel``: d/dzeta_i', or, for w' acting on the
    strains as R^T w', sum_b R_cb d/du_b). ``vel`` does not differentiate R: apply it last."""

    def __init__(self, nm, where="node"):
        self.items = [("z", i, None) for i in range(len(nm.Z))]
        self.items += [("r", r, c) for r in nm.rot for c in range(3)]
        self.nm, self.where = nm, where

    def frame(self, r):
        return getattr(r, self.where)

    def conf(self, expr, item):
        kind, i, c = item
        if kind == "z":
            return sp.diff(expr, self.nm.Z[i])
        return self.frame(i).rotate(expr, c)

    def vel(self, expr, item):
        kind, i, c = item
        if kind == "z":
            return sp.diff(expr, self.nm.V[i])
        R = i.node.R
        return sp.Add(*[R[c, b] * sp.diff(expr, i.U[b]) for b in range(3)])


def _check_end_live(nm, end: int, B, essential: dict, clamps: dict) -> None:
    """Refuse a term of the end term ``B`` (``end0``, ``end1``, a sum's top-level terms) that
    contains end values, all of them prescribed at that end (``fixed0``/``fixed1``: essential
    coordinates, clamped frames). On every admissible configuration such a term is a
    constant: the natural condition it was written for is replaced by the essential one, so
    it changes no equilibrium, and a parameter in it alone (a spring constant) would be
    called ``free`` with an ordinate that is zero. A term with one value left free (a
    coupling ``k (theta(0) - phi(0))^2 / 2`` with ``theta(0)`` prescribed) is live."""
    frames = {i: (r.start if end == 0 else r.end) for i, r in enumerate(nm.rot)}
    fixed, live = {}, set()
    for i, z in enumerate(nm.Z):
        if i in essential:
            fixed[z] = nm.coordinates[i]
        else:
            live.add(z)
    for i, frame in frames.items():
        for x in frame.entries:
            if i in clamps:
                fixed[x] = nm.rot[i].name
            else:
                live.add(x)
    live |= set(nm.X)              # a quadrature's final value (a dead load on a position)
    for term in sp.Add.make_args(B):
        syms = term.free_symbols
        if syms & set(fixed) and not syms & live:
            names = sorted({fixed[x] for x in syms & set(fixed)})
            _fail(f"end{end} contains the term {nm.user(term)} in {', '.join(names)} at "
                  f"s = {end}, which fixed{end} prescribes: it is a constant there and "
                  f"changes no equilibrium (a spring at an essential end does nothing); "
                  f"drop it, or leave {', '.join(names)} out of fixed{end} to make that end "
                  f"natural (the spring then sets it)")


def derive(energy: Energy) -> Derived:
    """The derived expressions of ``energy`` (module docstring); ProblemError (one line)
    where the energy cannot be derived or the engine cannot express it."""
    if not isinstance(energy, Energy):
        _fail(f"ENERGY() returned {type(energy).__name__}; expected an "
              "elastica_auto.energy.Energy")
    nm = _Names(energy)
    Z, V, M, X, S, P = nm.Z, nm.V, nm.M, nm.X, nm.S, nm.P
    rot = nm.rot
    k, nq = len(Z), len(X)
    L = nm.convert(energy.density, "the density")
    rates = []
    for j, (f, g) in enumerate(energy.quadratures.items()):
        rates.append(nm.convert(g, f"the rate of {nm.quadratures[j]}"))

    # -- end data --------------------------------------------------------------------------
    essential = {0: {}, 1: {}}                 # coordinate index -> value (in P)
    clamps = {0: {}, 1: {}}                    # rotation index -> quaternion (in P)
    initial, final = {}, {}                    # quadrature index -> value
    for end, given in ((0, energy.fixed0), (1, energy.fixed1)):
        for key, value in given.items():
            kind, i = nm.coordinate(key, f"fixed{end}")
            if kind == "rotations":
                clamps[end][i] = _quaternion(nm, value, f"fixed{end}[{rot[i].name}]")
                continue
            label = (nm.coordinates if kind == "coordinates" else nm.quadratures)[i]
            if kind == "quadratures" and end == 1:
                # a constraint x(1) = c may depend on the coordinates' and frames' values at
                # s = 1 (a pinned lever arm: x(1) + a(theta(1)) = X)
                expr = nm.convert(value, f"fixed1[{label}]", end=1, derivatives=False)
            else:
                expr = nm.convert(value, f"fixed{end}[{label}]", state=False,
                                  s_allowed=False)
            if kind == "coordinates":
                essential[end][i] = expr
            else:
                (initial if end == 0 else final)[i] = expr
    for j, name in enumerate(nm.quadratures):
        if j not in initial:
            _fail(f"the quadrature {name} has no initial value: give it in fixed0 "
                  f"({{{name}: 0}} for {name}(0) = 0)")
    multipliers = {}
    for key, mu in energy.multipliers.items():
        kind, j = nm.coordinate(key, "multipliers")
        if kind != "quadratures":
            _fail(f"multipliers: {key!r} is a coordinate; a multiplier belongs to a "
                  "quadrature whose final value fixed1 prescribes")
        sign, symbol = 1, mu
        if isinstance(mu, sp.Mul) and len(mu.args) == 2 and mu.args[0] == -1:
            sign, symbol = -1, mu.args[1]          # E - n (x(1) - c): n the reaction
        name = _name_of(symbol)
        if not isinstance(symbol, sp.Symbol) or name not in P:
            _fail(f"multipliers[{nm.quadratures[j]}] = {mu!r}: expected one of the "
                  "parameters' symbols, or minus one (declare it in parameters, with its "
                  "default)")
        if name in {m[0] for m in multipliers.values()}:
            _fail(f"multipliers: {name} is the multiplier of two constraints")
        multipliers[j] = (name, sign)
    for j in final:
        if j not in multipliers:
            _fail(f"fixed1[{nm.quadratures[j]}] is an isoperimetric constraint "
                  f"{nm.quadratures[j]}(1) = {nm.user(final[j])}: name its multiplier, "
                  f"multipliers={{{nm.quadratures[j]}: mu}} with mu a parameter")
    for j in multipliers:
        if j not in final:
            _fail(f"multipliers[{nm.quadratures[j]}]: {nm.quadratures[j]}(1) is not "
                  "prescribed; give its value in fixed1")
    mu = {j: sign * P[name] for j, (name, sign) in multipliers.items()}

    B0 = nm.convert(energy.end0, "end0", end=0, derivatives=False, quadratures=True)
    B1 = nm.convert(energy.end1, "end1", end=1, derivatives=False, quadratures=True)
    B0 = B0.xreplace({X[j]: initial[j] for j in range(nq)})
    B1 = B1.xreplace({X[j]: final[j] for j in final})
    for end, B in ((0, B0), (1, B1)):
        _check_end_live(nm, end, B, essential[end], clamps[end])
    end_entries = {x for r in rot for x in r.end.entries}
    c1 = {}
    for j in range(nq):
        c = sp.diff(B1, X[j])
        if c.free_symbols & {*Z, *X, *end_entries}:
            _fail(f"end1 contains {nm.quadratures[j]}(1) times {nm.user(c)}: a quadrature's "
                  "end value may enter only linearly, with a coefficient in the parameters; "
                  "otherwise the second variation has a product of two integrals of h (a "
                  "nonlocal term) that the engine's form cannot express")
        if c != 0:
            c1[j] = c
    B1p = B1.xreplace({x: 0 for x in X})            # B1 = B1' + c1.x(1)
    # a constraint's value that depends on the end (-mu c in E + mu (x(1) - c)) is an end
    # term of the Lagrangian: in the natural conditions and E1, not in the energy E
    B1p -= sum((mu[j] * final[j] for j in final if final[j].free_symbols - set(P.values())),
               sp.Integer(0))
    lam = {j: c1.get(j, 0) + mu.get(j, 0) for j in range(nq)}
    lam = {j: v for j, v in lam.items() if v != 0}
    Leff = L + sum((lam[j] * rates[j] for j in lam), sp.Integer(0))

    multiplier_names = {m[0] for m in multipliers.values()}
    for name in multiplier_names:
        p = P[name]
        for what, expr in (("the density", L), ("end0", B0), ("end1", B1),
                           *((f"the rate of {nm.quadratures[j]}", g)
                             for j, g in enumerate(rates)),
                           *((f"fixed0[{nm.coordinates[i]}]", e)
                             for i, e in essential[0].items()),
                           *((f"fixed1[{nm.coordinates[i]}]", e)
                             for i, e in essential[1].items()),
                           *((f"fixed{end}[{rot[i].name}]", e) for end in (0, 1)
                             for i, q in clamps[end].items() for e in q),
                           *((f"fixed0[{nm.quadratures[j]}]", e) for j, e in initial.items()),
                           *((f"fixed1[{nm.quadratures[j]}]", e) for j, e in final.items())):
            if expr.has(p):
                _fail(f"the multiplier {name} appears in {what}: a multiplier enters only "
                      "through its constraint (as E + mu (x(1) - c))")

    # -- the Legendre transform ------------------------------------------------------------
    velocities = [*V, *(u for r in rot for u in r.U)]
    Lv = _gradient(Leff, velocities)
    A = _hessian(Leff, velocities, velocities)
    linear = not any(a.has(*velocities) for row in A for a in row)
    defaults = {P[name]: _number(decl.default, f"parameter {name}'s default")
                for name, _, decl in nm.params}
    _check_convex(nm, A, defaults, linear)
    velocity = None
    if linear:
        b = [lv.xreplace({v: 0 for v in velocities}) for lv in Lv]
        Am = sp.Matrix(A)          # positive definite at the samples (_check_convex)
        # a rotation's momentum in the body, R^T m, is the symbol MB (computed at the nodes
        # as R^T m: codegen), so that the inverse stays short
        momenta = [*M, *(e for r in rot for e in r.MB)]
        rhs_vec = sp.Matrix([momenta[i] - b[i] for i in range(len(velocities))])
        sol = [rhs_vec[0] / Am[0, 0]] if len(velocities) == 1 else list(Am.LUsolve(rhs_vec))
        unknowns = momenta
        velocity = [_shorter(sp.factor_terms(sp.cancel(v)) if v.is_rational_function(*unknowns)
                             else v) for v in sol]

    def on_solution(expr):
        return expr.xreplace(dict(zip(velocities, velocity))) if linear else expr

    # -- the system, its ends --------------------------------------------------------------
    Lz = _gradient(Leff, Z)
    system = dict(zip(Z, V))
    system.update(zip(M, Lz))
    system.update(zip(X, rates))
    for r in rot:
        qdot = _hamilton(r.Q, [0, *r.U])
        system.update({q: e / 2 for q, e in zip(r.Q, qdot)})
        system.update({m: r.node.rotate(Leff, c) for c, m in enumerate(r.Mr)})
    rhs = [on_solution(system[x]) for x in nm.rows]
    YA, YB = nm.YA, nm.YB
    at0, at1 = nm.at0, nm.at1
    at0_all = {**at0, **{x: y for r in rot for x, y in zip(r.node.entries, r.start.entries)}}
    at1_all = {**at1, **{x: y for r in rot for x, y in zip(r.node.entries, r.end.entries)}}
    bc = []
    for end, B, at, fixed in ((0, B0, at0, essential[0]), (1, B1p, at1, essential[1])):
        sign = -1 if end == 0 else 1
        for kind, i in nm.order:
            if kind == "coordinates":
                if i in fixed:
                    bc.append(at[Z[i]] - fixed[i])
                else:
                    bc.append(sign * at[M[i]] + sp.diff(B, Z[i]).xreplace(at))
                continue
            r = rot[i]
            frame = r.start if end == 0 else r.end
            q = [at[x] for x in r.Q]
            if i in clamps[end]:
                qc = clamps[end][i]
                if end == 0:
                    bc += [a - b for a, b in zip(q, qc)]
                else:       # the same frame: conj(q_c) (x) q(1) real (3 rows)
                    bc += _hamilton([qc[0], -qc[1], -qc[2], -qc[3]], q)[1:]
            else:
                bc += [sign * at[m] + frame.rotate(B, c).xreplace(at)
                       for c, m in enumerate(r.Mr)]
                if end == 0:        # the scale of q, which nothing else fixes
                    bc.append(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2 - 1)
    for j in range(nq):
        bc.append(at0[X[j]] - initial[j])
    free = []
    for j in sorted(final):
        bc.append(at1[X[j]] - final[j].xreplace(at1))
        free.append(multipliers[j][0])
    for r in rot:
        for end, other in ((0, 1), (1, 0)):
            if r.offset is not None and i not in clamps[end] and False:
                pass

    # -- the second variation --------------------------------------------------------------
    dirs = _Directions(nm)
    items = dirs.items
    K = len(items)
    A2 = [[on_solution(dirs.vel(dirs.vel(Leff, b), a)) for b in items] for a in items]
    C2 = [[on_solution(dirs.vel(dirs.conf(Leff, b), a)) for b in items] for a in items]
    B2 = [[on_solution(dirs.conf(dirs.conf(Leff, b), a)) for b in items] for a in items]
    for r in rot:              # -m.(w x w') = -w'.[m]_x w, and D_i D_c not symmetric
        o = r.offset
        half = -_cross_matrix(r.Mr) / 2
        for a in range(3):
            for b in range(3):
                C2[o + a][o + b] = C2[o + a][o + b] + half[a, b]
        block = [[B2[o + a][o + b] for b in range(3)] for a in range(3)]
        for a in range(3):
            for b in range(3):
                if a != b:
                    B2[o + a][o + b] = (block[a][b] + block[b][a]) / 2
    ends = []
    for where, B, at in (("start", B0, at0_all), ("end", B1p, at1_all)):
        d = _Directions(nm, where)
        zsub = {z: at[z] for z in Z}
        E = [[d.conf(d.conf(B, b), a).xreplace(zsub) for b in items] for a in items]
        for r in rot:
            o = r.offset
            block = [[E[o + a][o + b] for b in range(3)] for a in range(3)]
            for a in range(3):
                for b in range(3):
                    if a != b:
                        E[o + a][o + b] = (block[a][b] + block[b][a]) / 2
        ends.append(E)
    E0, E1 = ends
    W = nm.W
    constraints = []
    at_end = _Directions(nm, "end")
    for j in sorted(final):
        g = rates[j]
        gz, gv = [dirs.conf(g, a) for a in items], [dirs.vel(g, a) for a in items]
        # x(1) - c(zeta(1)) = 0 linearised: the end's part -dc/dzeta(1).h(1)
        dc = [-at_end.conf(final[j], a).xreplace(at1_all) for a in items]
        if rot and any(e != 0 for e in gv):
            if not linear:
                _fail(f"the constraint on {nm.quadratures[j]}: its rate contains derivatives "
                      "or strains, and the density is not quadratic in them: integrating "
                      "the constraint by parts along the solution would need the strains' "
                      "and derivatives' rates (u', zeta'') computed numerically at each point "
                      "(derived only where the density is quadratic in them); write the rate "
                      "in the coordinates and the frame, or the density quadratic")
            fld = [gz[i] - _rotation_total(nm, e, Leff) for i, e in enumerate(gv)]
        elif any(e != 0 for e in gv):
            # (g_v)' along the solution: zeta' = V, zeta'' = W (runtime.acceleration)
            total = [sum((sp.diff(e, Z[j]) * V[j] + sp.diff(e, V[j]) * W[j]
                          for j in range(k)), sp.diff(e, S)) for e in gv]
            fld = [gz[i] - total[i] for i in range(k)]
            if linear:          # zeta'' = A^-1 (L_z - C zeta' - L_vs) (runtime.acceleration)
                Am = sp.Matrix(A)
                acc = Am.LUsolve(sp.Matrix([
                    Lz[i] - sum((sp.diff(Leff, V[i], Z[j]) * V[j] for j in range(k)),
                                sp.Integer(0)) - sp.diff(Lv[i], S) for i in range(k)]))
                fld = [e.xreplace(dict(zip(W, acc))) for e in fld]
        else:
            fld = gz
        constraints.append(([on_solution(e) for e in fld], [on_solution(e) for e in gv], dc))
    fixed0 = sorted([*essential[0], *(rot[i].offset + c for i in clamps[0] for c in range(3))])
    fixed1 = sorted([*essential[1], *(rot[i].offset + c for i in clamps[1] for c in range(3))])

    # -- where each parameter enters, its ordinate -----------------------------------------
    parameters = []
    ordinates = []
    user_terms_L = [L, *(rates[j] for j in lam)]
    user_terms_B = [B0, B1, *(initial[j] for j in lam), *(final[j] for j in final)]
    passive = [*(rates[j] for j in range(nq) if j not in lam),
               *(initial[j] for j in range(nq) if j not in lam)]
    turns = {end: {i: _turns(qc) for i, qc in clamps[end].items()} for end in (0, 1)}
    for name, sym, decl in nm.params:
        p = P[name]
        info = ParameterInfo(name, p, defaults[p], _tex(decl.tex, sym), "", _period(decl, name),
                             str(decl.doc), _shift(nm, decl, name), _flip(nm, decl, name))
        if name in multiplier_names:
            info.enters, info.multiplier = "ode", True
            info.where = "the multiplier of a constraint (solved for)"
            parameters.append(info)
            continue
        in_l = any(e.has(p) for e in user_terms_L)
        in_b = any(e.has(p) for e in user_terms_B)
        in_d = any(e.has(p) for end in (0, 1) for e in essential[end].values()) \
            or any(e.has(p) for end in (0, 1) for qc in clamps[end].values() for e in qc)
        if in_l:
            enters, where = "ode", "the density"
        elif in_b:
            enters, where = "free", "the end terms"
        elif in_d:
            enters, where = "fixed", "the essential end values only"
        elif any(e.has(p) for e in passive):
            enters, where = "free", "passive quadratures only: dE/dxi = 0, no ordinate"
        else:
            _fail(f"the parameter {name} enters nowhere: not in the density, the end terms, "
                  "the end values or a quadrature")
        if decl.enters is not None:
            if decl.enters not in ENTERS:
                _fail(f"parameter {name}: enters={decl.enters!r}, expected one of {ENTERS}")
            enters = decl.enters
        info.enters, info.where = enters, where
        integrand = sp.diff(L, p) + sum((lam[j] * sp.diff(rates[j], p) for j in lam),
                                        sp.Integer(0))
        # each end term at its own end's values (x(1) in B1_xi: the state's end value)
        ends_xi = sp.diff(B0, p).xreplace(at0) + sp.diff(B1, p).xreplace(at1)
        ends_xi += sum((lam[j] * sp.diff(initial[j], p) for j in lam), sp.Integer(0))
        ends_xi -= sum((mu[j] * sp.diff(final[j], p).xreplace(at1) for j in final),
                       sp.Integer(0))
        ends_xi -= sum((YA[nm.rows.index(M[i])] * sp.diff(e, p)
                        for i, e in essential[0].items()), sp.Integer(0))
        ends_xi += sum((YB[nm.rows.index(M[i])] * sp.diff(e, p)
                        for i, e in essential[1].items()), sp.Integer(0))
        for end, sign, Y in ((0, -1, YA), (1, 1, YB)):
            for i, turn in turns[end].items():
                w = turn(p)
                ends_xi += sign * sum((Y[nm.rows.index(m)] * e for m, e in zip(rot[i].Mr, w)),
                                      sp.Integer(0))
        if integrand == 0 and ends_xi == 0:
            parameters.append(info)
            continue
        info.sign = -1 if enters == "fixed" else 1
        default = f"R_{name}" if info.sign < 0 else f"dE_d{name}"
        info.ordinate = _checked_name(decl.ordinate or default, "ordinate")
        tex = _tex_bare(info.tex)
        ordinates.append(dict(
            name=info.ordinate, parameter=name, sign=info.sign,
            tex=(r"$-\partial E/\partial " if info.sign < 0 else r"$\partial E/\partial ")
            + tex + "$",
            doc=("the reaction -dE/d" if info.sign < 0 else "dE/d") + f"{name} along the "
                f"equilibria ({name} enters {where}); ordinate for {name}",
            integrand=integrand, ends=ends_xi))
        parameters.append(info)
    energy_integrand = L
    energy_ends = (B0.xreplace(at0) + B1.xreplace(at1))
    ordinates.append(dict(name="E", parameter=None, sign=1, tex="$E$",
                          doc="the energy E at the solution", integrand=energy_integrand,
                          ends=energy_ends))

    parts = {}
    for pname, members in energy.parts.items():
        pname = _checked_name(pname, "part")
        comps = []
        for key in members:
            if isinstance(key, RotationComponent):
                kind, i = nm.coordinate(key.rotation, f"parts[{pname}]")
                comps.append(rot[i].offset + key.index)
                continue
            kind, i = nm.coordinate(key, f"parts[{pname}]")
            if kind == "quadratures":
                _fail(f"parts[{pname}]: {key!r} is a quadrature; parts group coordinates")
            comps += [i] if kind == "coordinates" else [rot[i].offset + c for c in range(3)]
        parts[pname] = comps
    if parts and sorted(i for c in parts.values() for i in c) != list(range(K)):
        _fail(f"parts {', '.join(parts)} do not partition the coordinates (each in exactly "
              "one part)")

    names = {q.name: "parameter" for q in parameters}
    for item in [o["name"] for o in ordinates] + list(parts):
        if item in names:
            _fail(f"the name {item!r} is used twice ({names[item]} and ordinate)"
                  + (f"; the energy's ordinate is named E: rename the {names[item]}"
                     if item == "E" else "; rename one of them (Param(ordinate=...))"))
        names[item] = "ordinate"

    ends_info = dict(B0=B0, B1=B1p, essential=essential, clamps=clamps,
                     constant=sum((c1[j] * initial[j] for j in c1), sp.Integer(0)))
    derived = Derived(
        coordinates=nm.coordinates, momenta=nm.momenta, quadratures=nm.quadratures,
        parameters=parameters, S=S, Z=Z, V=V, M=M, X=X, W=W, YA=YA, YB=YB, P=P,
        linear=linear, velocity=velocity, lagrangian=Leff, density=L, rates=rates, rhs=rhs,
        bc=bc, A=A2, C=C2, B=B2, E0=E0, E1=E1, fixed0=fixed0, fixed1=fixed1,
        constraints=constraints, ordinates=ordinates,
        energy_integrand=energy_integrand, energy_ends=energy_ends, free=tuple(free),
        parts=parts, ends=ends_info, rows=nm.rows, names=nm.names, rotations=rot)
    derived.summary = _summary(nm, derived, L, B0, B1, rates, initial, final, essential,
                               multipliers, clamps)
    derived.user = nm.user
    return derived


def _shorter(v):
    """``v`` or its expansion, whichever has fewer operations. A shearable rod's x' = (S R
    v_hat + n) / S over one denominator expands to R v_hat + n / S, whose R v_hat then
    cancels, as sympy adds terms, against the - R v_hat of the strain x' - R v_hat in the
    equations and the second variation (n / S where the common denominator left S (x' - R
    v_hat) as seven products and sums of arrays)."""
    expanded = sp.expand(v)
    return expanded if sp.count_ops(expanded) < sp.count_ops(v) else v


def _rotation_total(nm, e, Leff):
    """d e / ds along a solution, for e in the scalar coordinates, their derivatives, the
    frames and strains at the nodes, s: e_z zeta' + e_v zeta'' + e_s + e_R : R [u]_x +
    e_u u', with the accelerations (zeta'', u') from the momentum equations differentiated
    along the solution (L quadratic in the velocities v = (zeta', u), A = L_vv constant in
    them):

        d/ds L_zeta' = L_zeta           (the scalar coordinates' m' = L_z),
        d/ds L_u     = R^T tau - u x L_u (m_b = R^T m: m_b' = R^T m' + R'^T m, R' = R [u]_x),

    each side's s-derivative in the velocities' rates: A (zeta'', u') = r, with r the right
    sides less the rest of the total derivative of L_v (in zeta, R, s). (The caller puts the
    Legendre inverse in for the velocities: on the solution.)"""
    Z, V, S = nm.Z, nm.V, nm.S
    k = len(Z)
    strains = [u for r in nm.rot for u in r.U]
    velocities = [*V, *strains]
    rates = [sp.Dummy(f"a{i}", real=True) for i in range(len(velocities))]

    def total(expr):
        """d expr / ds with the velocities' rates as the symbols ``rates``."""
        out = sp.diff(expr, S)
        out += sum((sp.diff(expr, z) * v for z, v in zip(Z, V)), sp.Integer(0))
        out += sum((sp.diff(expr, v) * a for v, a in zip(velocities, rates)), sp.Integer(0))
        for r in nm.rot:
            turned = r.node.R * _cross_matrix(r.U)           # R' = R [u]_x
            out += sum((sp.diff(expr, r.node.R[a, b]) * turned[a, b]
                        for a in range(3) for b in range(3)), sp.Integer(0))
        return out

    equations = []
    for i in range(k):
        equations.append(total(sp.diff(Leff, V[i])) - sp.diff(Leff, Z[i]))
    for r in nm.rot:
        lu = [sp.diff(Leff, u) for u in r.U]
        tau = [r.node.rotate(Leff, c) for c in range(3)]
        body_tau = [sum((r.node.R[a, c] * tau[a] for a in range(3)), sp.Integer(0))
                    for c in range(3)]
        u_cross = [r.U[1] * lu[2] - r.U[2] * lu[1], r.U[2] * lu[0] - r.U[0] * lu[2],
                   r.U[0] * lu[1] - r.U[1] * lu[0]]
        for c in range(3):
            equations.append(total(lu[c]) - body_tau[c] + u_cross[c])
    # linear in the rates: A rates + rest = 0
    A = sp.Matrix([[sp.diff(eq, a) for a in rates] for eq in equations])
    rest = sp.Matrix([eq.xreplace({a: 0 for a in rates}) for eq in equations])
    solved = list(A.LUsolve(-rest))
    return total(e).xreplace(dict(zip(rates, solved)))


def _quaternion(nm, value, what) -> list:
    """A clamp's quaternion (4 expressions in the parameters)."""
    try:
        items = list(value)
    except TypeError:
        items = None
    if items is None or len(items) != 4:
        _fail(f"{what}: a rotation's end value is a quaternion, four expressions in the "
              "parameters (scalar first); got {value!r:.80}")
    q = [nm.convert(e, what, state=False, s_allowed=False) for e in items]
    if all(e.is_number for e in q) and sum(float(e) ** 2 for e in q) < 1e-24:
        _fail(f"{what}: the quaternion is zero")
    return q


def _turns(qc):
    """xi -> w_xi = 2 Im(dq_c/dxi (x) conj(q_c)) / |q_c|^2, the spatial rotation of the clamp
    per unit xi (its first-order turn: [w] = dR_c/dxi R_c^T)."""
    conj = [qc[0], -qc[1], -qc[2], -qc[3]]
    size = qc[0] ** 2 + qc[1] ** 2 + qc[2] ** 2 + qc[3] ** 2

    def turn(p):
        if not any(e.has(p) for e in qc):
            return [0, 0, 0]
        dq = [sp.diff(e, p) for e in qc]
        w = [2 * e / size for e in _hamilton(dq, conj)[1:]]
        return [sp.factor_terms(e) for e in w]
    return turn


def _tex(tex, sym) -> str:
    if tex is not None:
        if not isinstance(tex, str) or not tex.isprintable():
            _fail(f"parameter {sym.name}: tex must be a one-line string, got {tex!r}")
        return tex
    return sp.latex(sym)


def _tex_bare(tex: str) -> str:
    return tex[1:-1] if len(tex) > 1 and tex[0] == tex[-1] == "$" else tex


def _period(decl: Param, name):
    if decl.period is None:
        return None
    value = _number(decl.period, f"parameter {name}'s period")
    if value <= 0:
        _fail(f"parameter {name}'s period must be positive, got {value}")
    return value


def _state_name(nm, key, what):
    name = _name_of(key)
    if name not in nm.names:
        _fail(f"{what}: {key!r} is not a state ({', '.join(nm.names)})")
    return name


def _shift(nm, decl, name) -> dict:
    items = decl.period_shift.items() if isinstance(decl.period_shift, dict) else \
        decl.period_shift
    for key, _ in items:
        if isinstance(key, Rotation):
            _fail(f"parameter {name}'s period_shift: {key.name} is a rotation; a period "
                  "turns its quaternion to -q (period_flip)")
    return {_state_name(nm, key, f"parameter {name}'s period_shift"):
            _number(v, f"parameter {name}'s period_shift") for key, v in items}


def _flip(nm, decl, name) -> tuple:
    """The states a period negates; a rotation stands for its quaternion's four."""
    out = []
    for key in decl.period_flip:
        if isinstance(key, Rotation):
            kind, i = nm.coordinate(key, f"parameter {name}'s period_flip")
            out += nm.rot[i].quaternion
        else:
            out.append(_state_name(nm, key, f"parameter {name}'s period_flip"))
    return tuple(out)



#: Where the Legendre condition is checked: s, and (seeded) values of the coordinates and
#: their derivatives (and each rotation's frame and strains), the parameters at their
#: defaults.
CONVEXITY_SAMPLES = 24
_S_SAMPLES = (0.0, 0.5, 1.0)


def _random_rotation(rng):
    """A rotation matrix from a random quaternion."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]])


def _check_convex(nm, A, defaults, linear):
    """Refuse a density that is not strictly convex in zeta' and the strains (A = L_vv not
    positive definite) at one of the samples: there the Legendre map has no unique inverse,
    and the second variation no index. Says for which coordinate and at which sample."""
    k = len(nm.Z)
    strains = [u for r in nm.rot for u in r.U]
    frames = [x for r in nm.rot for x in r.node.entries]
    labels = [*nm.coordinates, *(f"{r.name}.u{i + 1}" for r in nm.rot for i in range(3))]
    kv = len(labels)
    rng = np.random.default_rng(0)
    points = np.vstack((np.zeros((1, k + kv)),
                        rng.uniform(-1.5, 1.5, size=(CONVEXITY_SAMPLES, k + kv))))
    if linear:
        points[:, k:] = 0.0
    rotations = [np.eye(3)] + [_random_rotation(rng) for _ in range(CONVEXITY_SAMPLES)]
    entries = [[a.xreplace(defaults) for a in row] for row in A]
    fn = sp.lambdify([nm.S, *nm.Z, *nm.V, *strains, *frames], entries, modules="numpy")
    for s in _S_SAMPLES:
        for point, frame in zip(points, rotations):
            values = [*point, *(frame.ravel().tolist() * len(nm.rot))]
            with np.errstate(all="ignore"):
                try:
                    a = np.array(fn(s, *values), dtype=float).reshape(kv, kv)
                except (ArithmeticError, ValueError, TypeError):
                    continue
            if not np.all(np.isfinite(a)):
                continue
            w, vecs = np.linalg.eigh(0.5 * (a + a.T))
            if w[0] > 1e-12 * max(1.0, abs(w[-1])):
                continue
            i = int(np.argmax(np.abs(vecs[:, 0])))
            where = ", ".join([f"s = {s:g}"]
                              + [f"{c} = {v:.3g}" for c, v in zip(nm.coordinates, point[:k])]
                              + ([] if linear else [f"{c}' = {v:.3g}" for c, v in
                                                    zip(labels, point[k:])]))
            what = (f"d2L/d{labels[0]}'2 = {w[0]:.3g}" if kv == 1 else
                    f"the Hessian of L in the derivatives has the eigenvalue {w[0]:.3g}, "
                    f"mostly along {labels[i]}'")
            hint = ""
            if i >= k and all(sp.sympify(a) == 0 for a in A[i]):
                # the strain is nowhere in L: the likely cause is a frame's derivative
                # written as R.d3.diff(s), which is zero (the entries of R.matrix stand for
                # the frame at s, symbols to sympy), not d3' = R (u x e3)
                name = labels[i].split(".")[0]
                hint = (f"; the density does not contain {labels[i]}: a frame's derivative "
                        f"is written in its strains, R' = R [u]_x (d3' = {name}.matrix * "
                        f"{name}.strain.cross(e3)), never {name}.d3.diff(s), which is zero")
            _fail(f"the density is not strictly convex in {labels[i]}' ({what} at "
                  f"{where}, the parameters at their defaults): the Legendre transform has "
                  f"no unique inverse there, and the second variation no index{hint}")


def _summary(nm, d, L, B0, B1, rates, initial, final, essential, multipliers,
             clamps) -> list[str]:
    """The derivation in words and formulas, with the user's names: the generated module's
    header comment."""
    u = nm.user
    lines = [f"L  = {u(L)}"]
    if B0 != 0:
        lines.append(f"B0 = {u(B0)}")
    if B1 != 0:
        lines.append(f"B1 = {u(B1)}")
    for j, name in enumerate(nm.quadratures):
        line = f"{name}' = {u(rates[j])}, {name}(0) = {u(initial[j])}"
        if j in final:
            mult = ("-" if multipliers[j][1] < 0 else "") + multipliers[j][0]
            line += (f", {name}(1) = {u(final[j])} (multiplier {mult}: E + {mult} "
                     f"({name}(1) - {u(final[j])}))")
        lines.append(line)
    for end in (0, 1):
        for i, e in essential[end].items():
            lines.append(f"{nm.coordinates[i]}({end}) = {u(e)} (essential)")
        for i, q in clamps[end].items():
            lines.append(f"{nm.rot[i].name}({end}) = R({u(q)}) (a clamp: w({end}) = 0)")
    for r in nm.rot:
        lines.append(f"rotation {r.name}: quaternion {', '.join(r.quaternion)} (R = R(q/|q|), "
                     f"q' = q (x) (0, u) / 2), strains {r.name}.u1..3 = (R^T R')^vee, spatial "
                     f"moment {', '.join(r.momenta)} = R dL/du")
    if nm.coordinates:
        lines.append("momenta: " + ", ".join(f"{m} = dL/d{c}'" for c, m in
                                             zip(nm.coordinates, nm.momenta))
                     + (" (of L + lam.g: the quadratures' terms of B1 and their constraints' "
                        "multipliers)" if d.lagrangian != L else ""))
    if d.linear:
        labels = [*(c + "'" for c in nm.coordinates),
                  *(f"{r.name}.u{i + 1}" for r in nm.rot for i in range(3))]
        lines.append("Legendre inverse (linear solve): " + ", ".join(
            f"{c} = {u(v)}" for c, v in zip(labels, d.velocity)))
    else:
        lines.append("Legendre inverse: Newton's method per point (L is not quadratic in "
                     + ", ".join([*(c + "'" for c in nm.coordinates),
                                  *(f"{r.name}.u{i + 1}" for r in nm.rot for i in range(3))])
                     + ")")
    return lines
