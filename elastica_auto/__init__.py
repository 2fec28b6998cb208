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

__version__ = "0.1.0"
FORMAT_VERSION = 2

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
    "Switch": "execution.plan", "ContinuationOptions": "core.options", "snaps_along": "path",
    "BranchFile": "storage.store", "Branch": "branches.branch",
    "StoredLabel": "branches.branch",
    "PlanError": "core.errors", "ProblemError": "core.errors", "StoreError": "core.errors",
    "RunFileError": "core.errors", "StartError": "core.errors",
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
