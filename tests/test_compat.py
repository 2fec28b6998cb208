"""Issue 45 item 1: the import paths earlier docs gave keep working (docs/api.md).

The flat modules of 0.1.0 (``elastica_auto.problem``, ``store``, ...) were split into layers;
an import from an old path gives the object at its new place with a DeprecationWarning naming
that place. Checked three ways: every import the docs, examples, equations and tools ever
showed (listed here from their history, not from the package's table); every entry of the
table (`elastica_auto.core.moved`), against the module that really defines the name now; and,
where the repository's history is at hand, the table against the history's removed modules.
Then a user module written against the old docs is loaded and run through the command line.
"""

from __future__ import annotations

import ast
import importlib
import math
import re
import subprocess
import sys
import warnings

import pytest
from scipy.optimize import brentq

import elastica_auto
from elastica_auto.core import moved
from elastica_auto.storage.store import BranchFile
from helpers import REPO, run_cli

#: Every ``from elastica_auto.<old module> import ...`` and ``elastica_auto.<old>.<name>`` in
#: the history of README.md, docs/, examples/, equations/ and tools/ (``git log -p``), by old
#: module: the names imported from it.
DOCUMENTED_OLD = {
    "problem": ["Ordinate", "Parameter", "SecondVariation", "Constraint", "load_problem"],
    "store": ["BranchFile"],
    "stability": ["count_form", "nodes_and_midpoints", "count"],
    "solution": ["trapezoid_weights", "hermite", "simpson", "State"],
    "snaps": ["enumerate_equilibria", "scan_box"],
    "symmetry": ["Symmetry"],
    "landing": ["Flow", "damping_sweep"],
    "expressions": ["evaluate"],
    "options": ["ContinuationOptions"],
}

#: The same history's imports from paths that exist now: they must keep working, silently.
DOCUMENTED_CURRENT = {
    "elastica_auto": ["Constraint", "Flow", "Mirror", "Ordinate", "Parameter",
                      "SecondVariation", "hermite", "simpson", "trapezoid_weights", "BranchFile",
                      "Interrupted", "PlanError", "StartError", "Switch", "Symmetry",
                      "continuation", "load_problem", "save", "snaps_along", "view"],
    "elastica_auto.model.problem": ["Constraint", "Mirror", "Ordinate", "Parameter",
                                    "SecondVariation", "load_problem"],
    "elastica_auto.model.symmetry": ["Symmetry"],
    "elastica_auto.core.solution": ["State", "hermite", "simpson", "trapezoid_weights"],
    "elastica_auto.core.expressions": ["evaluate"],
    "elastica_auto.core.options": ["ContinuationOptions"],
    "elastica_auto.numerics.stability": ["count", "count_form", "nodes_and_midpoints"],
    "elastica_auto.analysis.equilibria": ["enumerate_equilibria", "scan_box"],
    "elastica_auto.analysis.snaps": ["enumerate_equilibria"],
    "elastica_auto.analysis.landing": ["Flow", "damping_sweep"],
    "elastica_auto.storage.store": ["BranchFile"],
    "elastica_auto.cli": ["main"],
    "elastica_auto.execution.run": [],
    "elastica_auto.plots": [],
    "elastica_auto.plots.layout": [],
    "elastica_auto.equations.elastica_lever_arm": ["ARM_COLOR", "CLAMP_COLOR", "LINE_WIDTH",
                                                  "draw_force", "draw_rod"],
    "elastica_auto.equations.kirchhoff_lever_arm": [],
}

WARNING = re.compile(r"^elastica_auto\.(?P<old>[\w.]+)\.(?P<name>\w+) is deprecated: import "
                     r"(?P=name) from (?P<where>elastica_auto(?: \((?P<new>[\w.]+)\))?"
                     r"|elastica_auto\.[\w.]+)$")


def _defining_module(obj, name: str) -> str:
    """Where ``obj`` is defined, found without the table: the module whose own top-level code
    binds ``name`` to it (its source names it in a def, class or assignment)."""
    for mod in sorted(m for m in sys.modules if m.split(".")[0] == "elastica_auto"):
        module = sys.modules[mod]
        if getattr(module, "__file__", None) is None or vars(module).get(name) is not obj:
            continue
        tree = ast.parse(open(module.__file__, encoding="utf-8").read())
        for node in tree.body:
            bound = [node.name] if isinstance(node, (ast.FunctionDef, ast.ClassDef)) else \
                [t.id for t in getattr(node, "targets", [getattr(node, "target", None)])
                 if isinstance(t, ast.Name)]
            if name in bound:
                return mod
    raise AssertionError(f"{name}: no module of the package defines it")


