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
* The distinguished ordinate of a parameter xi is the total derivative of E along the
  equilibria (the envelope theorem, as the Lagrangian is stationary there)::

      dE/dxi = int (L_xi + lam.g_xi) ds + B0_xi + B1_xi + lam.x0_xi - mu.c_xi
               - m(0).zeta0_xi + m(1).zeta1_xi

  xi ``enters`` ``"ode"`` where L or an active rate contains it, ``"free"`` where only end
  terms (or a constrained or energetic quadrature's end data) do, ``"fixed"`` where only the
  essential values do: that one's ordinate is the reaction -dE/dxi (the fold rule's sign,
  docs/stability.md). A parameter only in passive quadratures has dE/dxi = 0 and no ordinate.

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
from .declare import Energy, Param

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


@dataclass
class Derived:
    """The derived expressions, in the internal symbols: ``S`` (s), ``Z``, ``V``, ``M``, ``X``
    (coordinates, their derivatives, momenta, quadratures), ``P`` (parameters, by name),
    ``YA``, ``YB`` (the states at s = 0 and s = 1) and ``W`` (zeta'' along the solution)."""

    coordinates: list
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
    velocity: list | None            # V(Z, M, S) where linear
    lagrangian: sp.Expr              # L_eff in (Z, V, S, P)
    density: sp.Expr                 # the user's L in (Z, V, S, P)
    rates: list                      # g in (Z, V, S, P)
    rhs: list                        # in (Z, M, S, P) where linear, else in (Z, V, S, P)
    bc: list                         # in (YA, YB, P)
    A: list
    C: list
    B: list
    E0: list                         # in YA
    E1: list                         # in YB
    fixed0: list
    fixed1: list
    constraints: list                # (field in Z, V, W, S, P; g_v in Z, V, S, P)
    ordinates: list                  # (name, tex, doc, parameter, sign, integrand, end part)
    energy_integrand: sp.Expr
    energy_ends: sp.Expr
    free: tuple
    parts: dict
    ends: dict                       # B0, B1' in Z (the gradient flow), essential values
    summary: list = field(default_factory=list)   # lines for the generated module's header
    user: object = None              # expr -> text with the user's names (`_Names.user`)

    @property
    def k(self) -> int:
        return len(self.Z)

    @property
    def states(self) -> tuple:
        return (*self.coordinates, *self.momenta, *self.quadratures)


def _fail(message: str):
    raise ProblemError(f"ENERGY: {message}")


