"""The package's folders are its layers (docs/design.md, "Module layout").

Every import in the package, at the top of a module or inside a function, read with `ast`:
a module imports only from its own layer or a lower one, the modules import each other in no
circle, and no module imports a name starting with ``_`` from another module.
"""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "elastica_auto"

#: The layers, lowest first. At the bottom the package's ``__init__``: the version and the
#: table of public names, imported on first use (it imports nothing of the package when it is
#: imported, and every module of the package imports it first). Then a subpackage of
#: `elastica_auto` each, and on top the public API (`api`, `cli`), the figures
#: (`plots`) and the equation modules (`elastica_auto.equations`, the paper's figures read one).
#: `energy` (modules derived from an energy) sits right above `core`: `load_problem` (model)
#: calls its loader, and what its generated modules need from higher layers they pass in.
LAYERS = ["package", "core", "energy", "model", "numerics", "branches", "analysis", "storage",
          "execution", "top"]
#: Folders of the source tree that are not the engine's (symlinks of a working tree).
NOT_ENGINE = {"equations", "runs"}


def layer(module: str) -> str:
    """The layer of the dotted ``module`` (``elastica_auto.numerics.newton`` -> numerics)."""
    parts = module.split(".")
    if len(parts) == 1:
        return "package"
    return parts[1] if parts[1] in LAYERS else "top"


def modules(root: Path = PACKAGE) -> dict[str, Path]:
    """Dotted name -> file, for every module of the package."""
    found = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root.parent).with_suffix("")
        if rel.parts[1] in NOT_ENGINE:
            continue
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        found[".".join(parts)] = path
    return found


def imports(name: str, path: Path, known) -> list[tuple[str, str | None, int]]:
    """(module imported, name taken from it or None, line) for every import of the package's
    modules in ``path``, wherever it stands."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(a.name, None, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module
            for a in node.names:
                submodule = f"{source}.{a.name}"
                out.append((submodule, None, node.lineno) if submodule in known
                           else (source, a.name, node.lineno))
    return [(m, n, line) for m, n, line in out if m.split(".")[0] == "elastica_auto"]


def graph(root: Path = PACKAGE) -> dict[str, list[tuple[str, str | None, int]]]:
    known = modules(root)
    return {m: [i for i in imports(m, p, known) if i[0] != m] for m, p in known.items()}


def upward(edges) -> list[str]:
    return [f"{m}:{line} imports {target} ({layer(m)} < {layer(target)})"
            for m, out in edges.items() for target, _, line in out
            if LAYERS.index(layer(target)) > LAYERS.index(layer(m))]


def private(edges) -> list[str]:
    """Names starting with ``_`` imported from another module (``__version__`` is public)."""
    return [f"{m}:{line} imports {target}.{name}" for m, out in edges.items()
            for target, name, line in out
            if name is not None and name.startswith("_") and not name.endswith("__")]


def cycles(edges) -> list[list[str]]:
    """The circles of the module graph: its strongly connected components of more than one
    module (Tarjan)."""
    succ = {m: sorted({t for t, _, _ in out if t in edges}) for m, out in edges.items()}
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in succ[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in succ:
        if v not in index:
            visit(v)
    return found


def test_every_module_is_in_a_layer_folder_or_on_top():
    top = {m for m in modules() if layer(m) == "top"}
    assert top == {"elastica_auto.api", "elastica_auto.cli"} | {
        m for m in top if m.startswith("elastica_auto.plots.") or m == "elastica_auto.plots"}
    assert {layer(m) for m in modules()} == set(LAYERS)


def test_imports_go_down_only():
    assert upward(graph()) == []


def test_no_circle_of_imports():
    assert cycles(graph()) == []


def test_nothing_imports_the_command_line():
    """Issue 48 item 5: the command line (`cli`) is the package's outermost shell; what it
    shares with another module (``python -m elastica_auto.plots`` read the run files'
    restarts from it) lives below it, in the layer that owns it."""
    assert [f"{m}:{line}" for m, out in graph().items() for target, _, line in out
            if target == "elastica_auto.cli"] == []


def problem_kinds(root: Path = PACKAGE) -> set[str]:
    """The classes of the package that implement the problem interface: those deriving
    (through the package's classes, by name) from ``ProblemInterface``."""
    bases = {}
    for path in root.rglob("*.py"):
        if path.relative_to(root).parts[0] in NOT_ENGINE:
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ClassDef):
                bases.setdefault(node.name, set()).update(
                    b.id if isinstance(b, ast.Name) else getattr(b, "attr", "")
                    for b in node.bases)
    kinds = {"ProblemInterface"}
    while True:
        more = {c for c, b in bases.items() if b & kinds} - kinds
        if not more:
            return kinds - {"ProblemInterface"}
        kinds |= more


