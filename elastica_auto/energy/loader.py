"""The hook of `load_problem`: a module with ``ENERGY`` gets the derived names it lacks.

`attach` is called on a module that defines ``ENERGY()`` once it is imported. It finds the
generated module (`elastica_auto.energy.cache`; else it calls ``ENERGY()``, derives and
generates, `elastica_auto.energy.derive`, `elastica_auto.energy.codegen`), executes it in a
namespace of its own and gives the user's module each derived name that the module does not
define itself. The rules, the same in `printed` (``elastica-auto derive``):

* what the module defines by hand takes precedence: ``exact_start``, ``draw``, ``MIRROR``,
  ``symmetry``, ``shooting``, an ``rhs``, a ``second_variation``, ...;
* a hand-written ``rhs`` keeps the derived ``rhs_jac`` and ``rhs_dp`` out (they would be
  another system's), and a hand-written ``bc`` the derived ``bc_jac`` and ``bc_dp``;
* a hand-written ``ORDINATES`` list is added to the derived one: an ordinate of the same
  name, or the distinguished ordinate of the same parameter, replaces the derived one
  (`merged_ordinates`);
* a hand-written ``symmetry`` hook is also given to the derived second variation: where it
  holds, its generator (the coordinates' rows) is a zero mode left out of the count
  (`runtime.zero_modes`);
* ``STATES``, ``PARAMETERS``, ``FREE`` and integral conditions are declared in the energy, and
  refused by hand; so is a name of the generated module's own helpers (``_derived_...``).

A problem that travels to a Dask worker carries the generated source (`Problem.__reduce_ex__`):
the worker executes it with `merge`, and never derives.
"""

from __future__ import annotations

import ast
import functools
import re
import sys
import types
from pathlib import Path

from ..core.errors import ProblemError
from . import cache as _cache
from .runtime import PREFIX, merged_ordinates

#: The protocol's names a generated module defines.
DERIVED = ("STATES", "PARAMETERS", "FREE", "ORDINATES", "rhs", "rhs_jac", "rhs_dp", "bc",
           "bc_jac", "bc_dp", "second_variation", "gradient_flow")
#: A hand-written function keeps these derived ones out.
DEPENDENTS = {"rhs": ("rhs_jac", "rhs_dp"), "bc": ("bc_jac", "bc_dp")}
#: Declared in the energy: refused by hand, with what to do instead.
DECLARED = {
    "STATES": "the states are the energy's coordinates, momenta (momenta=...) and quadratures",
    "PARAMETERS": "declare the parameters in Energy(parameters={symbol: Param(...)})",
    "FREE": "the free parameters are the multipliers of the energy's constraints",
    "INTEGRALS": "an integral condition of an energy is a quadrature with its final value "
                 "in fixed1 and a multiplier",
    "integrals": "an integral condition of an energy is a quadrature with its final value "
                 "in fixed1 and a multiplier",
}


def _check(module, source):
    energy = getattr(module, "ENERGY")
    if not callable(energy):
        raise ProblemError(f"{source}: ENERGY must be a function ENERGY() returning an "
                           f"elastica_auto.energy.Energy, got {type(energy).__name__}")
    for name, instead in DECLARED.items():
        if hasattr(module, name):
            raise ProblemError(f"{source}: a module with ENERGY cannot define {name}: "
                               f"{instead}")
    clash = sorted(n for n in vars(module) if n.startswith(PREFIX))
    if clash:
        raise ProblemError(f"{source}: {clash[0]} is a name of the generated code "
                           f"({PREFIX}...); rename it")


def canonical(energy) -> str:
    """The energy's expressions and declarations as one text (sympy's ``srepr``: names,
    assumptions and structure), the key of its generated code."""
    import sympy as sp

    def text(x):
        if isinstance(x, sp.Basic):
            return sp.srepr(x)
        if isinstance(x, dict):
            return "{" + ", ".join(f"{text(k)}: {text(v)}" for k, v in x.items()) + "}"
        if isinstance(x, (list, tuple)):
            return "[" + ", ".join(text(v) for v in x) + "]"
        if hasattr(x, "__dataclass_fields__"):
            return type(x).__name__ + text({f: getattr(x, f) for f in x.__dataclass_fields__})
        return repr(x)

    return text(energy)