def _name_of(obj) -> str | None:
    """The name a user's key stands for: a coordinate or quadrature given as ``theta(s)``,
    ``theta(1)``, the function ``theta`` or the string ``"theta"``; a symbol's name."""
    if isinstance(obj, str):
        return obj
    if isinstance(obj, AppliedUndef):
        return obj.func.__name__
    if isinstance(obj, UndefinedFunction):
        return obj.__name__
    if isinstance(obj, sp.Symbol):
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
        self.coordinates, self.quadratures = [], []
        for what, items, out in (("coordinates", energy.coordinates, self.coordinates),
                                 ("quadratures", list(energy.quadratures), self.quadratures)):
            for i, f in enumerate(items):
                if not (isinstance(f, AppliedUndef) and f.args == (s,)):
                    _fail(f"{what}[{i}] = {f!r}: expected a function of s, "
                          f"sympy.Function(name)({s})")
                name = _checked_name(f.func.__name__, what[:-1])
                self._claim(name, what[:-1])
                self.functions[name] = (what, len(out))
                out.append(name)
        if not self.coordinates:
            _fail("coordinates is empty: the energy needs at least one coordinate")
        k, nq = len(self.coordinates), len(self.quadratures)
        self.Z = [sp.Dummy(f"z{i}", real=True) for i in range(k)]
        self.V = [sp.Dummy(f"v{i}", real=True) for i in range(k)]
        self.M = [sp.Dummy(f"m{i}", real=True) for i in range(k)]
        self.W = [sp.Dummy(f"w{i}", real=True) for i in range(k)]
        self.X = [sp.Dummy(f"x{j}", real=True) for j in range(nq)]
        n = 2 * k + nq
        self.YA = [sp.Dummy(f"ya{i}", real=True) for i in range(n)]
        self.YB = [sp.Dummy(f"yb{i}", real=True) for i in range(n)]
        self.momenta = self._momenta(energy.momenta)
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

    _kinds: dict

    def _claim(self, name, what):
        kinds = self.__dict__.setdefault("_kinds", {})
        if name in kinds:
            _fail(f"the name {name!r} is used twice ({kinds[name]} and {what}); every "
                  "coordinate, momentum, quadrature and parameter needs its own")
        kinds[name] = what

    def _momenta(self, momenta):
        k = len(self.coordinates)
        if momenta is None:
            names = [f"m_{c}" for c in self.coordinates]
        elif isinstance(momenta, dict):
            given = {}
            for key, value in momenta.items():
                name = _name_of(key)
                if name not in self.coordinates:
                    _fail(f"momenta: {key!r} is not a coordinate; coordinates are "
                          f"{', '.join(self.coordinates)}")
                given[name] = _name_of(value)
            names = [given.get(c, f"m_{c}") for c in self.coordinates]
        else:
            names = [_name_of(v) for v in momenta]
            if len(names) != k:
                _fail(f"momenta names {len(names)} states for {k} coordinates")
        for name in names:
            self._claim(_checked_name(name, "momentum"), "momentum")
        return names

    def coordinate(self, key, what) -> tuple[str, int]:
        """(kind, index) of a key naming a coordinate or a quadrature."""
        name = _name_of(key)
        if name not in self.functions:
            known = ", ".join(self.coordinates + self.quadratures)
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
        if not isinstance(expr, sp.Expr):
            _fail(f"{what} is not a scalar expression: {expr!r:.80}")
        s = self.s
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
            if name not in self.functions or len(f.args) != 1:
                _fail(f"{what} contains {f}, which is neither a coordinate nor a quadrature "
                      f"(declared: {', '.join(self.coordinates + self.quadratures)})")
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
                         "cannot express: make it a coordinate" if end is None else
                         ": at s = 0 a quadrature is its initial value; use the parameters"))
            subs[f] = (self.Z if kind == "coordinates" else self.X)[i]
        expr = expr.xreplace(subs)
        subs = dict(self.user_symbols)
        if s in expr.free_symbols:
            if end is not None:
                subs[s] = sp.Integer(end)
            elif not s_allowed:
                _fail(f"{what} contains {s}: it may depend on the parameters only")
            else:
                subs[s] = self.S
        expr = expr.xreplace(subs)
        known = {self.S, *self.Z, *self.V, *self.X, *self.P.values()}
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
        states = self.coordinates + self.momenta + self.quadratures
        back.update({y: sp.Symbol(f"{c}(0)") for y, c in zip(self.YA, states)})
        back.update({y: sp.Symbol(f"{c}(1)") for y, c in zip(self.YB, states)})
        back.update({w: sp.Symbol(c + "''") for w, c in zip(self.W, self.coordinates)})
        if isinstance(expr, (list, tuple)):
            return "[" + ", ".join(self.user(e) for e in expr) + "]"
        return " ".join(sp.sstr(sp.sympify(expr).xreplace(back)).split())


def _gradient(expr, symbols):
    return [sp.diff(expr, x) for x in symbols]


def _hessian(expr, rows, cols):
    return [[sp.diff(expr, r, c) for c in cols] for r in rows]


