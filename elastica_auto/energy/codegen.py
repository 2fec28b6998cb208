"""The derived expressions (`elastica_auto.energy.derive`) as a plain equation module in numpy.

The module printed is what the cache keeps, what `load_problem` executes and what
``elastica-auto derive`` shows: the protocol's names (``STATES``, ``PARAMETERS``,
``ORDINATES``, ``rhs``, ``bc``, their derivatives, ``second_variation``,
``gradient_flow``) as formulas, after common subexpressions are taken out. Its header says
what was derived, in the user's names: the energy, the Legendre inverse, where each
parameter enters and its ordinate, the second variation.

Safety of the text: the internal symbols print as ``s``, ``y3``, ``v0``, ``p2``, ``ya1``, ...
(and ``t0``, ... for common subexpressions; for a rotation ``j`` its frame ``F0`` and body
moment ``MB0`` at the nodes with their entries ``R0_12``, ``mb0_1``, its strains ``u0_1``, its
frames at the ends ``R0a_12``, ``R0b_12`` with ``n0a``, ``dR0b_12_3`` and their common
subexpressions ``c0a_4``), names no user name can take, since every user symbol was replaced
before printing. User names appear only as string literals (``repr``) and
in ``#`` comments (they are printable: no line breaks). Module-level helpers are named
``_derived_...``; a module that defines such a name itself is refused (`loader`).
"""

from __future__ import annotations

import re

import sympy as sp
from sympy.printing.numpy import NumPyPrinter

from ..core.errors import ProblemError
from .derive import Derived
from .runtime import PREFIX, TRAILER


def _lower(k: int) -> list[str]:
    """The lines that fill d2L/dv2's lower triangle from its upper one (the Legendre map's
    Jacobian is a Hessian, symmetric): printed once, each entry would be a second
    expression for the same number, its own arithmetic on every Newton iteration."""
    return [f"    Lvv[{i}, {j}] = Lvv[{j}, {i}]" for i in range(k) for j in range(i)]


def _far(Lv, velocities) -> str:
    """``, far=True`` where dL/dv is not finite at v = 0 whatever the other symbols (a norm
    of the velocities, such as a tendon's length |v + u x d|: its gradient is 0/0 there),
    else "": Newton's Legendre inverse then starts far out at once
    (`runtime.legendre_inverse`) instead of finding out by an evaluation at 0 at every
    call. Decided on the expressions as derived; a density singular at 0 only at some
    states stays with the evaluation."""
    zero = {v: 0 for v in velocities}
    bad = (sp.nan, sp.zoo, sp.oo, -sp.oo)
    return ", far=True" if any(e.subs(zero).has(*bad) for e in Lv) else ""


class _Printer(NumPyPrinter):
    """numpy's printer, strict: a function numpy cannot evaluate is an error, not code that
    fails when it runs."""


def _fail(message):
    raise ProblemError(f"ENERGY: {message}")


def _docstring(doc: str, indent: str = "    ", width: int = 96) -> list[str]:
    """A function's docstring lines, wrapped; a text with a user's name that would end the
    literal or escape in it (three double quotes, a backslash) as one ``repr``."""
    if '"""' in doc or "\\" in doc or doc.endswith('"'):
        return [indent + repr(doc)]
    words, lines, line = doc.split(), [], indent + '"""'
    for word in words:
        if len(line) + 1 + len(word) > width and line.strip() != '"""':
            lines.append(line)
            line = indent
        line += ("" if line.endswith(('"""', " ")) else " ") + word
    lines.append(line + '"""')
    return lines


class Block:
    """Assignments of expressions to targets inside one function, with the common
    subexpressions of all of them taken out once. ``frames``: the rotations' frames
    (`elastica_auto.energy.derive.Frame`) whose entries the expressions may contain; those
    used are computed first from their quaternions (with their own common subexpressions)."""

    def __init__(self, names: dict, indent: str = "    ", frames=(), collect=()):
        self.names = names                  # internal symbol -> printed name
        self.indent = indent
        self.items = []                     # (target or None, expr)
        self.frames = list(frames)
        self.collect = tuple(collect)       # symbols to try gathering each sum's terms by

    def add(self, target, expr):
        self.items.append((target, sp.sympify(expr)))

    def lines(self, unpack, needs=()) -> list[str]:
        """The function body: ``unpack`` (entries (name, line) or (name, line, names it
        needs), in the order they may be emitted) for each input used (and for ``needs``),
        the frames used, the common subexpressions, then ``target = expr`` for each item."""
        symbols = {k: sp.Symbol(v) for k, v in self.names.items()}
        exprs = [e.xreplace(symbols) for _, e in self.items]
        temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t"), order="none")
        if self.collect:
            temps, reduced = _gathered(exprs, [symbols[x] for x in self.collect],
                                       temps, reduced)
        used = set()
        for e in [*reduced, *(t for _, t in temps)]:
            used |= {x.name for x in e.free_symbols}
        printer = _Printer({"strict": True})

        def text(e):
            try:
                return printer.doprint(e)
            except Exception as exc:                # sympy's PrintMethodNotImplementedError
                found = re.search(r":\s*(\w+)", str(exc))
                what = found.group(1) if found else str(exc).split()[0]
                _fail(f"numpy cannot evaluate the function {what}, which the derived "
                      "expressions contain: write the energy with functions numpy has")

        frame_lines = []
        for frame in self.frames:
            definitions = [(symbols[x], e.xreplace(symbols)) for x, e in
                           (*frame.definitions(), *frame.derivative_definitions())]
            needed = set()
            for x, e in reversed(definitions):
                if x.name in used or x.name in needed:
                    needed.add(x.name)
                    needed |= {y.name for y in e.free_symbols}
            chosen = [(x, e) for x, e in definitions if x.name in needed]
            if not chosen:
                continue
            used |= needed
            ftemps, fexprs = sp.cse([e for _, e in chosen], order="none",
                                    symbols=sp.numbered_symbols(f"c{frame.tag}_"))
            frame_lines += [f"{self.indent}{x} = {text(e)}" for x, e in ftemps]
            frame_lines += [f"{self.indent}{x} = {text(e)}" for (x, _), e in zip(chosen, fexprs)]
        used |= set(needs)
        for entry in reversed(unpack):
            if entry[0] in used and len(entry) > 2:
                used |= set(entry[2])
        out = [self.indent + entry[1] for entry in unpack if entry[0] in used]
        out += frame_lines
        for t, e in temps:
            out.append(f"{self.indent}{t} = {text(e)}")
        self.printed = []
        for (target, _), e in zip(self.items, reduced):
            code = text(e)
            self.printed.append(code)
            if target is not None:
                out.append(f"{self.indent}{target} = {code}")
        return out


def _gathered(exprs, by, temps, reduced):
    """The common subexpressions of ``exprs`` with each sum's terms gathered by the symbols
    ``by`` (sympy's collect: ``a y + b y -> (a + b) y``) where that leaves fewer operations
    in all (``temps``, ``reduced``: `sp.cse` of ``exprs`` as they are, kept otherwise).

    A sheared rod's m' = n x (R v_hat) comes out of the derivation expanded, nine products
    of a frame entry, an intrinsic strain and a force, each an array operation; gathered by
    the force's components, its three sums R v_hat are the ones x' = R v_hat + n / S has, and
    the common subexpressions take them out once (rhs from about 55 array operations to 25).
    Tried where a function runs at every Newton iteration (``rhs``): the second cse costs
    little there, on the second variation's blocks it would double a derivation's time."""
    alt = [sp.collect(e, by) if isinstance(e, sp.Add) else e for e in exprs]
    if alt == exprs:
        return temps, reduced
    temps2, reduced2 = sp.cse(alt, symbols=sp.numbered_symbols("t"), order="none")

    def ops(t, r):
        return sp.count_ops([e for _, e in t] + list(r))
    return (temps2, reduced2) if ops(temps2, reduced2) < ops(temps, reduced) else (temps, reduced)