def _energy(module, source):
    try:
        energy = module.ENERGY()
    except ProblemError as exc:
        raise ProblemError(f"{source}: {exc}") from exc
    except ImportError as exc:
        raise ProblemError(f"{source}: ENERGY() failed: {exc} (the derivation needs sympy: "
                           "pip install sympy)") from exc
    except Exception as exc:
        raise ProblemError(f"{source}: ENERGY() failed: {type(exc).__name__}: {exc}") from exc
    except SystemExit as exc:
        raise ProblemError(f"{source}: ENERGY() called sys.exit({exc.code!r})") from exc
    return energy


def derived_source(module, source: str, text: str, cache: bool = True):
    """The generated module of ``module`` (whose file's text is ``text``), its file name for
    tracebacks (the cache's file, or a description) and whether it came from the cache:
    from the cache where it has it, else derived (and kept)."""
    _check(module, source)
    use = _cache.enabled(cache)
    if use:
        tkey = _cache.text_key(text)
        hit = _cache.lookup_text(tkey)
        if hit is not None:
            return hit[0], str(hit[1]), True
    energy = _energy(module, source)
    from .declare import Energy
    if not isinstance(energy, Energy):
        raise ProblemError(f"{source}: ENERGY() returned {type(energy).__name__}; expected an "
                           "elastica_auto.energy.Energy")
    if use:
        ekey = _cache.energy_key(canonical(energy))
        hit = _cache.lookup_energy(ekey)
        if hit is not None:
            _cache.store(tkey, ekey, None)
            return hit[0], str(hit[1]), True
    code = generate(energy, source)
    if use:
        path = _cache.store(tkey, ekey, code)
        if path is not None:
            return code, str(path), False
    return code, f"<derived from {source}>", False


def generate(energy, source: str) -> str:
    """Derive ``energy`` and print its module; ProblemError (naming ``source``) where it
    cannot be derived."""
    from .codegen import generate as print_module
    from .derive import derive
    try:
        return print_module(derive(energy))
    except ProblemError as exc:
        raise ProblemError(f"{source}: {exc}") from exc


def attach(module, source: str, text: str, cache: bool = True) -> str:
    """Give ``module`` (which defines ENERGY) the derived names it lacks; the generated
    source, which travels with the problem. A cached module that fails to execute (a file
    edited or damaged by hand) is derived again and replaced."""
    code, filename, cached = derived_source(module, source, text, cache)
    try:
        derived = execute(code, source, filename)
    except Exception:
        if not cached:
            raise
        energy = _energy(module, source)
        code = generate(energy, source)
        _cache.store(_cache.text_key(text), _cache.energy_key(canonical(energy)), code)
        derived = execute(code, source, f"<derived from {source}>")
    _give(module, derived)
    return code


def execute(code: str, source: str, filename: str | None = None) -> types.ModuleType:
    """The generated module ``code``, executed in a namespace of its own."""
    namespace = types.ModuleType(f"elastica_auto_derived_{Path(source).stem}")
    namespace.__file__ = filename or f"<derived from {source}>"
    exec(_compiled(code, namespace.__file__), namespace.__dict__)
    return namespace


@functools.lru_cache(maxsize=16)
def _compiled(code: str, filename: str):
    """``code`` compiled, once per process: a run loads its module again for each run file
    it reads and each restart, and compiling the spatial rod's 2000 lines costs 1 MB and
    tens of milliseconds each time."""
    return compile(code, filename, "exec")


def merge(module, source: str, code: str, filename: str | None = None):
    """Execute the generated ``code`` and give ``module`` its names (module docstring)."""
    _give(module, execute(code, source, filename))


def _give(module, derived):
    # the derived code's file is the module's: a failure there is the module's own
    # (`elastica_auto.core.errors.module_files`), not an internal error
    module.__derived_file__ = derived.__file__
    if getattr(module, "symmetry", None) is not None:
        derived._derived_symmetry = module.symmetry
    left_out = {dep for name, deps in DEPENDENTS.items() if hasattr(module, name)
                for dep in deps}
    for name in DERIVED:
        if name == "ORDINATES" and hasattr(module, name):
            module.ORDINATES = merged_ordinates(module.ORDINATES, derived.ORDINATES)
        elif hasattr(derived, name) and not hasattr(module, name) and name not in left_out:
            setattr(module, name, getattr(derived, name))


#: Set in a module imported as a Python module once its derived names are given (or being
#: given): `derived_names` does not derive again.
_ATTACHED = "__energy_derived__"