def kind_checks(root: Path = PACKAGE) -> list[str]:
    """``isinstance(x, K)`` with K a problem kind (`problem_kinds`) outside the model layer,
    as "module:line kind"; an isinstance on the interface itself is no check of a kind."""
    kinds = problem_kinds(root)
    found = []
    for name, path in modules(root).items():
        if layer(name) == "model":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not (isinstance(node, ast.Call) and getattr(node.func, "id", "") == "isinstance"
                    and len(node.args) == 2):
                continue
            classes = node.args[1].elts if isinstance(node.args[1], ast.Tuple) else [node.args[1]]
            for c in classes:
                k = c.id if isinstance(c, ast.Name) else getattr(c, "attr", "")
                if k in kinds:
                    found.append(f"{name}:{node.lineno} {k}")
    return found


def test_no_isinstance_on_problem_kinds_outside_the_model_layer():
    """Issue 48 item 3: what differs between the kinds of problem is in their answers to the
    interface (`elastica_auto.model.interface`), not in checks of their class."""
    assert {"Problem", "Augmented", "Phased", "PathProblem"} <= problem_kinds()
    assert kind_checks() == []


def test_no_private_name_from_another_module():
    assert private(graph()) == []


def kind_imports(edges) -> list[str]:
    """The imports of the package's modules by the kinds of special point an ``events``
    entry asks for (`elastica_auto.branches.registry.REQUESTED`) other than the event type
    (`branches.kinds`) and `core`: a new kind is its own module and one registry line, so
    it reads the walk only through the event interface."""
    from elastica_auto.branches.registry import REQUESTED
    allowed = {"elastica_auto.branches.kinds", "elastica_auto"}
    return [f"{m}:{line} imports {target}" for m in (f"elastica_auto.branches.{k}"
                                                    for k in REQUESTED)
            for target, _, line in edges[m]
            if target not in allowed and layer(target) != "core"]


def test_a_requested_event_kind_imports_only_the_event_type_and_core():
    assert kind_imports(graph()) == []


#: What locating, reconciling and checking the turns (folds, branch points) is made of: the
#: turn kinds' classes, their locators and probe, the fold rule's index change and the
#: kernel's dimension, the branch's folds and the search for them at their translates by a
#: period after the walk (`Fold.finish`). The turn kinds (`branches.kinds`, driven through
#: `registry.DETECTION`) use them; the stepper, which drives the kinds, does not.
TURN_LOGIC = {
    "elastica_auto.branches.kinds": {"Fold", "BranchPoint", "SymmetricBranchPoint",
                                     "EvenBranchPoint", "kernel_check", "rule_index",
                                     "branch_folds", "missing_translates", "TRANSLATE_NEAR",
                                     "TRANSLATE_SAME"},
    "elastica_auto.branches.registry": {"FOLD", "BRANCH_POINT", "SYMMETRIC_BRANCH_POINT",
                                        "EVEN_BRANCH_POINT"},
    "elastica_auto.branches.events": {"locate_fold", "locate_branch_point",
                                      "place_symmetric_branch_point", "locate_index_change",
                                      "pair_suspected", "parameter_turns"},
    "elastica_auto.numerics.stability": {"index_change", "kernel_dimension"},
}


