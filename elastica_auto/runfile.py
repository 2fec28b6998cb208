"""TOML run files -> a validated plan of branches.

A run file (``runs/<name>.toml``)::

    description = "what this run reproduces"
    equation = "elastica_lever_arm"     # shipped module name, or path to a .py file
    start = "trivial"                   # or "FILE.h5:LABEL", or a selector (below), or a list
    # start = { file = "rotating_arm.h5", type = "UZ", where = { eps = 0.5, psi = "pi/2" } }
    #   every UZ label of the file at those parameter values (angles modulo their period), in
    #   label order, one per distinct equilibrium (distinct = false keeps periodic copies);
    #   index = 0 keeps only stable ones; limit = 1 takes the first
    switch = 2                          # optional: also follow the other branch, both ways,
                                        # at the first 2 BPs of each branch (AUTO's ISW=-1);
                                        # or a list of "FILE.h5:BPn" labels to switch at

    [parameters]                        # values; a list gives one set of branches per value
    eps = [0.25, 0.5]
    P = ["pi^2/4", "9*pi^2/4"]          # numbers or expressions in pi, e, sqrt, sin, cos, ...

    [continuation]
    parameter = "psi"                   # the continued parameter
    directions = "both"                 # "both", "+" or "-"
    bounds = ["-6*pi", "6*pi"]          # the branch ends (EP) where the parameter leaves these
    stop = ["LP4"]                      # optional: end at the 4th fold
    uz = [0, "pi/12"]                   # optional: user points (UZ)
    uz_period = "2*pi"                  # optional: UZ at every value + k * uz_period

    [options]                           # ContinuationOptions: ds, ds_min, ds_max, ntst, ...

Unknown keys, wrong types and names the equation module does not declare are errors
(:class:`RunFileError`, whose message names the file and the key). So is every value that is
not a finite number (TOML's ``nan`` and ``inf``, ``"1e400"``): a parameter without bounds is
unbounded by omitting ``bounds``, never by writing ``inf``.
"""

from __future__ import annotations

import ast
import itertools
import math
import operator
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

from .errors import RunFileError
from .events import UserValues
from .options import ContinuationOptions, OptionsError
from .problem import Problem, ProblemError, load_problem
from .stepper import Stops


_FUNCS = {"sqrt": math.sqrt, "sin": math.sin, "cos": math.cos, "tan": math.tan,
          "exp": math.exp, "log": math.log, "abs": abs}
_CONSTS = {"pi": math.pi, "e": math.e}
_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_UNOPS = {ast.USub: operator.neg, ast.UAdd: operator.pos}


def evaluate(text: str) -> float:
    """Evaluate an arithmetic expression such as ``"9*pi^2/4"`` (``^`` means power).

    Only numbers, the constants pi, e, the functions sqrt, sin, cos, tan, exp, log, abs and
    + - * / ** are allowed, and the value must be a finite real number; anything else raises
    ValueError.
    """
    def ev(node):
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id in _CONSTS:
            return _CONSTS[node.id]
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            return _BINOPS[type(node.op)](ev(node.left), ev(node.right))
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNOPS:
            return _UNOPS[type(node.op)](ev(node.operand))
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                and node.func.id in _FUNCS and len(node.args) == 1 and not node.keywords):
            return float(_FUNCS[node.func.id](ev(node.args[0])))
        raise ValueError(f"not allowed in an expression: {ast.dump(node)[:40]}")

    try:
        value = ev(ast.parse(str(text).replace("^", "**"), mode="eval"))
    except (SyntaxError, ValueError, ZeroDivisionError, OverflowError, TypeError) as exc:
        raise ValueError(f"cannot evaluate {text!r}: {exc}") from exc
    except (RecursionError, MemoryError) as exc:  # the parser's or ev's stack, nested too deep
        raise ValueError(f"cannot evaluate {str(text)[:20]!r}...: nested too deeply") from exc
    if isinstance(value, complex) or not math.isfinite(value):
        raise ValueError(f"{text!r} is not a finite real number")
    return float(value)


@dataclass(frozen=True)
class Start:
    """Where a branch starts: the module's exact solution or a label in a branch file."""

    kind: str          # "trivial", "label", or "switch" (the other branch at a BP label)
    file: Path | None = None
    label: str = ""

    def __str__(self):
        if self.kind == "trivial":
            return "trivial"
        where = f"{self.file.name}:{self.label}" if self.file is not None else self.label
        return f"switch at {where}" if self.kind == "switch" else where