def derive(energy: Energy) -> Derived:
    """The derived expressions of ``energy`` (module docstring); ProblemError (one line)
    where the energy cannot be derived or the engine cannot express it."""
    if not isinstance(energy, Energy):
        _fail(f"ENERGY() returned {type(energy).__name__}; expected an "
              "elastica_auto.energy.Energy")
    nm = _Names(energy)
    Z, V, M, X, S, P = nm.Z, nm.V, nm.M, nm.X, nm.S, nm.P
    k, nq = len(Z), len(X)
    L = nm.convert(energy.density, "the density")
    rates = []
    for j, (f, g) in enumerate(energy.quadratures.items()):
        rates.append(nm.convert(g, f"the rate of {nm.quadratures[j]}"))

    # -- end data --------------------------------------------------------------------------
    essential = {0: {}, 1: {}}                 # coordinate index -> value (in P)
    initial, final = {}, {}                    # quadrature index -> value
    for end, given in ((0, energy.fixed0), (1, energy.fixed1)):
        for key, value in given.items():
            kind, i = nm.coordinate(key, f"fixed{end}")
            label = (nm.coordinates if kind == "coordinates" else nm.quadratures)[i]
            expr = nm.convert(value, f"fixed{end}[{label}]", state=False, s_allowed=False)
            if kind == "coordinates":
                essential[end][i] = expr
            else:
                (initial if end == 0 else final)[i] = expr
    for j, name in enumerate(nm.quadratures):
        if j not in initial:
            _fail(f"the quadrature {name} has no initial value: give it in fixed0 "
                  f"({{{name}: 0}} for x(0) = 0)")
    multipliers = {}
    for key, mu in energy.multipliers.items():
        kind, j = nm.coordinate(key, "multipliers")
        if kind != "quadratures":
            _fail(f"multipliers: {key!r} is a coordinate; a multiplier belongs to a "
                  "quadrature whose final value fixed1 prescribes")
        name = _name_of(mu)
        if not isinstance(mu, sp.Symbol) or name not in P:
            _fail(f"multipliers[{nm.quadratures[j]}] = {mu!r}: expected one of the "
                  "parameters' symbols (declare it in parameters, with its default)")
        if name in {_name_of(m) for m in multipliers.values()}:
            _fail(f"multipliers: {name} is the multiplier of two constraints")
        multipliers[j] = mu
    for j in final:
        if j not in multipliers:
            _fail(f"fixed1[{nm.quadratures[j]}] is an isoperimetric constraint "
                  f"{nm.quadratures[j]}(1) = {nm.user(final[j])}: name its multiplier, "
                  f"multipliers={{{nm.quadratures[j]}: mu}} with mu a parameter")
    for j in multipliers:
        if j not in final:
            _fail(f"multipliers[{nm.quadratures[j]}]: {nm.quadratures[j]}(1) is not "
                  "prescribed; give its value in fixed1")
    mu = {j: P[_name_of(m)] for j, m in multipliers.items()}

    B0 = nm.convert(energy.end0, "end0", end=0, derivatives=False, quadratures=True)
    B1 = nm.convert(energy.end1, "end1", end=1, derivatives=False, quadratures=True)
    B0 = B0.xreplace({X[j]: initial[j] for j in range(nq)})
    B1 = B1.xreplace({X[j]: final[j] for j in final})
    c1 = {}
    for j in range(nq):
        c = sp.diff(B1, X[j])
        if c.free_symbols & {*Z, *X}:
            _fail(f"end1 contains {nm.quadratures[j]}(1) times {nm.user(c)}: a quadrature's "
                  "end value may enter only linearly, with a coefficient in the parameters; "
                  "otherwise the second variation has a product of two integrals of h (a "
                  "nonlocal term) that the engine's form cannot express")
        if c != 0:
            c1[j] = c
    B1p = B1.xreplace({x: 0 for x in X})            # B1 = B1' + c1.x(1)
    lam = {j: c1.get(j, 0) + mu.get(j, 0) for j in range(nq)}
    lam = {j: v for j, v in lam.items() if v != 0}
    Leff = L + sum((lam[j] * rates[j] for j in lam), sp.Integer(0))

    multiplier_names = {_name_of(m) for m in multipliers.values()}
    for name in multiplier_names:
        p = P[name]
        for what, expr in (("the density", L), ("end0", B0), ("end1", B1),
                           *((f"the rate of {nm.quadratures[j]}", g)
                             for j, g in enumerate(rates)),
                           *((f"fixed0[{nm.coordinates[i]}]", e)
                             for i, e in essential[0].items()),
                           *((f"fixed1[{nm.coordinates[i]}]", e)
                             for i, e in essential[1].items()),
                           *((f"fixed0[{nm.quadratures[j]}]", e) for j, e in initial.items()),
                           *((f"fixed1[{nm.quadratures[j]}]", e) for j, e in final.items())):
            if expr.has(p):
                _fail(f"the multiplier {name} appears in {what}: a multiplier enters only "
                      "through its constraint (as E + mu (x(1) - c))")

    # -- the Legendre transform ------------------------------------------------------------
    Lv = _gradient(Leff, V)
    A = _hessian(Leff, V, V)
    linear = not any(a.has(*V) for row in A for a in row)
    defaults = {P[name]: _number(decl.default, f"parameter {name}'s default")
                for name, _, decl in nm.params}
    _check_convex(nm, A, defaults, linear)
    velocity = None
    if linear:
        b = [lv.xreplace({v: 0 for v in V}) for lv in Lv]
        Am = sp.Matrix(A)          # positive definite at the samples (_check_convex)
        rhs_vec = sp.Matrix([M[i] - b[i] for i in range(k)])
        sol = [rhs_vec[0] / Am[0, 0]] if k == 1 else list(Am.LUsolve(rhs_vec))
        velocity = [sp.factor_terms(sp.cancel(v)) if v.is_rational_function(*M) else v
                    for v in sol]

    def on_solution(expr):
        return expr.xreplace(dict(zip(V, velocity))) if linear else expr

    # -- the system, its ends --------------------------------------------------------------
    Lz = _gradient(Leff, Z)
    rhs = [*V, *Lz, *rates]
    rhs = [on_solution(e) for e in rhs]
    YA, YB = nm.YA, nm.YB
    at0 = dict(zip([*Z, *M, *X], YA))
    at1 = dict(zip([*Z, *M, *X], YB))
    bc = []
    for i in range(k):
        bc.append(YA[i] - essential[0][i] if i in essential[0]
                  else -YA[k + i] + sp.diff(B0, Z[i]).xreplace(at0))
    for i in range(k):
        bc.append(YB[i] - essential[1][i] if i in essential[1]
                  else YB[k + i] + sp.diff(B1p, Z[i]).xreplace(at1))
    for j in range(nq):
        bc.append(YA[2 * k + j] - initial[j])
    free = []
    for j in sorted(final):
        bc.append(YB[2 * k + j] - final[j])
        free.append(_name_of(multipliers[j]))

    # -- the second variation --------------------------------------------------------------
    A2 = [[on_solution(a) for a in row] for row in A]
    C2 = [[on_solution(sp.diff(Leff, V[i], Z[j])) for j in range(k)] for i in range(k)]
    B2 = [[on_solution(b) for b in row] for row in _hessian(Leff, Z, Z)]
    E0 = [[e.xreplace(at0) for e in row] for row in _hessian(B0, Z, Z)]
    E1 = [[e.xreplace(at1) for e in row] for row in _hessian(B1p, Z, Z)]
    W = nm.W
    constraints = []
    for j in sorted(final):
        g = rates[j]
        gz, gv = _gradient(g, Z), _gradient(g, V)
        if any(e != 0 for e in gv):
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
        constraints.append(([on_solution(e) for e in fld], [on_solution(e) for e in gv]))

    # -- where each parameter enters, its ordinate -----------------------------------------
    parameters = []
    ordinates = []
    user_terms_L = [L, *(rates[j] for j in lam)]
    user_terms_B = [B0, B1, *(initial[j] for j in lam), *(final[j] for j in final)]
    passive = [*(rates[j] for j in range(nq) if j not in lam),
               *(initial[j] for j in range(nq) if j not in lam)]
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
        in_d = any(e.has(p) for end in (0, 1) for e in essential[end].values())
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
        ends = sp.diff(B0, p).xreplace(at0) + sp.diff(B1, p).xreplace(at1)
        ends += sum((lam[j] * sp.diff(initial[j], p) for j in lam), sp.Integer(0))
        ends -= sum((mu[j] * sp.diff(final[j], p) for j in final), sp.Integer(0))
        ends -= sum((YA[k + i] * sp.diff(e, p) for i, e in essential[0].items()),
                    sp.Integer(0))
        ends += sum((YB[k + i] * sp.diff(e, p) for i, e in essential[1].items()),
                    sp.Integer(0))
        if integrand == 0 and ends == 0:
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
            integrand=integrand, ends=ends))
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
            kind, i = nm.coordinate(key, f"parts[{pname}]")
            if kind != "coordinates":
                _fail(f"parts[{pname}]: {key!r} is a quadrature; parts group coordinates")
            comps.append(i)
        parts[pname] = comps
    if parts and sorted(i for c in parts.values() for i in c) != list(range(k)):
        _fail(f"parts {', '.join(parts)} do not partition the coordinates (each in exactly "
              "one part)")

    names = {q.name: "parameter" for q in parameters}
    for item in [o["name"] for o in ordinates] + list(parts):
        if item in names:
            _fail(f"the name {item!r} is used twice ({names[item]} and ordinate)"
                  + (f"; the energy's ordinate is named E: rename the {names[item]}"
                     if item == "E" else "; rename one of them (Param(ordinate=...))"))
        names[item] = "ordinate"

    ends = dict(B0=B0, B1=B1p, essential=essential,
                constant=sum((c1[j] * initial[j] for j in c1), sp.Integer(0)))
    derived = Derived(
        coordinates=nm.coordinates, momenta=nm.momenta, quadratures=nm.quadratures,
        parameters=parameters, S=S, Z=Z, V=V, M=M, X=X, W=W, YA=YA, YB=YB, P=P,
        linear=linear, velocity=velocity, lagrangian=Leff, density=L, rates=rates, rhs=rhs,
        bc=bc, A=A2, C=C2, B=B2, E0=E0, E1=E1, fixed0=sorted(essential[0]),
        fixed1=sorted(essential[1]), constraints=constraints, ordinates=ordinates,
        energy_integrand=energy_integrand, energy_ends=energy_ends, free=tuple(free),
        parts=parts, ends=ends)
    derived.summary = _summary(nm, derived, L, B0, B1, rates, initial, final, essential,
                               multipliers)
    derived.user = nm.user
    return derived


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
    states = nm.coordinates + nm.momenta + nm.quadratures
    if name not in states:
        _fail(f"{what}: {key!r} is not a state ({', '.join(states)})")
    return name


