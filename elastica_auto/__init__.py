"""elastica-auto: AUTO-07p-style continuation of boundary value problems on s in [0, 1].

The engine continues the solutions of an equation module (`elastica_auto.model.problem`) in one
named parameter by Keller pseudo-arclength on a collocation discretisation, labels folds (LP),
branch points (BP), user points (UZ) and end points (EP, MX) with the stability index on each
side, and writes branches to HDF5. From Python::

    import elastica_auto as ea
    problem = ea.load_problem("elastica_lever_arm")
    branches = ea.continuation(problem, {"eps": 0.5, "P": 22.2}, "psi", bounds=(-7, 7))

The public names are imported on first use, so that ``import elastica_auto`` (and the command
line's ``--version``) does not import numpy and scipy.
"""

import sys

__version__ = "0.2.0"
FORMAT_VERSION = 3

#: Public name -> the module that defines it.
_PUBLIC = {
    "load_problem": "model.problem", "Problem": "model.problem",
    # what an equation module builds its declarations and hooks from
    "Parameter": "model.problem", "Ordinate": "model.problem", "Mirror": "model.problem",
    "SecondVariation": "model.second_variation", "Constraint": "model.second_variation",
    "Symmetry": "model.symmetry", "Flow": "analysis.landing",
    "simpson": "core.solution", "hermite": "core.solution",
    "trapezoid_weights": "core.solution",
    "continuation": "api", "save": "api", "Branches": "api", "Interrupted": "api",
    "Switch": "execution.plan", "ContinuationOptions": "core.options", "snaps_along": "api",
    "BranchFile": "storage.store", "Branch": "branches.branch",
    "StoredLabel": "branches.branch",
    "PlanError": "core.errors", "ProblemError": "core.errors", "StoreError": "core.errors",
    "RunFileError": "core.errors", "StartError": "core.errors", "WriteError": "core.errors",
    "ClusterError": "core.errors", "ClusterLost": "core.errors",
    "view": "plots.viewer",
}

__all__ = ["__version__", *_PUBLIC]


def __getattr__(name):
    if name in _PUBLIC:
        import importlib
        value = getattr(importlib.import_module(f".{_PUBLIC[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_PUBLIC))


class _OldPaths:
    """The import system's last resort for ``elastica_auto.<module>``: an import path of the
    flat layout (``elastica_auto.problem``) gives a module whose names are the objects at
    their new places (the table `elastica_auto.core.moved`), each handed out with a
    DeprecationWarning that names that place. Installed at the end of ``sys.meta_path``, so
    it is asked only about modules no file provides, and it reads its table only then:
    ``import elastica_auto`` stays as cheap as before. (A finder rather than a shim file per
    old module: 32 files would sit beside the layers, and the table would be spread over
    them.)"""

    @staticmethod
    def find_spec(fullname, path=None, target=None):
        old = fullname.removeprefix(__name__ + ".")
        if old == fullname:
            return None
        import importlib
        import importlib.machinery
        moved = importlib.import_module(".core.moved", __name__)
        if old in moved.REMOVED_MODULES:
            raise ModuleNotFoundError(f"{fullname} was removed: {moved.REMOVED_MODULES[old]}",
                                      name=fullname)
        if old not in moved.MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, _OldPaths)

    @staticmethod
    def create_module(spec):
        return None  # the default module

    @staticmethod
    def exec_module(module):
        import importlib
        moved = importlib.import_module(".core.moved", __name__)
        old = module.__name__.removeprefix(__name__ + ".")
        places, removed = moved.new_places(old), moved.REMOVED.get(old, {})

        def __getattr__(name):
            if name in removed:
                # ImportError, not AttributeError: `from m import x` replaces an
                # AttributeError's message with its own "cannot import name"
                raise ImportError(f"{module.__name__}.{name} was removed: {removed[name]}",
                                  name=module.__name__)
            if name not in places:
                raise AttributeError(f"module {module.__name__!r} has no attribute {name!r}")
            new = f"{__name__}.{places[name]}".rstrip(".")
            top = _PUBLIC.get(name) == places[name]  # the same object at the top level
            where = f"{__name__} ({new})" if top else new
            import warnings
            warnings.warn(f"{module.__name__}.{name} is deprecated: import {name} from {where}",
                          DeprecationWarning, stacklevel=2)
            return getattr(importlib.import_module(new), name)

        module.__getattr__ = __getattr__
        module.__all__ = sorted(places)
        module.__dir__ = lambda: sorted(places)
        module.__doc__ = (f"{module.__name__}, a module of {__name__} {moved.OLD_VERSION}, "
                          f"deprecated since {moved.DEPRECATED_IN}: its names live elsewhere "
                          "now, each named by the warning it gives (docs/api.md).")


if not any(isinstance(f, type) and f.__name__ == "_OldPaths" and f.__module__ == __name__
           for f in sys.meta_path):  # once, also if this module is executed again
    sys.meta_path.append(_OldPaths)