@dataclass(frozen=True)
class BranchSpec:
    """One branch to compute: start, parameter values, direction."""

    start: Start
    params: dict
    direction: int


@dataclass
class Plan:
    """A validated run: the problem, the branches and everything that applies to all of them."""

    name: str
    path: Path
    text: str
    description: str
    problem: Problem
    parameter: str
    options: ContinuationOptions
    stops: Stops
    user_values: list[UserValues]
    branches: list[BranchSpec] = field(default_factory=list)
    varying: list[str] = field(default_factory=list)
    switch_count: int = 0

    @property
    def output_name(self) -> str:
        return f"{self.name}.h5"


_TOP = {"description", "equation", "start", "switch", "parameters", "continuation", "options"}
_SELECT = {"file", "type", "where", "index", "distinct", "limit"}
_CONT = {"parameter", "directions", "bounds", "stop", "uz", "uz_period"}
_DIRECTIONS = {"both": (1, -1), "+": (1,), "-": (-1,), "forward": (1,), "backward": (-1,)}


def load(path, out_dir: Path | None = None) -> Plan:
    """Read and validate a run file; restart files are looked up in ``out_dir`` first."""
    path = Path(path)
    where = str(path)

    def fail(key, msg):
        raise RunFileError(f"{where}: {key}: {msg}")

    try:
        text = path.read_text(encoding="utf-8")  # TOML is UTF-8, whatever the locale
    except OSError as exc:
        raise RunFileError(f"{where}: cannot read ({exc.strerror})") from exc
    except UnicodeDecodeError as exc:
        raise RunFileError(f"{where}: not UTF-8 text (byte {exc.start}); "
                           "save the run file as UTF-8") from exc
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RunFileError(f"{where}: not valid TOML ({exc})") from exc

    for key in doc:
        if key not in _TOP:
            fail(key, f"unknown key; expected one of {sorted(_TOP)}")

    def number(key, v):
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            fail(key, f"expected a number or an expression string, got {v!r}")
        try:
            value = evaluate(v) if isinstance(v, str) else float(v)
        except ValueError as exc:
            fail(key, str(exc))
        if not math.isfinite(value):  # TOML's own nan and inf
            fail(key, f"expected a finite number, got {v!r}")
        return value

    def string(key, v):
        if not isinstance(v, str):
            fail(key, f"expected a string, got {v!r}")
        return v

    def table(key):
        v = doc.get(key, {})
        if not isinstance(v, dict):
            fail(key, f"expected a table [{key}], got {type(v).__name__}")
        return v

    description = string("description", doc.get("description", ""))
    if "equation" not in doc:
        fail("equation", "missing; name a module in equations/ or a .py file")
    try:
        problem = load_problem(string("equation", doc["equation"]), base_dir=path.parent)
    except ProblemError as exc:
        fail("equation", str(exc))

    cont = table("continuation")
    for key in cont:
        if key not in _CONT:
            fail(f"[continuation] {key}", f"unknown key; expected one of {sorted(_CONT)}")
    if "parameter" not in cont:
        fail("[continuation] parameter", "missing; name the continued parameter")
    parameter = string("[continuation] parameter", cont["parameter"])
    if parameter not in problem.parameters:
        fail("[continuation] parameter", f"unknown parameter {parameter!r}; "
             f"{problem.source} declares {', '.join(problem.parameter_names)}")

    directions = cont.get("directions", "both")
    if not isinstance(directions, str) or directions not in _DIRECTIONS:
        fail("[continuation] directions", f"expected one of {sorted(_DIRECTIONS)}, got {directions!r}")

    lower, upper = -math.inf, math.inf
    if "bounds" in cont:
        b = cont["bounds"]
        if not isinstance(b, list) or len(b) != 2:
            fail("[continuation] bounds", f"expected [lower, upper], got {b!r}")
        lower, upper = (number("[continuation] bounds", v) for v in b)
        if not lower < upper:
            fail("[continuation] bounds", f"need lower < upper, got {lower:g}, {upper:g}")
    at_fold = None
    stop = cont.get("stop", [])
    if not isinstance(stop, list):
        fail("[continuation] stop", f"expected a list such as [\"LP4\"], got {stop!r}")
    for item in stop:
        # isdigit() alone also accepts "²" and "٣"; only ASCII digits are a count
        if not (isinstance(item, str) and item.startswith("LP") and item[2:].isascii()
                and item[2:].isdigit() and int(item[2:]) > 0):
            fail("[continuation] stop", f"expected entries like \"LP4\", got {item!r}")
        at_fold = min(int(item[2:]), at_fold or math.inf)
    user_values = []
    if "uz" in cont:
        uz = cont["uz"]
        if not isinstance(uz, list):
            fail("[continuation] uz", f"expected a list of values, got {uz!r}")
        period = None
        if "uz_period" in cont:
            period = number("[continuation] uz_period", cont["uz_period"])
            if not period > 0:
                fail("[continuation] uz_period", f"must be positive, got {period:g}")
        user_values.append(UserValues(tuple(number("[continuation] uz", v) for v in uz), period))
    elif "uz_period" in cont:
        fail("[continuation] uz_period", "given without uz")

    opts = table("options")
    known = {f.name: f.type for f in fields(ContinuationOptions)}
    values = {}
    for key, v in opts.items():
        if key not in known:
            fail(f"[options] {key}", f"unknown option; expected one of {sorted(known)}")
        if key in ("max_points", "ntst", "max_nodes"):
            if isinstance(v, bool) or not isinstance(v, int):
                fail(f"[options] {key}", f"expected an integer, got {v!r}")
            values[key] = v
        elif key == "corrector":
            values[key] = string(f"[options] {key}", v)
        else:
            values[key] = number(f"[options] {key}", v)
    try:
        options = ContinuationOptions(**values)
    except OptionsError as exc:
        fail("[options]", str(exc))

    params = table("parameters")
    grid = {}
    for key, v in params.items():
        if key not in problem.parameters:
            fail(f"[parameters] {key}", f"unknown parameter; {problem.source} declares "
                 f"{', '.join(problem.parameter_names)}")
        vals = v if isinstance(v, list) else [v]
        if not vals:
            fail(f"[parameters] {key}", "empty list")
        grid[key] = [number(f"[parameters] {key}", x) for x in vals]

    from .store import BranchFile, StoreError

    def branch_file(key, fname):
        candidates = [Path(fname)] if Path(fname).is_absolute() else (
            ([out_dir / fname] if out_dir is not None else []) + [path.parent / fname, Path(fname)])
        file = next((c for c in candidates if c.is_file()), None)
        if file is None:
            folders = ", ".join(dict.fromkeys(str(c.parent) for c in candidates))
            fail(key, f"restart file {fname!r} not found (looked in {folders}); "
                 "run the run that writes it first")
        try:
            bf = BranchFile(file)
        except StoreError as exc:
            fail(key, str(exc))
        if Path(bf.equation).stem != problem.name:
            fail(key, f"{fname} was computed with {bf.equation!r}, not {problem.source!r}")
        return file, bf

    def file_label(key, s):
        if ":" not in s:
            fail(key, f"expected \"trivial\" or \"FILE.h5:LABEL\", got {s!r}")
        fname, label = s.rsplit(":", 1)
        file, bf = branch_file(key, fname)
        try:
            bf.label(label)
        except StoreError as exc:
            fail(key, str(exc))
        return file, label

    seen = []  # (parameters, ordinates) of the equilibria selected so far, by any selector

    def same_equilibrium(params, ords, other):
        """Equal parameters (angles modulo their period) and equal ordinates: the ordinates
        are physical, so periodic copies of one equilibrium have the same ones."""
        p2, o2 = other
        for q, v in params.items():
            d = v - p2[q]
            T = problem.parameters[q].period
            if T:
                d = math.remainder(d, T)
            if abs(d) > 1e-7 * (1 + abs(v)):
                return False
        return all(abs(a - b) <= 1e-5 * (1 + abs(a)) for a, b in zip(ords, o2))

    def selected(key, sel):
        """Labels of one type in a file whose parameters match ``where`` (periodic parameters
        modulo their period) and, if given, whose stability index is ``index``, in label
        order; with ``distinct``, one per equilibrium (also across selectors: periodic copies
        and the same equilibrium reached by two selectors count once); at most ``limit``."""
        for k in sel:
            if k not in _SELECT:
                fail(f"{key}.{k}", f"unknown key; expected one of {sorted(_SELECT)}")
        if "file" not in sel:
            fail(key, "a start selector needs file = \"FILE.h5\"")
        file, bf = branch_file(f"{key}.file", string(f"{key}.file", sel["file"]))
        kind = string(f"{key}.type", sel.get("type", "UZ"))
        where = sel.get("where", {})
        if not isinstance(where, dict):
            fail(f"{key}.where", f"expected a table of parameter values, got {where!r}")
        want = {}
        for q, v in where.items():
            if q not in problem.parameters:
                fail(f"{key}.where.{q}", f"unknown parameter; {problem.source} declares "
                     f"{', '.join(problem.parameter_names)}")
            want[q] = number(f"{key}.where.{q}", v)
        index = sel.get("index")
        if index is not None and (isinstance(index, bool) or not isinstance(index, int)):
            fail(f"{key}.index", f"expected an integer stability index, got {index!r}")
        distinct = sel.get("distinct", True)
        if not isinstance(distinct, bool):
            fail(f"{key}.distinct", f"expected true or false, got {distinct!r}")
        limit = sel.get("limit")
        if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int)
                                  or limit < 1):
            fail(f"{key}.limit", f"expected a positive integer, got {limit!r}")
        names = sorted((n for n in bf.labels if n[:2] == kind), key=lambda n: int(n[2:]))
        out = []
        for n in names:
            br, pt = bf.labels[n]
            cols = bf.branches[br - 1].columns
            ok = True
            for q, v in want.items():
                d = cols[q][pt - 1] - v
                T = problem.parameters[q].period
                if T:
                    d = math.remainder(d, T)
                ok &= abs(d) <= 1e-9 * (1 + abs(v))
            if not ok or (index is not None and cols["index"][pt - 1] != index):
                continue
            if distinct:
                params = {q: cols[q][pt - 1] for q in problem.parameter_names}
                ords = [cols[o][pt - 1] for o in problem.ordinate_names]
                if any(same_equilibrium(params, ords, other) for other in seen):
                    continue
                seen.append((params, ords))
            out.append(Start("label", file, n))
            if limit is not None and len(out) == limit:
                break
        if not out:
            fail(key, f"no {kind} label of {file.name} matches {where}")
        return out

    parsed = []
    switch = doc.get("switch", [])
    switch_count = 0
    if isinstance(switch, int) and not isinstance(switch, bool):
        if switch < 0:
            fail("switch", f"expected a count >= 0 or a list of \"FILE.h5:BPn\", got {switch}")
        switch_count = switch
    elif isinstance(switch, list):
        for item in switch:
            file, label = file_label("switch", string("switch", item))
            if not label.startswith("BP"):
                fail("switch", f"{item!r}: branch switching needs a BP label")
            parsed.append(Start("switch", file, label))
    else:
        fail("switch", f"expected a count or a list of \"FILE.h5:BPn\", got {switch!r}")
    starts = doc.get("start", [] if parsed else "trivial")
    starts = starts if isinstance(starts, list) else [starts]
    if not starts and not parsed:
        fail("start", "empty list")
    for s in starts:
        if isinstance(s, dict):
            parsed.extend(selected("start", s))
            continue
        s = string("start", s)
        if s == "trivial":
            parsed.append(Start("trivial"))
        else:
            parsed.append(Start("label", *file_label("start", s)))

    plan = Plan(name=path.stem, path=path, text=text, description=description, problem=problem,
                parameter=parameter, options=options, stops=Stops(lower, upper, at_fold),
                user_values=user_values, varying=[k for k, v in grid.items() if len(v) > 1],
                switch_count=switch_count)
    switches = [st for st in parsed if st.kind == "switch"]
    others = [st for st in parsed if st.kind != "switch"]
    if switches and grid and not others:
        fail("switch", "a branch switched at a stored BP has that point's parameters; "
             "remove [parameters]")
    for start in switches:  # both directions of the other branch, at the BP's parameters
        for d in (1, -1):
            plan.branches.append(BranchSpec(start, {}, d))
    keys = list(grid)
    for combo in itertools.product(*(grid[k] for k in keys)):
        for start in others:
            for d in _DIRECTIONS[directions]:
                plan.branches.append(BranchSpec(start, dict(zip(keys, combo)), d))
    return plan