def stepper_turn_logic(edges) -> list[str]:
    """The stepper's imports of what the turn kinds are made of (`TURN_LOGIC`)."""
    return [f"elastica_auto.branches.stepper:{line} imports {target}.{name}"
            for target, name, line in edges["elastica_auto.branches.stepper"]
            if name in TURN_LOGIC.get(target, ())]


def test_the_stepper_drives_the_turn_kinds_without_their_logic():
    assert stepper_turn_logic(graph()) == []


#: What placing the other shipped kinds is made of besides their classes and objects: the
#: locators of values and limits, the user values' crossings, and the return to the start's
#: tests (`branches.loops`). The placed kinds use them; the stepper does not.
PLACED_LOGIC = {
    "elastica_auto.branches.events": {"locate_value", "locate_limit", "crossings", "along",
                                      "tangent_between"},
    "elastica_auto.branches.loops": {"passes", "at_start", "far", "closed"},
}


def stepper_kinds(edges) -> list[str]:
    """The rule "the stepper imports no concrete kind": its imports of an event class other
    than the type itself (`branches.kinds.Event`: ``Fold``, ``Bound``, ``Closure``, a
    requested kind's ``EVENT``), of an event object (the registry's ``FOLD``, ``BOUND``,
    ``CLOSURE``, ...), of a whole module that defines a kind (``kinds``, ``loops``,
    ``user_events``), or of what a placed kind is made of (`PLACED_LOGIC`). It drives the
    kinds through the registry's two sets, ``DETECTION`` and ``PLACEMENT``, and the event
    interface (``crosses``, ``detect``, ``place``, ``keeps``, ``ahead``, ``action``), so that
    a new kind, turn or placed, is its class and its place in a set."""
    import importlib

    from elastica_auto.branches.kinds import Event

    def kind_class(v) -> bool:
        return isinstance(v, type) and issubclass(v, Event) and v is not Event

    out = []
    for target, name, line in edges["elastica_auto.branches.stepper"]:
        module = importlib.import_module(target)
        if name is None:
            bad = any(kind_class(v) and v.__module__ == target for v in vars(module).values())
        else:
            obj = getattr(module, name, None)
            bad = (kind_class(obj) or isinstance(obj, Event)
                   or name in PLACED_LOGIC.get(target, ()))
        if bad:
            out.append(f"elastica_auto.branches.stepper:{line} imports {target}"
                       + (f".{name}" if name else ""))
    return out


def test_the_stepper_imports_no_concrete_kind():
    assert stepper_kinds(graph()) == []


#: The labels only their kinds write or read in a walk: a failure's MX (`kinds.Failure`,
#: which the stepper hands every failure to), a fold curve's CP (`codim2.FoldCurvePoint`, a
#: placed kind of `registry.PLACEMENT`), and the turns' LP and BP (the turn kinds of
#: `registry.DETECTION`: their points, their ``detect`` switches, the folds at their
#: translates after the walk, `Fold.finish`). The stepper names the EP of its start and of
#: the ends it carries out, and the UZ of a user value's translate in the period it copies.
KIND_LABELS = {"MX", "CP", "LP", "BP"}


def stepper_labels(root: Path = PACKAGE) -> list[str]:
    """The labels of `KIND_LABELS` the stepper names (``labels.MX``, or ``MX`` imported from
    `core.labels`), as "line name": it hands a failure to its kind, a fold curve's folds
    are their kind's to label, and the turns are their kinds' (the repeat resumes past a
    turn by its property, `labels.TURNS`), so that none is written or read by the loop
    itself."""
    path = root / "branches" / "stepper.py"
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if (isinstance(node, ast.Attribute) and node.attr in KIND_LABELS
                and getattr(node.value, "id", "") == "labels"):
            out.append(f"{node.lineno} labels.{node.attr}")
        elif isinstance(node, ast.ImportFrom) and (node.module or "").endswith("labels"):
            out += [f"{node.lineno} {a.name}" for a in node.names if a.name in KIND_LABELS]
    return out