def _shift(nm, decl, name) -> dict:
    items = decl.period_shift.items() if isinstance(decl.period_shift, dict) else \
        decl.period_shift
    return {_state_name(nm, key, f"parameter {name}'s period_shift"):
            _number(v, f"parameter {name}'s period_shift") for key, v in items}


def _flip(nm, decl, name) -> tuple:
    return tuple(_state_name(nm, key, f"parameter {name}'s period_flip")
                 for key in decl.period_flip)


#: Where the Legendre condition is checked: s, and (seeded) values of the coordinates and
#: their derivatives, the parameters at their defaults.
CONVEXITY_SAMPLES = 24
_S_SAMPLES = (0.0, 0.5, 1.0)


def _check_convex(nm, A, defaults, linear):
    """Refuse a density that is not strictly convex in zeta' (A = L_vv not positive
    definite) at one of the samples: there the Legendre map has no unique inverse, and the
    second variation no index. Says for which coordinate and at which sample."""
    k = len(nm.Z)
    rng = np.random.default_rng(0)
    points = np.vstack((np.zeros((1, 2 * k)),
                        rng.uniform(-1.5, 1.5, size=(CONVEXITY_SAMPLES, 2 * k))))
    if linear:
        points[:, k:] = 0.0
    entries = [[a.xreplace(defaults) for a in row] for row in A]
    fn = sp.lambdify([nm.S, *nm.Z, *nm.V], entries, modules="numpy")
    for s in _S_SAMPLES:
        for point in points:
            with np.errstate(all="ignore"):
                try:
                    a = np.array(fn(s, *point), dtype=float).reshape(k, k)
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
                                                    zip(nm.coordinates, point[k:])]))
            what = (f"d2L/d{nm.coordinates[0]}'2 = {w[0]:.3g}" if k == 1 else
                    f"the Hessian of L in the derivatives has the eigenvalue {w[0]:.3g}, "
                    f"mostly along {nm.coordinates[i]}'")
            _fail(f"the density is not strictly convex in {nm.coordinates[i]}' ({what} at "
                  f"{where}, the parameters at their defaults): the Legendre transform has "
                  "no unique inverse there, and the second variation no index")


def _summary(nm, d, L, B0, B1, rates, initial, final, essential, multipliers) -> list[str]:
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
            line += (f", {name}(1) = {u(final[j])} (multiplier "
                     f"{_name_of(multipliers[j])}: E + {_name_of(multipliers[j])} "
                     f"({name}(1) - {u(final[j])}))")
        lines.append(line)
    for end in (0, 1):
        for i, e in essential[end].items():
            lines.append(f"{nm.coordinates[i]}({end}) = {u(e)} (essential)")
    lines.append("momenta: " + ", ".join(f"{m} = dL/d{c}'" for c, m in
                                         zip(nm.coordinates, nm.momenta))
                 + (" (of L + lam.g: the quadratures' terms of B1 and their constraints' "
                    "multipliers)" if d.lagrangian != L else ""))
    if d.linear:
        lines.append("Legendre inverse (linear solve): " + ", ".join(
            f"{c}' = {u(v)}" for c, v in zip(nm.coordinates, d.velocity)))
    else:
        lines.append("Legendre inverse: Newton's method per point (L is not quadratic in "
                     + ", ".join(c + "'" for c in nm.coordinates) + ")")
    return lines
