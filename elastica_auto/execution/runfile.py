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
    switch_depth = 2                    # optional (default 1): also switch at the BPs of
                                        # the switched branches (with switch = N)

    [parameters]                        # values; a list gives one set of branches per value
    eps = [0.25, 0.5]
    P = ["pi^2/4", "9*pi^2/4"]          # numbers or expressions in pi, e, sqrt, sin, cos, ...

    [continuation]
    parameter = "psi"                   # the continued parameter; or ["psi", "eps"]: the
                                        # fold (or branch-point) curves through LP (BP)
                                        # starts, psi solved for, eps continued
    directions = "both"                 # "both", "+" or "-"
    bounds = ["-6*pi", "6*pi"]          # the branch ends (EP) where the parameter leaves these
    stop = ["LP4", "u_max > 100"]       # optional: end at the 4th fold, or where an ordinate
                                        # (or a free parameter) passes a value
    free = ["mu"]                       # optional: parameters solved for (the module's FREE)
    uz = [0, "pi/12"]                   # optional: user points (UZ)
    uz_period = "2*pi"                  # optional: UZ at every value + k * uz_period

    [options]                           # ContinuationOptions: ds, ds_min, ds_max, ntst, ...

Unknown keys, wrong types and names the equation module does not declare are errors
(:class:`RunFileError`, whose message names the file and the key). So is every value that is
not a finite number (TOML's ``nan`` and ``inf``, ``"1e400"``): a parameter without bounds is
unbounded by omitting ``bounds``, never by writing ``inf``.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import fields
from pathlib import Path
from typing import Sequence

from ..core import labels
from ..core.errors import PlanError, RunFileError, StoreError
from ..core.expressions import evaluate
from ..core.options import DETECTABLE, NCOL_AUTO, ContinuationOptions
from .plan import MAX_BRANCHES, BranchSpec, Plan, Request, Start, Switch, make_plan
from ..model.problem import Problem, ProblemError, load_problem
from ..storage.store import BranchFile, StoredLabel

__all__ = ["load", "evaluate", "Plan", "BranchSpec", "Start", "RunFileError"]


#: The keys of a run file (docs/run-files.md, promised by docs/api.md): at the top, of a
#: start selector, and of ``[continuation]``; ``[options]`` takes `ContinuationOptions`'s
#: fields.
TOP_KEYS = {"description", "equation", "start", "switch", "switch_depth", "parameters",
        "continuation", "options", "execution"}
SELECTOR_KEYS = {"file", "type", "where", "index", "distinct", "limit"}
CONTINUATION_KEYS = {"parameter", "directions", "bounds", "stop", "events", "uz", "uz_period",
                     "free", "map", "landing", "damping", "damping_folds"}
_INTEGER_OPTIONS = ("max_points", "ntst", "max_nodes", "ncol")


def restart_files(doc: dict) -> list[str]:
    """The branch files a parsed run file's ``start`` and ``switch`` read, as written there."""
    return sorted({ref.split(":")[0] if isinstance(ref, str) else ref.get("file", "")
                   for key in ("start", "switch")
                   for ref in (doc.get(key) if isinstance(doc.get(key), list)
                               else [doc.get(key)])
                   if isinstance(ref, dict) or (isinstance(ref, str) and ":" in ref)})


def load(path, out_dir: Path | None = None, overrides: Sequence[str] = (),
         restart: str | None = None) -> Plan:
    """Read and validate a run file; restart files are looked up in ``out_dir`` first.

    Each table is read into the arguments of :func:`elastica_auto.continuation` (TOML types
    and expressions checked here); :func:`~elastica_auto.execution.plan.make_plan` checks their
    meaning, as for a call from Python, and its errors are reported under the run-file key.

    ``overrides`` are the command line's ``--set NAME=VALUE`` (:func:`apply_overrides`), and
    ``restart`` its ``--from FILE.h5:LABEL``, which replaces ``start``, ``switch`` and
    ``[parameters]`` (the label's parameters hold, except those given with ``--set``).
    Both are applied to the parsed file before it is checked, so they are checked exactly as
    the file's own values, and recorded as comments in the run file text stored with the
    branches.
    """
    path = Path(path)
    doc = Document(path, out_dir)
    apply_overrides(doc, overrides, restart)
    problem = doc.equation()
    parameter, cont = doc.continuation(problem)
    options = doc.options()
    params = doc.parameters()
    starts, switch = doc.starts(problem)
    try:
        plan = make_plan(problem, starts, parameter,
                         Request(params=params, switch=switch,
                                 switch_depth=doc.doc.get("switch_depth", 1), **cont), options)
    except PlanError as exc:
        raise RunFileError(f"{path}: {_toml_key(exc.key)}: {exc.detail}") from None
    plan.name, plan.path, plan.text = path.stem, path, doc.text
    plan.scheduler, plan.worker_timeout = doc.execution()
    doc.string("description", doc.doc.get("description", ""))  # for the reader only: checked
    return plan


def _toml_key(key: str) -> str:
    """The run-file key of an argument of ``continuation()``."""
    if key in CONTINUATION_KEYS:
        return f"[continuation] {key}"
    if key.startswith("params"):
        return f"[parameters] {key[len('params.'):]}".rstrip()
    return "[options]" if key == "options" else key


def _toml(value) -> str:
    """``value`` as a run file spells it (``true``, ``"x"``, ``[1, 2]``, ``{ a = 1 }``), for
    messages about what a user wrote: Python's spelling (``True``, ``'x'``) is not theirs."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }"
    return repr(value)


def apply_overrides(doc: Document, overrides: Sequence[str], restart: str | None):
    """``NAME=VALUE`` into the table that has NAME: ``[options]`` for an option,
    ``[parameters]`` for a parameter of the module, ``[continuation]`` for one of its keys,
    or the one named (``options.ds_max=0.3``). VALUE is read as TOML (``0.3``,
    ``[0.25, 0.5]``, ``"pi/2"``) or else taken as a string (``pi/2``, ``both``)."""
    tables = {"options": {f.name for f in fields(ContinuationOptions)},
              "continuation": CONTINUATION_KEYS, "parameters": None}
    notes = []
    if restart is not None:
        fname, colon, label = restart.rpartition(":")
        if not colon or not fname or not label:
            raise RunFileError(f"--from {restart}: expected FILE.h5:LABEL")
        if Path(fname).is_file():  # typed at the command line: relative to here first
            restart = f"{Path(fname).resolve()}:{label}"
        doc.doc["start"] = restart
        doc.doc.pop("switch", None)
        doc.doc.pop("switch_depth", None)
        doc.doc.pop("parameters", None)  # the label's own; --set may change them
        notes.append(f"--from {restart}")
    for item in overrides:
        if item and item.splitlines() != [item]:  # TOML would read the lines after the first
            raise RunFileError(f"--set {item!r}: a value cannot span lines; give each "
                               "setting its own --set")
        name, eq, text = item.partition("=")
        name = name.strip()
        if not eq or not name:
            raise RunFileError(f"--set {item}: expected NAME=VALUE")
        try:
            value = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        table, _, key = name.rpartition(".")
        if table:
            if table not in tables:
                raise RunFileError(f"--set {item}: no table [{table}]; expected "
                                   f"{', '.join(tables)}")
        else:
            params = doc.parameter_names()
            owners = [t for t, keys in tables.items()
                      if key in (params if keys is None else keys)]
            if len(owners) > 1:
                raise RunFileError(f"--set {item}: {key!r} is ambiguous; write TABLE.{key} "
                                   f"with TABLE one of {', '.join(owners)}")
            if not owners:
                raise RunFileError(f"--set {item}: {_not_settable(key, tables, params)}")
            table = owners[0]
        section = doc.doc.setdefault(table, {})
        if not isinstance(section, dict):
            raise RunFileError(f"{doc.path}: {table}: expected a table [{table}]")
        section[key] = value
        notes.append(f"--set {table}.{key}={text.strip()}")
    if notes:
        doc.text += "\n# command line:\n" + "".join(f"#   {_comment(n)}\n" for n in notes)


def _not_settable(key: str, tables: dict, params) -> str:
    """Why ``--set KEY=...`` names nothing it can set, and what to write instead: a key at
    the top of the run file (``start``, ``switch``, ...) is in no table, and a typo gets the
    names it is closest to (case aside: ``Eps`` is ``eps``)."""
    if key in TOP_KEYS:
        instead = ", or give --from FILE.h5:LABEL" if key == "start" else ""
        return (f"{key!r} is a key at the top of the run file, which --set does not change: "
                f"edit the run file{instead}; --set changes an option, a parameter or a "
                "[continuation] key")
    names = sorted({*params, *(k for keys in tables.values() if keys for k in keys)})
    lower = {n.lower(): n for n in names}
    close = ([lower[key.lower()]] if key.lower() in lower
             else difflib.get_close_matches(key, names, n=3, cutoff=0.75))
    meant = f"; did you mean {' or '.join(close)}?" if close else ""
    return f"{key!r} is not an option, parameter or [continuation] key{meant}"


def _comment(text: str) -> str:
    """``text`` for one comment line of the stored run file: each character that is not
    printable written as its escape (``\\n``), since a line break would end the comment and
    make the rest live TOML, and TOML allows no other control character in a comment."""
    return "".join(c if c.isprintable() or c == "\t" else c.encode("unicode_escape").decode()
                   for c in text)


class Document:
    """A run file's parsed TOML, with checks that name the file and the key."""

    def __init__(self, path: Path, out_dir: Path | None):
        self.path, self.out_dir = path, out_dir
        try:
            self.text = path.read_text(encoding="utf-8")  # TOML is UTF-8, whatever the locale
        except OSError as exc:
            raise RunFileError(f"{path}: cannot read ({exc.strerror})") from exc
        except UnicodeDecodeError as exc:
            raise RunFileError(f"{path}: not UTF-8 text (byte {exc.start}); "
                               "save the run file as UTF-8") from exc
        # A byte-order mark says only that the file is UTF-8 (some Windows editors write
        # one), which TOML takes for a stray character: dropped, here and in the stored text.
        self.text = self.text.removeprefix("\ufeff")
        try:
            self.doc = tomllib.loads(self.text)
        except tomllib.TOMLDecodeError as exc:
            raise RunFileError(f"{path}: not valid TOML ({exc})") from exc
        for key in self.doc:
            if key not in TOP_KEYS:
                self.fail(key, f"unknown key; expected one of {sorted(TOP_KEYS)}")
        self.seen = []  # (parameters, ordinates) of the equilibria selected so far
        self._problem: Problem | None = None
        self._branch_files: dict[Path, BranchFile] = {}  # by resolved path: each opened once

    def fail(self, key, msg):
        raise RunFileError(f"{self.path}: {key}: {msg}")

    def number(self, key, v) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            self.fail(key, f"expected a number or an expression string, got {_toml(v)}")
        try:
            value = evaluate(v) if isinstance(v, str) else float(v)
        except ValueError as exc:
            self.fail(key, str(exc))
        if not math.isfinite(value):  # TOML's own nan and inf
            self.fail(key, f"expected a finite number, got {_toml(v)}")
        return value

    def string(self, key, v) -> str:
        if not isinstance(v, str):
            self.fail(key, f"expected a string, got {_toml(v)}")
        return v

    def table(self, key) -> dict:
        v = self.doc.get(key, {})
        if not isinstance(v, dict):
            self.fail(key, f"expected a table [{key}], got {type(v).__name__}")
        return v

    def parameter_names(self) -> list[str]:
        """The module's parameters, or none if the module cannot be loaded (the error is
        reported when the file is checked)."""
        try:
            return self.equation().parameter_names
        except RunFileError:
            return []

    def equation(self) -> Problem:
        if "equation" not in self.doc:
            self.fail("equation", "missing; name a module in equations/ or a .py file")
        if self._problem is None:
            try:
                self._problem = load_problem(self.string("equation", self.doc["equation"]),
                                             base_dir=self.path.parent)
            except ProblemError as exc:
                self.fail("equation", str(exc))
        return self._problem

    def continuation(self, problem: Problem) -> tuple[str | list[str], dict]:
        """``[continuation]``: the parameter, and the rest as keyword arguments of
        :class:`~elastica_auto.execution.plan.Request` (directions, bounds, stop, uz, ...)."""
        cont = self.table("continuation")
        for key in cont:
            if key not in CONTINUATION_KEYS:
                self.fail(f"[continuation] {key}",
                          f"unknown key; expected one of {sorted(CONTINUATION_KEYS)}")
        if "parameter" not in cont:
            self.fail("[continuation] parameter", "missing; name the continued parameter")
        parameter = cont["parameter"]
        if isinstance(parameter, list):  # a fold or branch-point curve: [solved, continued]
            parameter = [self.string("[continuation] parameter", q) for q in parameter]
        else:
            parameter = self.string("[continuation] parameter", parameter)
        out = {"directions": cont.get("directions", "both")}
        if "bounds" in cont:
            b = cont["bounds"]
            if not isinstance(b, list) or len(b) != 2:
                self.fail("[continuation] bounds", f"expected [lower, upper], got {_toml(b)}")
            out["bounds"] = [self.number("[continuation] bounds", v) for v in b]
        for key in ("stop", "events", "uz", "free"):
            if key in cont:
                if not isinstance(cont[key], list):
                    example = {"stop": "[\"LP4\"]", "events": "[\"m0 = 0\"]",
                               "uz": "of values", "free": "of parameter names"}[key]
                    self.fail(f"[continuation] {key}",
                              f"expected a list {example}, got {_toml(cont[key])}")
                out[key] = cont[key]
        out["uz"] = [self.number("[continuation] uz", v) for v in out.get("uz", [])]
        if "uz_period" in cont:
            out["uz_period"] = self.number("[continuation] uz_period", cont["uz_period"])
        if "map" in cont:
            if not isinstance(cont["map"], bool):
                self.fail("[continuation] map", f"expected true or false, got {_toml(cont['map'])}")
            out["map"] = cont["map"]
        if "landing" in cont:
            if not isinstance(cont["landing"], bool):
                self.fail("[continuation] landing",
                          f"expected true or false, got {_toml(cont['landing'])}")
            out["landing"] = cont["landing"]
        if "damping" in cont:
            if not isinstance(cont["damping"], list):
                self.fail("[continuation] damping",
                          f"expected a list of damping values, got {_toml(cont['damping'])}")
            out["damping"] = [self.number("[continuation] damping", v) for v in cont["damping"]]
        if "damping_folds" in cont:
            folds = cont["damping_folds"]
            if not isinstance(folds, list):
                self.fail("[continuation] damping_folds",
                          f"expected a list of fold labels such as [\"LP3\"], got {_toml(folds)}")
            out["damping_folds"] = [self.string("[continuation] damping_folds", f) for f in folds]
        return parameter, out

    def execution(self) -> tuple[str | None, float | None]:
        """``[execution]``: ``scheduler``, the address of a Dask scheduler to compute on (not
        empty: an empty address would silently mean this machine), and ``worker_timeout``,
        the seconds its cluster may have no worker before the run ends (a positive number);
        None for each not given."""
        table = self.table("execution")
        for key in table:
            if key not in ("scheduler", "worker_timeout"):
                self.fail(f"[execution] {key}",
                          "unknown key; expected 'scheduler' or 'worker_timeout'")
        scheduler = timeout = None
        if "scheduler" in table:
            scheduler = self.string("[execution] scheduler", table["scheduler"])
            if not scheduler.strip():
                self.fail("[execution] scheduler", "an empty address; give tcp://HOST:PORT, "
                          "or leave the key out to compute on this machine")
        if "worker_timeout" in table:
            timeout = self.number("[execution] worker_timeout", table["worker_timeout"])
            if timeout <= 0:
                self.fail("[execution] worker_timeout",
                          f"expected a positive number of seconds, got {timeout:g}")
        return scheduler, timeout

    def options(self) -> dict:
        """``[options]``: numbers (or expressions), integers (``ncol`` also ``"auto"``), the
        corrector's name,
        ``mirror`` (true or false) and ``detect`` (a table of true or false)."""
        known = {f.name for f in fields(ContinuationOptions)}
        values = {}
        for key, v in self.table("options").items():
            where = f"[options] {key}"
            if key not in known:
                self.fail(where, f"unknown option; expected one of {sorted(known)}")
            if key == "ncol" and v == NCOL_AUTO:
                values[key] = v
            elif key in _INTEGER_OPTIONS:
                if isinstance(v, bool) or not isinstance(v, int):
                    self.fail(where, "expected an integer" + (f' or "{NCOL_AUTO}"'
                              if key == "ncol" else "") + f", got {_toml(v)}")
                values[key] = v
            elif key == "corrector":
                values[key] = self.string(where, v)
            elif key == "mirror":
                if not isinstance(v, bool):
                    self.fail(where, f"expected true or false, got {_toml(v)}")
                values[key] = v
            elif key == "detect":
                values[key] = self.detect(where, v)
            else:
                values[key] = self.number(where, v)
        return values

    def detect(self, where: str, v) -> dict:
        """``detect = { LP = false, BP = false }``: the kinds of special point looked for
        (`elastica_auto.core.options.DETECTABLE`), true or false each."""
        if not isinstance(v, dict):
            self.fail(where, f"expected a table such as {{ LP = false }}, got {_toml(v)}")
        for kind, on in v.items():
            if kind not in DETECTABLE:
                self.fail(f"{where}.{kind}", f"unknown kind; expected one of "
                          f"{', '.join(DETECTABLE)}")
            if not isinstance(on, bool):
                self.fail(f"{where}.{kind}", f"expected true or false, got {_toml(on)}")
        return dict(v)

    def parameters(self) -> dict[str, list[float]]:
        """``[parameters]``: a value, a list of values or a range per parameter."""
        grid = {}
        for key, v in self.table("parameters").items():
            where = f"[parameters] {key}"
            if isinstance(v, dict):
                grid[key] = self.span(where, v)
            else:
                vals = v if isinstance(v, list) else [v]
                grid[key] = [self.number(where, x) for x in vals]
        return grid

    def span(self, where: str, v: dict) -> list[float]:
        """``{ from = A, to = B, num = N }``: N equally spaced values from A to B, both
        included (A alone if N = 1)."""
        if set(v) != {"from", "to", "num"}:
            self.fail(where, f"a range is {{ from = A, to = B, num = N }}, got {_toml(v)}")
        num = v["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            self.fail(f"{where}.num", f"expected a positive integer, got {_toml(num)}")
        if num > MAX_BRANCHES:  # before the values are listed
            self.fail(f"{where}.num", f"{num:,} values; a plan has at most {MAX_BRANCHES:,} "
                      "branches")
        a, b = self.number(f"{where}.from", v["from"]), self.number(f"{where}.to", v["to"])
        if num == 1:
            return [a]
        return [a + (b - a) * i / (num - 1) if i < num - 1 else b for i in range(num)]

    def starts(self, problem: Problem) -> tuple[list, int]:
        """``start`` and ``switch``: the starts (``{}`` for the module's exact solution, a
        label, or :class:`Switch` at a label) and the count of branch points to switch at."""
        parsed = []
        switch = self.doc.get("switch", [])
        count = 0
        if isinstance(switch, int) and not isinstance(switch, bool):
            if switch < 0:
                self.fail("switch", f"expected a count >= 0 or a list of \"FILE.h5:BPn\", "
                          f"got {switch}")
            count = switch
        elif isinstance(switch, list):
            for item in switch:
                label = self.file_label("switch", problem, self.string("switch", item))
                if labels.kind_of(label.name) not in labels.SWITCHES:
                    self.fail("switch", f"{item!r}: branch switching needs a BP label")
                parsed.append(Switch(label))
        else:
            self.fail("switch", "expected a count or a list of \"FILE.h5:BPn\", got "
                      + _toml(switch))
        starts = self.doc.get("start", [] if parsed else "trivial")
        starts = starts if isinstance(starts, list) else [starts]
        if not starts and not parsed:
            self.fail("start", "empty list")
        for s in starts:
            if isinstance(s, dict):
                parsed.extend(self.selected("start", problem, s))
            elif self.string("start", s) == "trivial":
                parsed.append({})
            else:
                parsed.append(self.file_label("start", problem, s))
        return parsed, count

    def branch_file(self, key, problem: Problem, fname: str) -> BranchFile:
        """The branch file ``fname`` (looked up in the output folder, beside the run file,
        then here), computed with ``problem``'s module. A file is opened (and its layout
        checked) once per run file: every ``start``, ``switch`` and selector naming it, however
        spelled, gets the same `BranchFile`."""
        given = Path(fname)
        candidates = [given] if given.is_absolute() else (
            ([self.out_dir / fname] if self.out_dir is not None else [])
            + [self.path.parent / fname, given])
        file = next((c for c in candidates if c.is_file()), None)
        if file is None:
            folders = ", ".join(dict.fromkeys(str(c.parent) for c in candidates))
            self.fail(key, f"restart file {fname!r} not found (looked in {folders}); "
                      "run the run that writes it first")
        resolved = file.resolve()
        bf = self._branch_files.get(resolved)
        if bf is None:
            try:
                bf = self._branch_files[resolved] = BranchFile(file)
            except StoreError as exc:
                self.fail(key, str(exc))
        if Path(bf.equation).stem != problem.name:
            self.fail(key, f"{fname} was computed with {bf.equation!r}, not {problem.source!r}")
        return bf

    def file_label(self, key, problem: Problem, s: str) -> StoredLabel:
        if ":" not in s:
            self.fail(key, f"expected \"trivial\" or \"FILE.h5:LABEL\", got {_toml(s)}")
        fname, name = s.rsplit(":", 1)
        try:
            return self.branch_file(key, problem, fname).label(name)
        except StoreError as exc:
            self.fail(key, str(exc))

    def selected(self, key, problem: Problem, sel: dict) -> list[StoredLabel]:
        """Labels of one type in a file whose parameters match ``where`` (periodic parameters
        modulo their period) and, if given, whose stability index is ``index``, in label
        order; with ``distinct``, one per equilibrium (also across selectors: periodic copies
        and the same equilibrium reached by two selectors count once); at most ``limit``."""
        for k in sel:
            if k not in SELECTOR_KEYS:
                self.fail(f"{key}.{k}", f"unknown key; expected one of {sorted(SELECTOR_KEYS)}")
        if "file" not in sel:
            self.fail(key, "a start selector needs file = \"FILE.h5\"")
        bf = self.branch_file(f"{key}.file", problem,
                              self.string(f"{key}.file", sel["file"]))
        kind = self.string(f"{key}.type", sel.get("type", labels.UZ))
        where = sel.get("where", {})
        if not isinstance(where, dict):
            self.fail(f"{key}.where", f"expected a table of parameter values, got {_toml(where)}")
        want = {}
        for q, v in where.items():
            if q not in problem.parameters:
                self.fail(f"{key}.where.{q}", f"unknown parameter; {problem.source} declares "
                          f"{', '.join(problem.parameter_names)}")
            want[q] = self.number(f"{key}.where.{q}", v)
        index = sel.get("index")
        if index is not None and (isinstance(index, bool) or not isinstance(index, int)):
            self.fail(f"{key}.index", f"expected an integer stability index, got {_toml(index)}")
        distinct = sel.get("distinct", True)
        if not isinstance(distinct, bool):
            self.fail(f"{key}.distinct", f"expected true or false, got {_toml(distinct)}")
        limit = sel.get("limit")
        if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int)
                                  or limit < 1):
            self.fail(f"{key}.limit", f"expected a positive integer, got {_toml(limit)}")
        names = sorted((n for n in bf.labels if n[:2] == kind), key=lambda n: int(n[2:]))
        out = []
        for n in names:
            br, pt = bf.labels[n]
            cols = bf.branches[br - 1].columns
            if not all(_same(cols[q][pt - 1], v, problem.parameters[q].period, 1e-9)
                       for q, v in want.items()):
                continue
            if index is not None and cols["index"][pt - 1] != index:
                continue
            if distinct:
                params = {q: cols[q][pt - 1] for q in problem.parameter_names}
                ords = [cols[o][pt - 1] for o in problem.ordinate_names]
                if any(_same_equilibrium(problem, params, ords, other) for other in self.seen):
                    continue
                self.seen.append((params, ords))
            out.append(bf.label(n))
            if limit is not None and len(out) == limit:
                break
        if not out:
            self.fail(key, f"no {kind} label of {bf.path.name} matches {where}")
        return out


def _same(a: float, b: float, period: float | None, rel: float) -> bool:
    """a == b to ``rel`` (relative, with 1 added), modulo ``period`` if there is one."""
    d = a - b
    if period:
        d = math.remainder(d, period)
    return abs(d) <= rel * (1 + abs(b))


def _same_equilibrium(problem: Problem, params, ords, other) -> bool:
    """Equal parameters (angles modulo their period) and equal ordinates: the ordinates are
    physical, so periodic copies of one equilibrium have the same ones."""
    p2, o2 = other
    return (all(_same(p2[q], v, problem.parameters[q].period, 1e-7) for q, v in params.items())
            and all(abs(a - b) <= 1e-5 * (1 + abs(a)) for a, b in zip(ords, o2)))