def _total(expr, x, frames):
    """d expr / dx for a state x, every frame's entries taken as functions of its
    quaternion."""
    for frame in frames:
        if x in frame.q:
            return frame.total(expr, x)
    return sp.diff(expr, x)


class Module:
    """The text of the generated module of a `Derived`."""

    def __init__(self, d: Derived):
        self.d = d
        self.k, self.nq = d.k, len(d.quadratures)
        self.n = len(d.rows)
        self.K = d.components
        self.kv = len(d.velocities)
        self.pindex = {q.name: i for i, q in enumerate(d.parameters)}
        self.lines: list[str] = []
        self.zrows = [d.row(z) for z in d.Z]
        self.mrows = [d.row(m) for m in d.M]
        self.xrows = [d.row(x) for x in d.X]
        canonical = [*self.zrows, *self.mrows, *self.xrows]
        #: for each row, its place in the canonical order (coordinates, momenta,
        #: quadratures) where the states are in another (Energy(states=...)); else None
        #: (the Newton case's system is assembled in the canonical order: scalar
        #: coordinates only)
        self.order = None if d.rotations or canonical == list(range(self.n)) else \
            [canonical.index(r) for r in range(self.n)]

    # -- names of the inputs ---------------------------------------------------------------
    def _params(self):
        d = self.d
        names = {d.P[q.name]: f"p{i}" for i, q in enumerate(d.parameters)}
        unpack = [(f"p{i}", f"p{i} = p[{q.name!r}]") for i, q in enumerate(d.parameters)]
        return names, unpack

    def _node_rotations(self, names, unpack):
        """The rotations' frames R and body moments R^T m at the nodes, computed from the
        rows of y at once (`runtime.frame`, `runtime.body`): their names, and their unpack
        entries put after the states'."""
        d = self.d
        extra = []
        for j, r in enumerate(d.rotations):
            q = self._rows([d.row(x) for x in r.Q])
            m = self._rows([d.row(x) for x in r.Mr])
            extra.append((f"F{j}", f"F{j} = {PREFIX}runtime.frame(y[{q}])  # {r.name}", ()))
            for a in range(3):
                for b in range(3):
                    names[r.node.R[a, b]] = f"R{j}_{a}{b}"
                    extra.append((f"R{j}_{a}{b}", f"R{j}_{a}{b} = F{j}[{a}, {b}]", (f"F{j}",)))
            extra.append((f"MB{j}", f"MB{j} = {PREFIX}runtime.body(F{j}, y[{m}])  # "
                          f"{r.name}^T m", (f"F{j}",)))
            for c in range(3):
                names[r.MB[c]] = f"mb{j}_{c}"
                extra.append((f"mb{j}_{c}", f"mb{j}_{c} = MB{j}[{c}]", (f"MB{j}",)))
        at = max((i + 1 for i, e in enumerate(unpack) if re.fullmatch(r"y\d+", e[0])),
                 default=0)
        return unpack[:at] + extra + unpack[at:]

    def _end_frames(self, names):
        frames = [f for r in self.d.rotations for f in (r.start, r.end)]
        for f in frames:
            names.update(f.names())
        return frames

    def _states(self, with_v: bool):
        """Names for a function of (s, y, p): the states as the rows of y, V as ``v``."""
        d = self.d
        names, unpack = self._params()
        names[d.S] = "s"
        for i, x in enumerate(d.rows):
            names[x] = f"y{i}"
        unpack = [(f"y{i}", f"y{i} = y[{i}]  # {d.names[i]}") for i in range(self.n)] + unpack
        if with_v:
            for i, v in enumerate(d.velocities):
                names[v] = f"v{i}"
            unpack = [(f"v{i}", f"v{i} = v[{i}]  # {label}'")
                      for i, label in enumerate(self._velocity_labels())] + unpack
        return names, unpack

    def _velocity_labels(self):
        d = self.d
        return [*d.coordinates, *(f"{r.name}.u{i + 1}" for r in d.rotations for i in range(3))]

    def _kernel(self):
        """Names for a kernel of (s, z, v, p): Z as the rows of z, V of v (scalar
        coordinates only: the Newton inverse and the gradient flow)."""
        d = self.d
        names, unpack = self._params()
        names[d.S] = "s"
        for i, (z, v) in enumerate(zip(d.Z, d.V)):
            names[z], names[v] = f"z{i}", f"v{i}"
        unpack = ([(f"z{i}", f"z{i} = z[{i}]  # {c}") for i, c in enumerate(d.coordinates)]
                  + [(f"v{i}", f"v{i} = v[{i}]  # {c}'") for i, c in enumerate(d.coordinates)]
                  + unpack)
        return names, unpack

    def _ends(self):
        d = self.d
        names, unpack = self._params()
        for i, (a, b) in enumerate(zip(d.YA, d.YB)):
            names[a], names[b] = f"ya{i}", f"yb{i}"
        unpack = ([(f"ya{i}", f"ya{i} = ya[{i}]  # {c}(0)") for i, c in enumerate(d.states)]
                  + [(f"yb{i}", f"yb{i} = yb[{i}]  # {c}(1)") for i, c in enumerate(d.states)]
                  + unpack)
        return names, unpack

    def _solution_ends(self):
        """Names for the end values inside a function of (s, y, p)."""
        names, unpack = self._ends()
        unpack = [(key, line.replace(f"= ya[{key[2:]}]", f"= y[{key[2:]}, 0]")
                   .replace(f"= yb[{key[2:]}]", f"= y[{key[2:]}, -1]")) for key, line in unpack]
        return names, unpack

    @staticmethod
    def _rows(rows):
        """The rows ``rows`` of y as index text: a slice where they are consecutive."""
        if not rows:
            return "0:0"
        if list(rows) == list(range(rows[0], rows[0] + len(rows))):
            return f"{rows[0]}:{rows[0] + len(rows)}"
        return repr(list(rows))

    # -- output ----------------------------------------------------------------------------
    def emit(self, *lines):
        self.lines.extend(lines)

    def function(self, signature, doc, block: Block, unpack, before=(), after=()):
        self.emit("", "", f"def {signature}:", *_docstring(doc), *before,
                  *block.lines(unpack), *after)

    def alias(self, name):
        """``_derived_<name> = <name>``: the derived function that the module's own helpers
        use, whichever the module defines by hand (`loader.printed` renames it)."""
        self.emit("", "", f"{PREFIX}{name} = {name}  # what the derived ordinates use")

    def text(self) -> str:
        d = self.d
        self.header()
        self.declarations()
        if d.linear:
            self.linear_system()
        elif d.rotations:
            self.rotation_newton_system()
        else:
            self.newton_system()
        self.boundary()
        if not d.rotations:
            self.kernels()
        self.tangent()
        self.second_variation()
        self.ordinates()
        if not d.free and not d.rotations:
            self.emit("", "", "def gradient_flow(p, nodes):",
                      *_docstring('The energy discretised on ``nodes`` and its overdamped dynamics '
                                  '(runtime.gradient_flow).'),
                      f"    return {PREFIX}runtime.gradient_flow(p, nodes, {PREFIX}density, "
                      f"{PREFIX}ends, {PREFIX}essential, {self.k}, Flow, {self.zrows!r})")
        elif not d.free:
            self.frame_kernels()
            qrows = [[d.row(q) for q in r.Q] for r in d.rotations]
            self.emit("", "", "def gradient_flow(p, nodes):",
                      *_docstring('The energy discretised on ``nodes`` and the overdamped '
                                  'dynamics of its frames (frame_flow.frame_flow).'),
                      "    from elastica_auto.energy.frame_flow import frame_flow",
                      f"    return frame_flow(p, nodes, {PREFIX}frame_density, "
                      f"{PREFIX}frame_ends, {PREFIX}frame_essential, {self.k}, "
                      f"{len(d.rotations)}, Flow, {self.zrows!r}, {qrows!r})")
        return "\n".join(self.lines) + "\n\n" + TRAILER + "\n"

    def header(self):
        d = self.d
        u = d.user
        self.emit('"""An equation module derived from an energy by elastica-auto '
                  '(docs/energy.md).', "",
                  "Plain numpy: it needs neither sympy nor the module it was derived from. The "
                  "derivation is",
                  'summarised in the comments below, in the energy\'s own names."""', "")
        lines = ["E = int_0^1 L ds + B0 + B1, with", *d.summary, ""]
        lines.append("parameters (where each enters; its distinguished ordinate, which the "
                     "fold rule reads):")
        for q in d.parameters:
            ordinate = ""
            if q.ordinate:
                ordinate = (f"; ordinate {q.ordinate} = " + ("-" if q.sign < 0 else "")
                            + f"dE/d{q.name}")
            lines.append(f"  {q.name}: enters {q.enters!r} ({q.where}){ordinate}")
        for o in d.ordinates:
            parts = []
            if o["integrand"] != 0:
                parts.append(f"int_0^1 ({u(o['sign'] * o['integrand'])}) ds")
            if o["ends"] != 0:
                parts.append(u(o["sign"] * o["ends"]))
            lines.append(f"  {o['name']} = " + " + ".join(parts).replace("+ -", "- ")
                         if parts else f"  {o['name']} = 0")
        lines += ["", "second variation, d2E[h] = int (h'.A h' + 2 h'.C h + h.B h) ds "
                  "+ h(0).E0 h(0) + h(1).E1 h(1)"
                  + (f", h = ({', '.join(d.labels)}):" if d.rotations else ":")]
        for name, m in (("A", d.A), ("C", d.C), ("B", d.B), ("E0", d.E0), ("E1", d.E1)):
            lines.append(f"  {name} = {u(m) if self.K > 1 else u(m[0][0])}")
        for end, fixed in ((0, d.fixed0), (1, d.fixed1)):
            if fixed:
                lines.append(f"  h({end}) = 0 in " + ", ".join(d.labels[i] for i in fixed))
        for fld, gv, _ in d.constraints:
            lines.append(f"  constraint: int ({u(fld)}).h ds"
                         + (" = 0" if all(e == 0 for e in gv) else
                            f" - g_v(0).h(0) + g_v(1).h(1) = 0, g_v = {u(gv)}"))
        # one comment line per line, whatever sympy prints (a line break would end it)
        self.emit(*(("# " + piece).rstrip() for line in lines
                    for piece in (line.splitlines() or [""])))
        self.emit("", "import numpy", "",
                  "from elastica_auto import Constraint, Flow, Ordinate, Parameter, "
                  "SecondVariation",
                  f"from elastica_auto.energy import runtime as {PREFIX}runtime",
                  *(["from elastica_auto.numerics.stability import count_form"]
                    if d.parts else []))

    def declarations(self):
        d = self.d
        self.emit("", f"STATES = {tuple(d.states)!r}", "", "PARAMETERS = [")
        for q in d.parameters:
            extra = ""
            if q.period is not None:
                extra += f", period={q.period!r}"
            if q.period_shift:
                extra += f", period_shift={q.period_shift!r}"
            if q.period_flip:
                extra += f", period_flip={q.period_flip!r}"
            doc = q.doc or f"enters {q.where}"
            self.emit(f"    Parameter({q.name!r}, {q.default!r}, {q.tex!r}, {q.enters!r}"
                      f"{extra}, doc={doc!r}),")
        self.emit("]")
        if d.free:
            self.emit("", "# the multipliers of the isoperimetric constraints, solved for",
                      f"FREE = {d.free!r}")
        self.emit("", "# the module's own symmetry(s, y, p) hook, if it has one (the loader sets "
                  "it): where it", "# holds, its generator is a zero mode of the second "
                  "variation, left out of the count", f"{PREFIX}symmetry = None")

    # -- the system ------------------------------------------------------------------------
    def linear_system(self):
        d = self.d
        n, kv = self.n, self.kv
        names, unpack = self._states(False)
        unpack = self._node_rotations(names, unpack)
        block = Block(names, collect=d.rows)
        # a rotation's q' = q (x) (0, u) / 2 by one product (runtime.quaternion_rate), its
        # strains u the Legendre inverse's
        kinematics, after = {}, []
        for j, r in enumerate(d.rotations):
            rows = [d.row(q) for q in r.Q]
            kinematics.update(dict.fromkeys(rows))
            strains = d.velocity[self.k + 3 * j: self.k + 3 * j + 3]
            for c, e in enumerate(strains):
                block.add(f"u{j}_{c}", e)
            after.append(f"    out[{self._rows(rows)}] = {PREFIX}runtime.quaternion_rate("
                         f"y[{self._rows(rows)}], u{j}_0, u{j}_1, u{j}_2)  # {r.name}")
        for i, e in enumerate(d.rhs):
            if i not in kinematics:
                block.add(f"out[{i}]", e)
        self.function("rhs(s, y, p)", "zeta' = V(zeta, m), m' = dL/dzeta, x' = g (the "
                      "Euler-Lagrange equations in the states)"
                      + ("; q' = q (x) (0, u) / 2 and m' = the torque D L for a rotation."
                         if d.rotations else "."), block, unpack,
                      before=["    out = numpy.empty(y.shape)"],
                      after=[*after, "    return out"])
        self.alias("rhs")
        if d.rotations:
            self.rotation_jacobian(names, unpack)
        else:
            block = Block(names)
            for i, e in enumerate(d.rhs):
                for j, x in enumerate(d.rows):
                    de = sp.diff(e, x)
                    if de != 0:
                        block.add(f"jac[{i}, {j}]", de)
            self.function("rhs_jac(s, y, p)", "df/dy, (n, n, m).", block, unpack,
                          before=[f"    jac = numpy.zeros(({n}, {n}, y.shape[1]))"],
                          after=["    return jac"])
        self._by_parameter("rhs_dp(s, y, p, name)", "df/dp[name], (n, m).", d.rhs, names,
                           unpack, "    out = numpy.zeros(y.shape)", "out[{i}]")
        block = Block(names)
        for i, e in enumerate(d.velocity):
            block.add(f"v[{i}]", e)
        self.function(f"{PREFIX}velocity(s, y, p)", "zeta' from the momenta: the inverse of "
                      "the Legendre map, (k, m)"
                      + (" (the rotations' strains after the coordinates' derivatives)."
                         if d.rotations else "."), block, unpack,
                      before=[f"    v = numpy.empty(({kv}, y.shape[1]))"], after=["    return v"])

    def rotation_jacobian(self, names, unpack):
        """rhs_jac of a module with rotations: the partial derivatives with each frame R and
        body moment R^T m held, then the chain through them, df/dq += f_R dR/dq + f_mb
        d(R^T m)/dq and df/dm += f_mb R^T, by one product each (`runtime.chain`): far fewer
        numpy calls than the chain written out entry by entry."""
        n = self.n
        block = Block(names)
        before, chains, needs = self._partials(block, self.d.rhs, "jac")
        self.emit("", "", "def rhs_jac(s, y, p):",
                  *_docstring("df/dy, (n, n, m): with each frame R = R(q) and body moment "
                              "R^T m held, then through them (runtime.chain)."),
                  f"    jac = numpy.zeros(({n}, {n}, y.shape[1]))", *before,
                  *block.lines(unpack, needs), *chains, "    return jac")

    def _partials(self, block, exprs, target):
        """Add to ``block`` the derivatives of ``exprs`` (in the states, frames and body
        moments at the nodes) in the states, into ``target[i, j]``, with each frame and body
        moment held; return the lines that allocate their derivatives in the frames' entries
        and body moments, the lines that chain them in (`runtime.chain`), and the names
        those need."""
        d = self.d
        for i, e in enumerate(exprs):
            for j, x in enumerate(d.rows):
                de = sp.diff(e, x)
                if de != 0:
                    block.add(f"{target}[{i}, {j}]", de)
        before, chains, needs = [], [], []
        for j, r in enumerate(d.rotations):
            rows_r = [i for i, e in enumerate(exprs) if e.has(*r.node.entries)]
            rows_m = [i for i, e in enumerate(exprs) if e.has(*r.MB)]
            q = [d.row(x) for x in r.Q]
            m = [d.row(x) for x in r.Mr]
            if not rows_r and not rows_m:
                continue
            needs.append(f"F{j}")
            fr, fm = "None", "None"
            if rows_r:
                fr = f"fR{j}"
                before.append(f"    fR{j} = numpy.zeros(({len(rows_r)}, 3, 3, y.shape[1]))")
                for a, i in enumerate(rows_r):
                    for b in range(3):
                        for c in range(3):
                            de = sp.diff(exprs[i], r.node.R[b, c])
                            if de != 0:
                                block.add(f"fR{j}[{a}, {b}, {c}]", de)
            if rows_m:
                fm = f"fM{j}"
                before.append(f"    fM{j} = numpy.zeros(({len(rows_m)}, 3, y.shape[1]))")
                for a, i in enumerate(rows_m):
                    for c in range(3):
                        de = sp.diff(exprs[i], r.MB[c])
                        if de != 0:
                            block.add(f"fM{j}[{a}, {c}]", de)
            chains.append(f"    {PREFIX}runtime.chain({target}, F{j}, y[{self._rows(q)}], "
                          f"y[{self._rows(m)}], {q!r}, {m!r}, {rows_r!r}, {fr}, {rows_m!r}, "
                          f"{fm})  # {r.name}")
        return before, chains, needs

    def _remembered_velocity(self):
        """``velocity``, Newton's (``newton_velocity``) remembered for the last few (s, y, p)
        (`runtime.remembered`): rhs, rhs_jac, rhs_dp and the second variation are asked at
        the same points one after the other, and Newton's inverse is most of their cost."""
        self.emit("", "", f"def {PREFIX}velocity(s, y, p):",
                  *_docstring("The velocities (k, m) at (s, y, p): Newton's, remembered for the "
                              "last few arguments (read-only)."),
                  f"    return {PREFIX}runtime.remembered({PREFIX}newton_velocity, s, y, p)")

    def rotation_newton_system(self):
        """The system of a module with rotations whose density is not quadratic in the
        derivatives and strains: the velocities v (zeta' and the strains) from the momenta
        (m and each rotation's body moment R^T m) by Newton's method per point
        (`runtime.legendre_inverse`), the equations at (y, v), and their Jacobians by the
        implicit function theorem. With G(y, v) = dL/dv - (m, R^T m) = 0 defining v,
        dv/dy = -A^-1 dG/dy (A = d2L/dv2; dG/dy through z, R(q) and R^T m), so df/dy =
        (df/dy at v held) + (df/dv) dv/dy, and df/dp likewise with dv/dp = -A^-1 dG/dp."""
        d = self.d
        n, k, kv = self.n, self.k, self.kv
        vel = d.velocities
        # -- the Legendre map at given frames ----------------------------------------------
        names, unpack = self._params()
        names[d.S] = "s"
        for i, z in enumerate(d.Z):
            names[z] = f"z{i}"
        for i, v in enumerate(vel):
            names[v] = f"v{i}"
        rot_unpack = []
        for j, r in enumerate(d.rotations):
            for a in range(3):
                for b in range(3):
                    names[r.node.R[a, b]] = f"R{j}_{a}{b}"
                    rot_unpack.append((f"R{j}_{a}{b}", f"R{j}_{a}{b} = R[{j}][{a}, {b}]"))
        labels = self._velocity_labels()
        kernel_unpack = ([(f"z{i}", f"z{i} = z[{i}]  # {c}") for i, c in enumerate(d.coordinates)]
                         + [(f"v{i}", f"v{i} = v[{i}]  # {c}'") for i, c in enumerate(labels)]
                         + rot_unpack + unpack)
        block = Block(names)
        block.add("L", d.lagrangian)
        Lv = [sp.diff(d.lagrangian, v) for v in vel]
        for i, e in enumerate(Lv):
            block.add(f"Lv[{i}]", e)
            for j, w in enumerate(vel[i:], i):
                block.add(f"Lvv[{i}, {j}]", sp.diff(e, w))
        self.function(f"{PREFIX}legendre(s, z, v, R, p)", "L, dL/dv (kv, m), d2L/dv2 (kv, kv, "
                      "m) at the frames R (one (3, 3, m) per rotation): what the Legendre "
                      "inverse needs.", block, kernel_unpack,
                      before=[f"    Lv = numpy.empty(({kv}, v.shape[1]))",
                              f"    Lvv = numpy.empty(({kv}, {kv}, v.shape[1]))"],
                      after=[*_lower(kv), "    return L, Lv, Lvv"])
        frames = ", ".join(f"{PREFIX}runtime.frame(y[{self._rows([d.row(q) for q in r.Q])}])"
                           for r in d.rotations)
        bodies = ", ".join(
            f"{PREFIX}runtime.body(F[{j}], y[{self._rows([d.row(m) for m in r.Mr])}])"
            for j, r in enumerate(d.rotations))
        self._remembered_velocity()
        self.emit("", "", f"def {PREFIX}newton_velocity(s, y, p):",
                  *_docstring("zeta' and the strains from the momenta m and R^T m, by Newton's "
                              "method on L - (m, R^T m).v (runtime.legendre_inverse), (kv, m)."),
                  f"    F = [{frames}]",
                  f"    mom = numpy.concatenate((y[{self._rows(self.mrows)}], {bodies}))",
                  f"    return {PREFIX}runtime.legendre_inverse(lambda s_, z_, v_, p_: "
                  f"{PREFIX}legendre(s_, z_, v_, F, p_), s, y[{self._rows(self.zrows)}], mom, p"
                  f"{_far(Lv, vel)})")
        # -- the equations at (y, v) ------------------------------------------------------
        names, unpack = self._states(True)
        unpack = self._node_rotations(names, unpack)
        kinematics, after = set(), []
        for j, r in enumerate(d.rotations):
            rows = [d.row(q) for q in r.Q]
            kinematics |= set(rows)
            o = k + 3 * j
            after.append(f"    out[{self._rows(rows)}] = {PREFIX}runtime.quaternion_rate("
                         f"y[{self._rows(rows)}], v[{o}], v[{o + 1}], v[{o + 2}])  # {r.name}")
        block = Block(names)
        for i, e in enumerate(d.rhs):
            if i not in kinematics:
                block.add(f"out[{i}]", e)
        self.function("rhs(s, y, p)", "zeta' = V, m' = dL/dzeta, x' = g, q' = q (x) (0, u) / 2 "
                      "and m' = the torque D L for a rotation, at the velocities V (zeta' and "
                      "the strains) from Newton's Legendre inverse.", block, unpack,
                      before=[f"    v = {PREFIX}velocity(s, y, p)",
                              "    out = numpy.empty(y.shape)"],
                      after=[*after, "    return out"])
        self.alias("rhs")
        # G = dL/dv - (m, R^T m): the momentum's equation that defines v
        momenta = [*d.M, *(e for r in d.rotations for e in r.MB)]
        G = [Lv[a] - momenta[a] for a in range(kv)]
        block = Block(names)
        for i, e in enumerate(d.rhs):
            for a, v in enumerate(vel):
                de = sp.diff(e, v)
                if de != 0:
                    block.add(f"fv[{i}, {a}]", de)
        for a, e in enumerate(Lv):
            for b, v in enumerate(vel):
                block.add(f"A[{a}, {b}]", sp.diff(e, v))
        self.function(f"{PREFIX}vpartials(s, y, v, p)", "df/dv (n, kv, m) and A = d2L/dv2 "
                      "(kv, kv, m) at (y, v).", block, unpack,
                      before=["    m = y.shape[1]", f"    fv = numpy.zeros(({n}, {kv}, m))",
                              f"    A = numpy.zeros(({kv}, {kv}, m))"],
                      after=["    return fv, A"])
        block = Block(names)
        before, chains, needs = self._partials(block, [*d.rhs, *G], "jac")
        self.emit("", "", "def rhs_jac(s, y, p):",
                  *_docstring("df/dy by the implicit function theorem: the partial "
                              "derivatives at v held (through each frame R = R(q) and body "
                              "moment R^T m, runtime.chain), plus df/dv dv/dy with dv/dy = "
                              "-A^-1 dG/dy, G = dL/dv - (m, R^T m)."),
                  f"    v = {PREFIX}velocity(s, y, p)",
                  f"    jac = numpy.zeros(({n + kv}, {n}, y.shape[1]))", *before,
                  *block.lines(unpack, needs), *chains,
                  f"    fv, A = {PREFIX}vpartials(s, y, v, p)",
                  f"    dv = -{PREFIX}runtime._solve(A, jac[{n}:])",
                  f"    return jac[:{n}] + numpy.einsum('iam,ajm->ijm', fv, dv)")
        self._by_parameter(f"{PREFIX}dp(s, y, v, p, name)", "df/dp at v held (n, m) and dG/dp "
                           "(kv, m) for the parameter name.", [*d.rhs, *G], names, unpack,
                           f"    out = numpy.zeros(({n + kv}, y.shape[1]))", "out[{i}]")
        self.emit("", "", "def rhs_dp(s, y, p, name):",
                  *_docstring("df/dp[name] with dv/dp = -A^-1 dG/dp."),
                  f"    v = {PREFIX}velocity(s, y, p)",
                  f"    out = {PREFIX}dp(s, y, v, p, name)",
                  f"    fv, A = {PREFIX}vpartials(s, y, v, p)",
                  f"    dv = -{PREFIX}runtime._solve(A, out[{n}:])",
                  f"    return out[:{n}] + numpy.einsum('iam,am->im', fv, dv)")

    def newton_system(self):
        d = self.d
        k, nq = self.k, self.nq
        z_rows, m_rows = self._rows(self.zrows), self._rows(self.mrows)
        order = self.order
        names, unpack = self._kernel()
        block = Block(names)
        block.add("L", d.lagrangian)
        lv = [sp.diff(d.lagrangian, v) for v in d.V]
        for i, v in enumerate(d.V):
            block.add(f"Lv[{i}]", lv[i])
            for j, w in enumerate(d.V[i:], i):
                block.add(f"Lvv[{i}, {j}]", sp.diff(lv[i], w))
        self.function(f"{PREFIX}legendre(s, z, v, p)", "L, dL/dv (k, m), d2L/dv2 (k, k, m): "
                      "what the Legendre inverse needs.", block, unpack,
                      before=[f"    Lv = numpy.empty(({k}, z.shape[1]))",
                              f"    Lvv = numpy.empty(({k}, {k}, z.shape[1]))"],
                      after=[*_lower(k), "    return L, Lv, Lvv"])
        self._remembered_velocity()
        self.emit("", "", f"def {PREFIX}newton_velocity(s, y, p):",
                  *_docstring("zeta' from the momenta, by Newton's method on L - m.v "
                              '(runtime.legendre_inverse).'),
                  f"    return {PREFIX}runtime.legendre_inverse({PREFIX}legendre, s, "
                  f"y[{z_rows}], y[{m_rows}], p{_far(lv, d.V)})")
        block = Block(names)
        for j, g in enumerate(d.rates):
            block.add(f"g[{j}]", g)
            for i, z in enumerate(d.Z):
                block.add(f"gz[{j}, {i}]", sp.diff(g, z))
            for i, v in enumerate(d.V):
                block.add(f"gv[{j}, {i}]", sp.diff(g, v))
        self.function(f"{PREFIX}rates(s, z, v, p)", "The quadratures' rates g (nq, m) and "
                      "their derivatives in z and v (nq, k, m).", block, unpack,
                      before=[f"    g = numpy.empty(({nq}, z.shape[1]))",
                              f"    gz = numpy.empty(({nq}, {k}, z.shape[1]))",
                              f"    gv = numpy.empty(({nq}, {k}, z.shape[1]))"],
                      after=["    return g, gz, gv"])
        canonical = "numpy.concatenate((v, Lz, g))"
        self.emit("", "", "def rhs(s, y, p):",
                  *_docstring("zeta' = V(zeta, m), m' = dL/dzeta, x' = g."),
                  f"    v = {PREFIX}velocity(s, y, p)",
                  f"    z = y[{z_rows}]",
                  f"    _, Lz, _, _, _, _ = {PREFIX}density(s, z, v, p)",
                  f"    g, _, _ = {PREFIX}rates(s, z, v, p)",
                  f"    return {canonical}" if order is None else
                  f"    return {PREFIX}runtime.in_rows({canonical}, {order!r})",
                  "", "", f"{PREFIX}rhs = rhs  # what the derived ordinates use",
                  "", "",
                  "def rhs_jac(s, y, p):",
                  *_docstring('df/dy by the implicit function theorem: dv/dm = A^-1, dv/dzeta = '
                              '-A^-1 C (runtime.hamilton_jacobian).'),
                  f"    v = {PREFIX}velocity(s, y, p)",
                  f"    z = y[{z_rows}]",
                  f"    _, _, _, Lzz, Lvz, Lvv = {PREFIX}density(s, z, v, p)",
                  f"    _, gz, gv = {PREFIX}rates(s, z, v, p)",
                  f"    jac = {PREFIX}runtime.hamilton_jacobian(Lvv, Lvz, Lzz, gz, gv)",
                  "    return jac" if order is None else
                  f"    return {PREFIX}runtime.in_rows(jac, {order!r}, columns=True)")
        cases = []
        for q in d.parameters:
            p = d.P[q.name]
            exprs = [sp.diff(d.lagrangian, z, p) for z in d.Z] + \
                [sp.diff(d.lagrangian, v, p) for v in d.V] + [sp.diff(g, p) for g in d.rates]
            if any(e != 0 for e in exprs):
                cases.append((q.name, exprs))
        self.emit("", "", f"def {PREFIX}dp(s, z, v, p, name):",
                  *_docstring('d2L/dzeta dp, d2L/dv dp (k, m) and dg/dp (nq, m) for the parameter '
                              'name.'),
                  f"    Lzp = numpy.zeros(({k}, z.shape[1]))",
                  f"    Lvp = numpy.zeros(({k}, z.shape[1]))",
                  f"    gp = numpy.zeros(({nq}, z.shape[1]))")
        for c, (name, exprs) in enumerate(cases):
            block = Block(names, indent="        ")
            for i, e in enumerate(exprs):
                if e != 0:
                    target = (f"Lzp[{i}]" if i < k else f"Lvp[{i - k}]" if i < 2 * k
                              else f"gp[{i - 2 * k}]")
                    block.add(target, e)
            self.emit(f"    {'if' if c == 0 else 'elif'} name == {name!r}:",
                      *block.lines(unpack))
        dp = f"{PREFIX}runtime.hamilton_dp(Lvv, Lvz, gv, Lzp, Lvp, gp)"
        self.emit("    return Lzp, Lvp, gp", "", "",
                  "def rhs_dp(s, y, p, name):",
                  *_docstring('df/dp[name] with dv/dp = -A^-1 d2L/dv dp.'),
                  f"    v = {PREFIX}velocity(s, y, p)",
                  f"    z = y[{z_rows}]",
                  f"    _, _, _, _, Lvz, Lvv = {PREFIX}density(s, z, v, p)",
                  f"    _, _, gv = {PREFIX}rates(s, z, v, p)",
                  f"    Lzp, Lvp, gp = {PREFIX}dp(s, z, v, p, name)",
                  f"    return {dp}" if order is None else
                  f"    return {PREFIX}runtime.in_rows({dp}, {order!r})")

    def _by_parameter(self, signature, doc, exprs, names, unpack, init, target, ret="out",
                      frames=()):
        """A function dispatching on the parameter ``name``: the derivatives of ``exprs``
        in each parameter that enters them."""
        d = self.d
        self.emit("", "", f"def {signature}:", *_docstring(doc), init)
        first = True
        for q in d.parameters:
            p = d.P[q.name]
            block = Block(names, indent="        ", frames=frames)
            for i, e in enumerate(exprs):
                de = sp.diff(e, p)
                if de != 0:
                    block.add(target.format(i=i), de)
            if block.items:
                self.emit(f"    {'if' if first else 'elif'} name == {q.name!r}:",
                          *block.lines(unpack))
                first = False
        self.emit(f"    return {ret}")

    def boundary(self):
        d = self.d
        n, nbc = self.n, len(d.bc)
        names, unpack = self._ends()
        frames = self._end_frames(names)
        block = Block(names, frames=frames)
        for i, e in enumerate(d.bc):
            block.add(f"out[{i}]", e)
        self.function("bc(ya, yb, p)", "Essential values, natural conditions (-m(0) + "
                      "dB0/dzeta, m(1) + dB1/dzeta), quadratures' starts, constraints.",
                      block, unpack, before=[f"    out = numpy.empty({nbc})"],
                      after=["    return out"])
        block = Block(names, frames=frames)
        for i, e in enumerate(d.bc):
            for j in range(n):
                for arr, y in (("da", d.YA[j]), ("db", d.YB[j])):
                    de = _total(e, y, frames)
                    if de != 0:
                        block.add(f"{arr}[{i}, {j}]", de)
        self.function("bc_jac(ya, yb, p)", "dbc/dya, dbc/dyb, each (nbc, n).", block, unpack,
                      before=[f"    da = numpy.zeros(({nbc}, {n}))",
                              f"    db = numpy.zeros(({nbc}, {n}))"],
                      after=["    return da, db"])
        self._by_parameter("bc_dp(ya, yb, p, name)", "dbc/dp[name], (nbc,).", d.bc, names,
                           unpack, f"    out = numpy.zeros({nbc})", "out[{i}]", frames=frames)

    def kernels(self):
        """The density and end terms with their derivatives: the gradient flow's energy, and
        the Newton case's system (scalar coordinates)."""
        d = self.d
        k = self.k
        names, unpack = self._kernel()
        block = Block(names)
        L = d.lagrangian
        block.add("L", L)
        for i, z in enumerate(d.Z):
            block.add(f"Lz[{i}]", sp.diff(L, z))
        for i, v in enumerate(d.V):
            block.add(f"Lv[{i}]", sp.diff(L, v))
        for i, a in enumerate(d.Z):
            for j, b in enumerate(d.Z):
                block.add(f"Lzz[{i}, {j}]", sp.diff(L, a, b))
        for i, a in enumerate(d.V):
            for j, b in enumerate(d.Z):
                block.add(f"Lvz[{i}, {j}]", sp.diff(L, a, b))
        for i, a in enumerate(d.V):
            for j, b in enumerate(d.V):
                block.add(f"Lvv[{i}, {j}]", sp.diff(L, a, b))
        self.function(f"{PREFIX}density(s, z, v, p)", "The Lagrangian L (with the "
                      "multipliers' terms) at (z, v = z', s) and its first and second "
                      "derivatives.", block, unpack,
                      before=["    m = z.shape[1]", f"    Lz = numpy.empty(({k}, m))",
                              f"    Lv = numpy.empty(({k}, m))",
                              f"    Lzz = numpy.empty(({k}, {k}, m))",
                              f"    Lvz = numpy.empty(({k}, {k}, m))",
                              f"    Lvv = numpy.empty(({k}, {k}, m))"],
                      after=["    L = L + numpy.zeros(m)",
                             "    return L, Lz, Lv, Lzz, Lvz, Lvv"])
        names, unpack = self._params()
        for i, (a, b) in enumerate(zip(d.YA[:k], d.YB[:k])):
            names[d.Z[i]] = f"z{i}"
        unpack = [(f"z{i}", f"z{i} = z[{i}]  # {c}") for i, c in enumerate(d.coordinates)] \
            + unpack
        for end, B in ((0, d.ends["B0"]), (1, d.ends["B1"])):
            block = Block(names)
            block.add("B", B)
            for i, z in enumerate(d.Z):
                block.add(f"Bz[{i}]", sp.diff(B, z))
                for j, w in enumerate(d.Z):
                    block.add(f"Bzz[{i}, {j}]", sp.diff(B, z, w))
            self.function(f"{PREFIX}end{end}(z, p)", f"B{end} at the end values z (k,), its "
                          "gradient and Hessian" + (" (the quadratures' terms are in the "
                                                     "density)" if end else "") + ".",
                          block, unpack, before=[f"    Bz = numpy.empty({k})",
                                                 f"    Bzz = numpy.empty(({k}, {k}))"],
                          after=["    return float(B), Bz, Bzz"])
        self.emit("", "", f"def {PREFIX}ends(za, zb, p):",
                  *_docstring('B0 and B1, each (value, gradient, Hessian), at the end values.'),
                  f"    return {PREFIX}end0(za, p), {PREFIX}end1(zb, p)")
        names, unpack = self._params()
        block = Block(names)
        items = [(0, i, e) for i, e in d.ends["essential"][0].items()] + \
                [(1, i, e) for i, e in d.ends["essential"][1].items()]
        for end, i, e in items:
            block.add(None, e)
        block.add(None, d.ends["constant"])
        body = block.lines(unpack)
        values = block.printed
        at0 = ", ".join(f"{i}: {v}" for (end, i, _), v in zip(items, values) if end == 0)
        at1 = ", ".join(f"{i}: {v}" for (end, i, _), v in zip(items, values) if end == 1)
        self.emit("", "", f"def {PREFIX}essential(p):",
                  *_docstring("The essential end values {coordinate: value} at s = 0 and "
                              "s = 1, and the energy's constant (the quadratures' starts in "
                              "B1)."),
                  *body, f"    return {{{at0}}}, {{{at1}}}, float({values[-1]})")

    def frame_kernels(self):
        """The gradient flow's pieces for a module with rotations: the Lagrangian at the
        intervals' midpoints in the scalar coordinates, their derivatives, the frames' entries
        and the strains (each given), with its first derivatives; the end terms in the end
        values and frames, with theirs; the essential values and the clamps'
        quaternions (`frame_flow.frame_flow`)."""
        d = self.d
        k, nrot = self.k, len(d.rotations)
        names, unpack = self._params()
        names[d.S] = "s"
        for i, (z, v) in enumerate(zip(d.Z, d.V)):
            names[z], names[v] = f"z{i}", f"v{i}"
        rot_unpack = []
        for j, r in enumerate(d.rotations):
            for a in range(3):
                for b in range(3):
                    names[r.node.R[a, b]] = f"R{j}_{a}{b}"
                    rot_unpack.append((f"R{j}_{a}{b}", f"R{j}_{a}{b} = R[{j}, {a}, {b}]"))
            for c in range(3):
                names[r.U[c]] = f"u{j}_{c}"
                rot_unpack.append((f"u{j}_{c}", f"u{j}_{c} = U[{j}, {c}]  # {r.name}.u{c + 1}"))
        unpack = ([(f"z{i}", f"z{i} = z[{i}]  # {c}") for i, c in enumerate(d.coordinates)]
                  + [(f"v{i}", f"v{i} = v[{i}]  # {c}'") for i, c in enumerate(d.coordinates)]
                  + rot_unpack + unpack)
        block = Block(names)
        L = d.lagrangian
        block.add("L", L)
        for i, z in enumerate(d.Z):
            block.add(f"Lz[{i}]", sp.diff(L, z))
        for i, v in enumerate(d.V):
            block.add(f"Lv[{i}]", sp.diff(L, v))
        for j, r in enumerate(d.rotations):
            for a in range(3):
                for b in range(3):
                    de = sp.diff(L, r.node.R[a, b])
                    if de != 0:
                        block.add(f"LR[{j}, {a}, {b}]", de)
            for c in range(3):
                de = sp.diff(L, r.U[c])
                if de != 0:
                    block.add(f"LU[{j}, {c}]", de)
        self.function(f"{PREFIX}frame_density(s, z, v, R, U, p)", "The Lagrangian L (with "
                      "the multipliers' terms) at (z, v = z', the frames R (nrot, 3, 3, m), "
                      "their strains U (nrot, 3, m), s) and its derivatives in z, v, the "
                      "frames' entries and the strains.", block, unpack,
                      before=["    m = len(s)", f"    Lz = numpy.empty(({k}, m))",
                              f"    Lv = numpy.empty(({k}, m))",
                              f"    LR = numpy.zeros(({nrot}, 3, 3, m))",
                              f"    LU = numpy.zeros(({nrot}, 3, m))"],
                      after=["    L = L + numpy.zeros(m)", "    return L, Lz, Lv, LR, LU"])
        for end, B in ((0, d.ends["B0"]), (1, d.ends["B1"])):
            names, unpack = self._params()
            ends_unpack = [(f"z{i}", f"z{i} = z[{i}]  # {c}({end})")
                           for i, c in enumerate(d.coordinates)]
            for i, z in enumerate(d.Z):
                names[z] = f"z{i}"
            for j, r in enumerate(d.rotations):
                frame = r.start if end == 0 else r.end
                for a in range(3):
                    for b in range(3):
                        names[frame.R[a, b]] = f"R{j}_{a}{b}"
                        ends_unpack.append((f"R{j}_{a}{b}", f"R{j}_{a}{b} = R[{j}, {a}, {b}]"))
            block = Block(names)
            block.add("B", B)
            for i, z in enumerate(d.Z):
                block.add(f"Bz[{i}]", sp.diff(B, z))
            for j, r in enumerate(d.rotations):
                frame = r.start if end == 0 else r.end
                for a in range(3):
                    for b in range(3):
                        de = sp.diff(B, frame.R[a, b])
                        if de != 0:
                            block.add(f"BR[{j}, {a}, {b}]", de)
            self.function(f"{PREFIX}frame_end{end}(z, R, p)", f"B{end} at the end values z "
                          "(k,) and frames R (nrot, 3, 3), its derivatives in them"
                          + (" (the quadratures' terms are in the density)" if end else "")
                          + ".", block, ends_unpack + unpack,
                          before=[f"    Bz = numpy.zeros({k})",
                                  f"    BR = numpy.zeros(({nrot}, 3, 3))"],
                          after=["    return float(B), Bz, BR"])
        self.emit("", "", f"def {PREFIX}frame_ends(za, Ra, zb, Rb, p):",
                  *_docstring('B0 and B1, each (value, dB/dz, dB/dR), at the end values.'),
                  f"    return {PREFIX}frame_end0(za, Ra, p), {PREFIX}frame_end1(zb, Rb, p)")
        names, unpack = self._params()
        block = Block(names)
        items = [(0, i, e) for i, e in d.ends["essential"][0].items()] + \
                [(1, i, e) for i, e in d.ends["essential"][1].items()]
        for end, i, e in items:
            block.add(None, e)
        clamps = [(end, j, qc) for end in (0, 1) for j, qc in d.ends["clamps"][end].items()]
        for end, j, qc in clamps:
            for e in qc:
                block.add(None, e)
        block.add(None, d.ends["constant"])
        body = block.lines(unpack)
        values = block.printed
        at = [", ".join(f"{i}: {v}" for (e, i, _), v in zip(items, values) if e == end)
              for end in (0, 1)]
        rest = values[len(items):]
        quats = [[], []]
        for c, (end, j, _) in enumerate(clamps):
            quats[end].append(f"{j}: numpy.array(({', '.join(rest[4 * c:4 * c + 4])}), "
                              "dtype=float)")
        self.emit("", "", f"def {PREFIX}frame_essential(p):",
                  *_docstring("The scalar coordinates' essential end values {coordinate: "
                              "value} at s = 0 and s = 1, the energy's constant (the "
                              "quadratures' starts in B1), the clamps' quaternions {rotation: "
                              "q} at s = 0 and s = 1."),
                  *body, f"    return ({{{at[0]}}}, {{{at[1]}}}, float({values[-1]}), "
                  f"{{{', '.join(quats[0])}}}, {{{', '.join(quats[1])}}})")

    def tangent(self):
        """The perturbation (K, m) of a tangent g to the states at y: the scalar
        coordinates' rows, and each rotation's spatial turn 2 Im(g_q (x) conj(q)) / |q|^2
        (a symmetry's generator as the zero mode of the second variation)."""
        d = self.d
        lines = [f"    out = numpy.empty(({self.K}, y.shape[1]))"]
        for i, row in enumerate(self.zrows):
            lines.append(f"    out[{i}] = g[{row}]  # {d.coordinates[i]}")
        for r in d.rotations:
            rows = [d.row(q) for q in r.Q]
            lines.append(f"    out[{r.offset}:{r.offset + 3}] = {PREFIX}runtime.spatial_turn("
                         f"y[{self._rows(rows)}], g[{self._rows(rows)}])  # {r.name}")
        self.emit("", "", f"def {PREFIX}tangent(y, g):",
                  *_docstring("The perturbation of the states' tangent g at y: the "
                              "coordinates' rows, a rotation's spatial turn."),
                  *lines, "    return out")

    def second_variation(self):
        d = self.d
        k, K = self.k, self.K
        constraints = d.constraints
        uses_w = any(e.has(*d.W) for fld, _, _ in constraints for e in fld)
        if d.linear:
            names, unpack = self._states(False)
            before = []
        else:
            names, unpack = self._states(True)
            before = [f"    v = {PREFIX}velocity(s, y, p)"]
            if uses_w:
                for i, w in enumerate(d.W):
                    names[w] = f"w{i}"
                before += [f"    w = {PREFIX}runtime.acceleration({PREFIX}density, "
                           f"{PREFIX}lvs, s, y[{self._rows(self.zrows)}], v, p)"]
                unpack = [(f"w{i}", f"w{i} = w[{i}]") for i in range(k)] + unpack
        ends, end_unpack = self._solution_ends()
        names.update(ends)
        unpack = self._node_rotations(names, unpack)
        frames = self._end_frames(names)
        unpack = unpack + [u for u in end_unpack if u[0].startswith(("ya", "yb"))]
        if K > 1 or constraints:
            before += ["    m = y.shape[1]"]
        block = Block(names, frames=frames)

        def entry(name, i, j):
            return name if K == 1 else f"{name}{i}_{j}"

        for name, mat in (("A", d.A), ("B", d.B), ("C", d.C), ("E0", d.E0), ("E1", d.E1)):
            for i in range(K):
                for j in range(K):
                    block.add(entry(name, i, j), mat[i][j])
        for c, (fld, gv, dc) in enumerate(constraints):
            for i in range(K):
                block.add(f"g{c}_{i}", fld[i])
                block.add(f"d{c}_{i}", gv[i])
                if any(e != 0 for e in dc):
                    block.add(f"e{c}_{i}", dc[i])
        body = block.lines(unpack)
        args = []
        for name in ("A", "B", "C", "E0", "E1"):
            if K == 1:
                value = name
            else:
                rows = ", ".join("[" + ", ".join(entry(name, i, j) for j in range(K)) + "]"
                                 for i in range(K))
                value = f"{PREFIX}runtime.field([{rows}], m)"
            args.append(value)
        after = []
        cons = []
        for c, (_, _, dc) in enumerate(constraints):
            g = ", ".join(f"g{c}_{i}" for i in range(K))
            dv = ", ".join(f"d{c}_{i}" for i in range(K))
            after.append(f"    gv = {PREFIX}runtime.field([[{dv}]], m)[0]")
            cons.append(f"constraint{c}")
            d1 = f"{PREFIX}runtime.at_end(gv, -1)"
            if any(e != 0 for e in dc):     # x(1) = c(zeta(1)): -dc/dzeta(1) at s = 1
                d1 += (f" + {PREFIX}runtime.field([[{', '.join(f'e{c}_{i}' for i in range(K))}"
                       "]], m)[0]")
            after.append(f"    constraint{c} = Constraint({PREFIX}runtime.field([[{g}]], m)[0], "
                         f"{d1}, -{PREFIX}runtime.at_end(gv, 0))")
        parts = ""
        if d.parts:
            parts = f", parts={ {name: comps for name, comps in d.parts.items()}!r}"
        after.append(f"    return SecondVariation({args[0]}, {args[1]}, {args[2]}, E0={args[3]}, "
                     f"E1={args[4]}, fixed0={d.fixed0!r}, fixed1={d.fixed1!r}, "
                     f"constraints=[{', '.join(cons)}] + {PREFIX}runtime.zero_modes("
                     f"{PREFIX}symmetry, s, y, p, {PREFIX}tangent, Constraint){parts})")
        self.emit("", "", "def second_variation(s, y, p):",
                  *_docstring("The second variation at the solution y: A = d2L/dv2, C = "
                              "d2L/dv dz, B = d2L/dz2, E0 = d2B0/dz2, E1 = d2B1/dz2 "
                              + ("(a rotation's components by spatial turns w: A = R L_uu "
                                 "R^T, C = R G - [m]_x / 2, B = sym(D_i D_c L)) "
                                 if d.rotations else "")
                              + "(docs/energy.md)."),
                  *before, *body, *after)
        self.alias("second_variation")
        if uses_w and not d.linear:
            names, unpack = self._kernel()
            block = Block(names)
            for i, v in enumerate(d.V):
                block.add(f"out[{i}]", sp.diff(d.lagrangian, v, d.S))
            self.function(f"{PREFIX}lvs(s, z, v, p)", "d2L/dv ds, (k, m).", block, unpack,
                          before=[f"    out = numpy.empty(({k}, z.shape[1]))"],
                          after=["    return out"])

    def ordinates(self):
        d = self.d
        integrals = [o for o in d.ordinates if o["integrand"] != 0]
        names, unpack = self._states(True)
        unpack = self._node_rotations(names, unpack)
        block = Block(names)
        for i, o in enumerate(integrals):
            block.add(f"out[{i}]", o["sign"] * o["integrand"])
        q = len(integrals)
        if q:
            self.function(f"{PREFIX}integrands(s, y, v, p)", "The integrands of the "
                          "ordinates that are integrals at the states y and the velocities "
                          "v, (q, m).", block, unpack,
                          before=[f"    out = numpy.empty(({q}, y.shape[1]))"],
                          after=["    return out"])
            self.emit("", "", f"def {PREFIX}integrals(s, y, p):",
                      *_docstring("The integrals of the ordinates at the solution y "
                                  "(Simpson's rule on its Hermite cubics; one pass for all "
                                  "of them)."),
                      f"    return {PREFIX}runtime.integrals(s, y, p, {PREFIX}rhs, "
                      f"{PREFIX}velocity, {PREFIX}integrands)")
        names, unpack = self._solution_ends()
        frames = self._end_frames(names)
        entries = []
        for i, o in enumerate(d.ordinates):
            block = Block(names, frames=frames)
            block.add("value", o["sign"] * o["ends"])
            extra = []
            if o["integrand"] != 0:
                extra = [f"    value = value + {PREFIX}integrals(s, y, p)"
                         f"[{integrals.index(o)}]"]
            self.function(f"{PREFIX}ordinate{i}(s, y, p)", o["doc"], block, unpack,
                          after=[*extra, "    return float(value)"])
            entries.append(f"    Ordinate({o['name']!r}, {o['tex']!r}, {PREFIX}ordinate{i}, "
                           f"{o['parameter']!r}, {o['doc']!r}),")
        for name in d.parts:
            entries.append(f"    Ordinate({name!r}, {name!r}, {PREFIX}runtime.part_count("
                           f"{PREFIX}second_variation, {PREFIX}rhs, {name!r}, count_form), "
                           "None, "
                           f"{'the index of the part ' + name + ' of the second variation'!r}),")
        self.emit("", "", "ORDINATES = [", *entries, "]")


def generate(d: Derived) -> str:
    """The generated module's text."""
    return Module(d).text()