def _take(old: str, name: str):
    """``elastica_auto.<old>.<name>`` as a user's import gets it: the object and the one
    DeprecationWarning's message."""
    module = importlib.import_module(f"elastica_auto.{old}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        obj = getattr(module, name)
    messages = [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]
    assert len(messages) == 1, messages
    return obj, messages[0]


def _check_moved(old: str, name: str):
    obj, message = _take(old, name)
    m = WARNING.match(message)
    assert m and m["old"] == old and m["name"] == name, message
    place = m["new"] or m["where"]
    importlib.import_module(place)
    assert vars(sys.modules[place])[name] is obj          # the same object, at the named place
    assert _defining_module(obj, name) == place           # ... where it is defined
    at_top = name in elastica_auto.__all__ and getattr(elastica_auto, name) is obj
    assert (m["new"] is not None) == at_top, message     # the top-level name where there is one
    if place == "elastica_auto":
        assert m["where"] == "elastica_auto"


@pytest.mark.parametrize("old, name", [(o, n) for o, names in DOCUMENTED_OLD.items()
                                       for n in names])
def test_each_documented_old_import_warns_and_gives_the_new_object(old, name):
    """``from elastica_auto.problem import Ordinate`` (and every other import earlier docs
    showed): the object defined at the new place, and a DeprecationWarning that names it."""
    _check_moved(old, name)
    namespace = {}
    with pytest.warns(DeprecationWarning, match=rf"elastica_auto\.{old}\.{name} is deprecated"):
        exec(f"from elastica_auto.{old} import {name}", namespace)
    assert namespace[name] is _take(old, name)[0]


@pytest.mark.parametrize("old, name", [(o, n) for o in sorted(moved.MOVED)
                                       for n in sorted(moved.new_places(o))])
def test_every_name_of_the_table_resolves_where_its_warning_says(old, name):
    _check_moved(old, name)


@pytest.mark.parametrize("module, names", sorted(DOCUMENTED_CURRENT.items()))
def test_documented_current_paths_import_without_a_warning(module, names):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        namespace = {}
        exec(f"import {module}", namespace)
        for name in names:
            exec(f"from {module} import {name}", namespace)


def test_the_path_module_moved_into_the_analysis_layer():
    """Issue 48 item 5: ``elastica_auto.path`` (an analysis at the top) is
    ``elastica_auto.analysis.path`` now, ``snaps_along`` a top-level name defined in
    ``elastica_auto.api``; the old imports give the same objects with a warning each."""
    from elastica_auto.analysis import path
    with pytest.warns(DeprecationWarning, match=r"elastica_auto\.path\.snaps_along is "
                      r"deprecated: import snaps_along from elastica_auto \(elastica_auto\.api\)"):
        from elastica_auto.path import snaps_along
    assert snaps_along is elastica_auto.snaps_along
    with pytest.warns(DeprecationWarning, match=r"import path_problem from "
                                                r"elastica_auto\.analysis\.path$"):
        from elastica_auto.path import path_problem
    assert path_problem is path.path_problem


def test_removed_names_say_why():
    with pytest.raises(ImportError, match="corrector.solve_tangent was removed: a step's "
                                          "tangent"):
        exec("from elastica_auto.corrector import solve_tangent", {})
    with pytest.raises(ModuleNotFoundError, match="plots.config was removed: .*draw hook"):
        importlib.import_module("elastica_auto.plots.config")
    with pytest.raises(ModuleNotFoundError, match="No module named 'elastica_auto.nothing'"):
        importlib.import_module("elastica_auto.nothing")


def test_importing_the_package_reads_no_table_and_no_numpy():
    """The finder of old paths is installed by ``import elastica_auto`` but reads its table
    only when an old path is imported: the package still imports nothing else."""
    code = ("import sys, elastica_auto; "
            "print(sorted(m for m in sys.modules if m.startswith(('elastica_auto', 'numpy'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "['elastica_auto']"


def _git(*args) -> str:
    return subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                          check=True).stdout


def _history_at_hand() -> bool:
    try:
        return _git("rev-parse", "--is-shallow-repository").strip() == "false"
    except (OSError, subprocess.CalledProcessError):
        return False


@pytest.mark.skipif(not _history_at_hand(), reason="needs the repository's full history")
def test_the_table_covers_every_public_name_of_every_removed_module():
    """From the history: each module of the package deleted at some commit and not there now,
    its last version's public top-level names (defined there, or imported there from the
    package, which made them importable from it): each is moved or removed with a reason."""
    paths = {p for p in _git("log", "--no-renames", "--diff-filter=D", "--name-only",
                             "--pretty=format:", "HEAD", "--", "elastica_auto").split()
             if p.endswith(".py") and not (REPO / p).exists()}
    assert "elastica_auto/problem.py" in paths and len(paths) >= 32
    missing = []
    for path in sorted(paths):
        old = path.removeprefix("elastica_auto/").removesuffix(".py").replace("/", ".")
        if old.endswith("__init__"):
            continue
        if old in moved.REMOVED_MODULES:
            continue
        commit = _git("log", "--no-renames", "--diff-filter=D", "-1", "--pretty=%H", "HEAD", "--",
                      path).strip()
        tree = ast.parse(_git("show", f"{commit}^:{path}"))
        names = set()
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                names.add(node.name)
            elif isinstance(node, ast.Assign):
                names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
            elif isinstance(node, ast.ImportFrom) and node.level and node.module:
                names |= {a.asname or a.name for a in node.names}
        known = set(moved.new_places(old)) | set(moved.REMOVED.get(old, {}))
        missing += [f"{old}.{n}" for n in sorted(names)
                    if not n.startswith("_") and n not in known]
    assert not missing


BRATU_OLD = '''\
import numpy as np
from elastica_auto.problem import Ordinate, Parameter

STATES = ("u", "v")
PARAMETERS = [Parameter("lam", 0.0, "lam", "ode")]


def rhs(s, y, p):
    return np.vstack((y[1], -p["lam"] * np.exp(y[0])))


def bc(ya, yb, p):
    return np.array((ya[0], yb[0]))


def exact_start(s, p):
    return np.zeros((2, len(s))) if p["lam"] == 0 else None


ORDINATES = [Ordinate("du0", "du0", lambda s, y, p: y[1, 0], "lam")]
'''


def test_a_module_written_against_the_old_docs_loads_and_runs(tmp_path, cli_exe):
    """A Bratu module importing from ``elastica_auto.problem`` (the docs of 0.1.0): loaded
    by load_problem with the warning, and run by the command line, which shows the warning
    (naming the module's line and the new place) and computes the branch; its user point at
    lam = 1/2 has the closed form's u'(0) = 2 z tanh(z/2), 2 z^2 / cosh^2(z/2) = 1/2."""
    (tmp_path / "bratu_old.py").write_text(BRATU_OLD)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        problem = elastica_auto.load_problem(tmp_path / "bratu_old.py")
    assert {(w.category, w.filename, w.lineno, str(w.message)) for w in caught} == {
        (DeprecationWarning, str(tmp_path / "bratu_old.py"), 2,
         f"elastica_auto.problem.{name} is deprecated: import {name} from elastica_auto "
         "(elastica_auto.model.problem)") for name in ("Ordinate", "Parameter")}
    assert problem.parameter_names == ["lam"]
    toml = tmp_path / "old.toml"
    toml.write_text('equation = "bratu_old.py"\n[continuation]\nparameter = "lam"\n'
                    'directions = "+"\nbounds = [-1, 1]\nuz = [0.5]\n')
    proc = run_cli(cli_exe, "run", toml, "--out", tmp_path / "out", "-q", "-j", "1")
    assert proc.returncode == 0, proc.stderr
    assert "bratu_old.py:2: DeprecationWarning: elastica_auto.problem.Parameter is " \
           "deprecated: import Parameter from elastica_auto (elastica_auto.model.problem)" \
           in proc.stderr
    bf = BranchFile(tmp_path / "out" / "old.h5")
    br, pt = bf.labels["UZ1"]
    z = brentq(lambda z: 2 * z * z / math.cosh(z / 2) ** 2 - 0.5, 0.0, 2.0)
    assert bf.branches[br - 1].columns["du0"][pt - 1] == pytest.approx(
        2 * z * math.tanh(z / 2), rel=1e-6)