def test_the_stepper_names_no_failure_cusp_or_turn_label():
    assert stepper_labels() == []


@pytest.mark.parametrize("where, line, check", [
    ("branches/extrema.py", "from .stepper import Course", lambda r: kind_imports(graph(r))),
    ("branches/stepper.py", "from .events import locate_fold",
     lambda r: stepper_turn_logic(graph(r))),
    ("branches/stepper.py", "from .registry import FOLD", lambda r: stepper_turn_logic(graph(r))),
    ("branches/stepper.py", "from .registry import BOUND", lambda r: stepper_kinds(graph(r))),
    ("branches/stepper.py", "from .loops import Closure", lambda r: stepper_kinds(graph(r))),
    ("branches/stepper.py", "from . import user_events", lambda r: stepper_kinds(graph(r))),
    ("branches/stepper.py", "from .events import locate_value",
     lambda r: stepper_kinds(graph(r))),
    ("numerics/newton.py", "from ..execution.run import execute", lambda r: upward(graph(r))),
    ("numerics/newton.py", "from .stability import _kernel", lambda r: private(graph(r))),
    ("numerics/collocation.py", "from .newton import newton", lambda r: cycles(graph(r))),
    ("execution/run.py", "return isinstance(problem, Augmented)", lambda r: kind_checks(r)),
    ("branches/codim2.py", "return isinstance(base, Augmented)", lambda r: kind_checks(r)),
    ("branches/stepper.py", "return labels.MX", lambda r: stepper_labels(r)),
    ("branches/stepper.py", "from ..core.labels import CP", lambda r: stepper_labels(r)),
    ("branches/stepper.py", "return labels.LP", lambda r: stepper_labels(r)),
    ("branches/stepper.py", "from .kinds import branch_folds",
     lambda r: stepper_turn_logic(graph(r))),
    ("branches/stepper.py", "from .kinds import missing_translates",
     lambda r: stepper_turn_logic(graph(r))),
])
def test_the_checks_catch_what_they_forbid(tmp_path, where, line, check):
    """A copy of the package with one bad line, inside a function as the lazy imports are:
    an import from a higher layer, of a private name, and a circle (`newton` imports
    `collocation`); an isinstance on a kind of problem outside the model layer; the stepper
    naming a failure's, a cusp's or a turn's label, or the branch's folds or their search at
    the translates."""
    copy = tmp_path / "elastica_auto"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns(*NOT_ENGINE, "__pycache__"))
    assert not check(copy)
    module = copy / where
    module.write_text(module.read_text() + f"\n\ndef _bad():\n    {line}\n")
    assert check(copy)


def label_strings(root: Path = PACKAGE) -> list[str]:
    """Label-type strings (``"LP"``, ``"BP"``, ... : `elastica_auto.core.labels.KINDS`)
    compared with, looked up by, or matched as a name's prefix outside `core.labels`, as
    "module:line": what a kind is for the code is its `Kind`'s property or constant, so that
    a new kind is its row of the table and its event's module, not an edit of every reader.
    A string in a message or a column heading is no comparison and passes."""
    from elastica_auto.core.labels import KINDS

    def kind(node) -> bool:
        elts = node.elts if isinstance(node, (ast.Tuple, ast.List, ast.Set)) else [node]
        return any(isinstance(e, ast.Constant) and e.value in KINDS for e in elts)

    found = []
    for m, path in modules(root).items():
        if m == "elastica_auto.core.labels":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Compare):
                hit = any(kind(x) for x in (node.left, *node.comparators))
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
                hit = node.func.attr in ("startswith", "endswith") and any(map(kind, node.args))
            elif isinstance(node, ast.Subscript):
                hit = kind(node.slice)
            else:
                continue
            if hit:
                found.append(f"{m}:{node.lineno}")
    return found