def derived_names(name: str):
    """A module-level ``__getattr__`` for the module ``name`` (its ``__name__``) that defines
    ENERGY: imported as a Python module (``import elastica_auto.equations.X``, not through
    `load_problem`), it gets its derived names on first use of one of them (from the cache,
    or derived), as `load_problem` gives them. Write ``__getattr__ = derived_names(__name__)``
    in a module whose derived functions other code imports. Under `load_problem` (which
    executes the module under another name) it only says that a name is missing."""
    def __getattr__(attr):
        module = sys.modules.get(name)
        if module is None or attr not in DERIVED or _ATTACHED in vars(module) \
                or "ENERGY" not in vars(module):    # (a module `derive` printed)
            raise AttributeError(f"module {name!r} has no attribute {attr!r}")
        vars(module)[_ATTACHED] = True
        path = Path(module.__file__)
        attach(module, name, path.read_text(encoding="utf-8"))
        if attr not in vars(module):
            raise AttributeError(f"module {name!r} has no attribute {attr!r}")
        return vars(module)[attr]
    return __getattr__


def _bound_names(tree) -> dict[str, ast.stmt]:
    """The names the top-level statements of ``tree`` bind, each with its statement."""
    out = {}
    for node in tree.body:
        targets = []
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            targets = [node.name]
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            for t in (node.targets if isinstance(node, ast.Assign) else [node.target]):
                targets += [n.id for n in ast.walk(t) if isinstance(n, ast.Name)]
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            targets = [(a.asname or a.name).split(".")[0] for a in node.names]
        for name in targets:
            out[name] = node
    return out


def _lines(stmt) -> tuple[int, int]:
    first = min([stmt.lineno] + [d.lineno for d in getattr(stmt, "decorator_list", [])])
    return first - 1, stmt.end_lineno


def printed(text: str, code: str) -> str:
    """The module whose file's text is ``text`` with its ENERGY replaced by the derived
    definitions (``code``, its generated module) that it does not define itself (the rules
    of `merge`): a plain equation module, which loads without sympy and gives the same
    results (``elastica-auto derive``)."""
    user = _bound_names(ast.parse(text))
    lines = text.splitlines()
    energy = user["ENERGY"]
    if isinstance(energy, (ast.FunctionDef, ast.Assign)) and \
            (not isinstance(energy, ast.Assign) or len(energy.targets) == 1):
        a, b = _lines(energy)
        while a > 0 and lines[a - 1].lstrip().startswith("#"):
            a -= 1                        # its comment goes with it
        lines[a:b] = []
    else:
        lines.append("del ENERGY")
    generated = code.splitlines()
    tree = ast.parse(code)
    bound = _bound_names(tree)
    left_out = {dep for name, deps in DEPENDENTS.items() if name in user for dep in deps}
    edits = [(*_lines(tree.body[0]), [])]               # the generated module's docstring
    for name in DERIVED:
        if name not in bound:
            continue
        a, b = _lines(bound[name])
        if name == "ORDINATES" and name in user:        # hand-written ones merged in
            merged = generated[a:b]
            assert merged[0] == "ORDINATES = [" and merged[-1] == "]"
            merged[0] = f"ORDINATES = {PREFIX}runtime.merged_ordinates(ORDINATES, ["
            merged[-1] = "])"
            edits.append((a, b, merged))
        elif name in ("rhs", "second_variation") and name in user:
            # kept under its alias's name, which the derived ordinates call
            renamed = generated[a:b]
            assert renamed[0].startswith(f"def {name}(")
            renamed[0] = renamed[0].replace(f"def {name}(", f"def {PREFIX}{name}(", 1)
            edits.append((a, b, renamed))
            edits.append((*_lines(bound[PREFIX + name]), []))
        elif name in user or name in left_out:
            edits.append((a, b, []))
    if "symmetry" in user:
        a, b = _lines(bound[f"{PREFIX}symmetry"])
        edits.append((a, b, [f"{PREFIX}symmetry = symmetry  # the hand-written hook above"]))
    for a, b, new in sorted(edits, key=lambda e: e[0], reverse=True):
        generated[a:b] = new
    out = re.sub(r"\n{4,}", "\n\n\n", "\n".join(generated))
    head = re.sub(r"\n{4,}", "\n\n\n", "\n".join(lines).rstrip("\n"))
    return (head + "\n\n\n# " + "-" * 94 + "\n# Derived from ENERGY() by `elastica-auto "
            "derive`: what the hand-written definitions above do\n# not replace "
            "(docs/energy.md).\n#\n" + out.strip("\n") + "\n")