def test_label_kinds_are_read_by_name_outside_the_table():
    assert label_strings() == []


@pytest.mark.parametrize("where, line", [
    ("plots/diagram.py", 'return t == "LP"'),
    ("analysis/snaps.py", 'return t in ("LP", "BP")'),
    ("execution/run.py", 'return name.startswith("BP")'),
    ("execution/plan.py", 'return opts.detect["LP"]'),
])
def test_the_label_check_catches_what_it_forbids(tmp_path, where, line):
    """A copy of the package with one label compared as a string, in each form the readers
    used before the table's properties."""
    copy = tmp_path / "elastica_auto"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns(*NOT_ENGINE, "__pycache__"))
    name = "elastica_auto." + where[:-3].replace("/", ".")
    assert not [f for f in label_strings(copy) if f.startswith(name + ":")]
    module = copy / where
    module.write_text(module.read_text() + f"\n\ndef _bad(t, name, opts):\n    {line}\n")
    assert [f for f in label_strings(copy) if f.startswith(name + ":")]


#: The names a corrector is held by outside ``numerics/`` (``corr``, ``self.corr``,
#: ``walk.corr``, ``corrector``): every attribute read on them must be an operation or field of
#: the corrector interface (`elastica_auto.numerics.corrector.Corrector`).
CORRECTOR_HOLDERS = {"corr", "corrector"}
#: What only a corrector reads: a solution's linearisation (``sol.lin``), a linearisation's
#: or corrector's discretisation (``.disc``), the corrector's own linearizer.
CORRECTOR_INTERNALS = {"lin", "disc", "_linearizer"}


def corrector_interface() -> set[str]:
    """The operations and fields of the corrector interface."""
    from elastica_auto.numerics.corrector import Corrector
    return {n for n in vars(Corrector) if not n.startswith("_")} | set(
        Corrector.__annotations__)


def corrector_reads(root: Path = PACKAGE) -> list[str]:
    """Attribute reads outside ``numerics/`` that reach into a corrector: on a name that holds
    one (CORRECTOR_HOLDERS), anything but the interface; anywhere, CORRECTOR_INTERNALS."""
    allowed = corrector_interface()
    found = []
    for m, path in modules(root).items():
        if layer(m) == "numerics":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.Attribute):
                continue
            held = node.value
            holder = (held.id if isinstance(held, ast.Name)
                      else held.attr if isinstance(held, ast.Attribute) else None)
            if (holder in CORRECTOR_HOLDERS and node.attr not in allowed) \
                    or node.attr in CORRECTOR_INTERNALS:
                found.append(f"{m}:{node.lineno} reads .{node.attr}")
    return found


def test_nothing_outside_numerics_reads_a_correctors_internals():
    assert corrector_reads() == []


@pytest.mark.parametrize("where, line", [
    ("branches/stepper.py", "return corr.disc(s)"),
    ("branches/events.py", "return self.corr.split"),
    ("branches/switching.py", "return walk.corr.solution(d, p, y, lam, row)"),
    ("branches/events.py", "return sol.lin.sign"),
    ("analysis/equilibria.py", "return corrector._linearizer"),
    ("branches/restart.py", "return lin.disc.s"),
])
def test_the_corrector_check_catches_what_it_forbids(tmp_path, where, line):
    """A copy of the package with one read of a corrector's internals: the patterns the
    stepper, events and switching used before the interface."""
    copy = tmp_path / "elastica_auto"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns(*NOT_ENGINE, "__pycache__"))
    assert corrector_reads(copy) == []
    module = copy / where
    module.write_text(module.read_text() + f"\n\ndef _bad(corr, self, walk, sol, lin, corrector):"
                                           f"\n    {line}\n")
    assert corrector_reads(copy)
