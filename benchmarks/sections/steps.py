"""One continuation step, and the direct count: sections 1 (a step on meshes of 100, 400 and
1600 intervals, and a fold), 7 (``--index``) and 8 (``--size``: a step as the system grows)."""

from __future__ import annotations

import importlib
import math
import statistics
import time

from . import REPO


def step_cost(intervals=(100, 400, 1600), steps=40):
    """Median ms per continuation step on a fixed mesh (no regridding), and the time to
    locate the first fold met (on meshes refined to fold_tol, as in a run)."""
    import numpy as np

    from elastica_auto.numerics.correctors import Collocation
    from elastica_auto.branches.events import Step, locate_fold
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.model.problem import load_problem
    from elastica_auto.core.solution import State, secant
    from elastica_auto.numerics.stability import index
    from elastica_auto.branches.stepper import start_solution

    problem = load_problem("elastica_lever_arm")
    params = {**problem.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    print("one continuation step of the elastica from the straight rod (psi, eps = 0.5, "
          "P = 9 pi^2/4, ds = 0.03), on a fixed mesh; then the first fold:")
    print(f"{'intervals':>10} {'ms/step':>8} {'ms/fold':>8}")
    for n in intervals:
        # tol = 1: no regridding, the mesh stays as given (folds still meet fold_tol)
        corr = Collocation(problem, "psi", ContinuationOptions(tol=0.99, ds_max=1.0))
        s = np.linspace(0.0, 1.0, n + 1)
        a = start_solution(corr, State.from_values(problem, s, problem.exact_start(s, params),
                                                   params), 1, None, False)
        times, ds, fold = [], 0.03, float("nan")
        while len(times) < steps or fold != fold:
            t0 = time.perf_counter()
            b = corr.step(a, ds)
            index(problem, b.state)
            times.append(time.perf_counter() - t0)
            if a.tangent.lam * b.tangent.lam < 0 and fold != fold:
                sec, dist = secant(a.state, b.state, "psi")
                t0 = time.perf_counter()
                locate_fold(corr, Step(a, b, sec, dist, 0.0, ds, "psi"))
                fold = time.perf_counter() - t0
            a = b
        print(f"{n:>10} {1e3 * statistics.median(times):>8.2f} {1e3 * fold:>8.1f}")


def index_cost(repeats=400):
    """Median ms of the direct count: the elastica at a buckled point (k = 1), and a k = 3
    form shaped like a spatial rod's (A = diag(1, 2, 1/1.3), B and C smooth and of the size
    of the paper's loads) on 100 intervals, unconstrained and with one constraint."""
    import numpy as np

    from elastica_auto.model.problem import load_problem
    from elastica_auto.model.second_variation import Constraint, SecondVariation
    from elastica_auto.core.solution import State
    from elastica_auto.numerics.stability import count, count_form

    def median_ms(f):
        f()
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            f()
            times.append(time.perf_counter() - t0)
        return 1e3 * statistics.median(times)

    problem = load_problem("elastica_lever_arm")
    s = np.linspace(0.0, 1.0, 101)
    params = {**problem.defaults(), "eps": 0.25, "P": 9 * math.pi ** 2 / 4}
    theta = 1.2 * np.sin(math.pi * s / 2)          # a buckled-like profile (the count does not
    y = np.vstack((theta, 0.6 * math.pi * np.cos(math.pi * s / 2), -np.sin(theta),
                   np.cos(theta)))                 # need an equilibrium)
    state = State.from_values(problem, s, y, params)
    a = np.diag([1.0, 2.0, 1 / 1.3])
    skew = np.array([[0.0, -1.0, 0.5], [1.0, 0.0, -0.3], [-0.5, 0.3, 0.0]])

    def rod(pts, constrained=False):
        c = np.cos(np.pi * pts)
        b = -22.0 * np.einsum("ij,m->ijm", np.array([[1.0, 0.2, 0.0], [0.2, 0.6, 0.1],
                                                     [0.0, 0.1, 0.3]]), c)
        return SecondVariation(a, b, np.einsum("ij,m->ijm", 2.0 * skew, 1 + 0.5 * c),
                               fixed0=[0, 1, 2],
                               constraints=[Constraint(np.vstack((c, c, c)))] * constrained)

    print("the direct count of the index, median ms per point:")
    ms = median_ms(lambda: count(problem, state))
    print(f"  elastica (k = 1, {len(s) - 1} intervals): {ms:.3f}"
          f" (index {count(problem, state).index})")
    for constrained in (False, True):
        ms = median_ms(lambda: count_form(lambda p: rod(p, constrained), s))
        what = "one constraint" if constrained else "no constraint"
        print(f"  k = 3, {len(s) - 1} intervals, {what}: {ms:.3f} (index "
              f"{count_form(lambda p: rod(p, constrained), s).index})")


class _Phases:
    """Wall time per phase of a step: the outermost call of a wrapped function counts."""

    GROUPS = {
        "assembly": [("numerics.collocation", "Discretisation", "evaluate"),
                     ("numerics.collocation", "Discretisation", "blocks"),
                     ("numerics.gauss", "GaussDiscretisation", "evaluate"),
                     ("numerics.gauss", "GaussDiscretisation", "blocks")],
        "factor": [("numerics.bordered", None, "factor")],
        "solves": [("numerics.bordered", "Factorization", "solve"),
                   ("numerics.bordered", "Factorization", "solve_transpose"),
                   ("numerics.bordered", "Factorization", "solve_with_border")],
        "estimate+tests": [("numerics.collocation", "Discretisation", "rms_residuals"),
                           ("numerics.gauss", "GaussDiscretisation", "rms_residuals"),
                           ("numerics.bordered", "Factorization", "sign")],
    }

    def __init__(self):
        self.total = dict.fromkeys(self.GROUPS, 0.0)
        self.depth = 0
        self.saved = []

    def _wrap(self, group, fn):
        def timed(*args, **kwargs):
            self.depth += 1
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.depth -= 1
                if self.depth == 0:
                    self.total[group] += time.process_time() - t0
        return timed

    def __enter__(self):
        for group, where in self.GROUPS.items():
            for module, cls, name in where:
                try:
                    mod = importlib.import_module(f"elastica_auto.{module}")
                except ImportError:          # an older commit without Gauss collocation
                    continue
                owner = mod if cls is None else getattr(mod, cls)
                attr = owner.__dict__[name]
                if isinstance(attr, property):
                    new = property(self._wrap(group, attr.fget))
                else:
                    new = self._wrap(group, attr)
                self.saved.append((owner, name, attr))
                setattr(owner, name, new)
        return self

    def __exit__(self, *exc):
        for owner, name, attr in reversed(self.saved):
            setattr(owner, name, attr)


def _stacked_elastica(copies):
    """``copies`` copies of the planar elastica as one system of 4 copies states (a generic
    module object: the engine sees one BVP with block-diagonal Jacobians)."""
    import dataclasses
    import types

    import numpy as np

    from elastica_auto.model.problem import Problem, load_problem

    base = load_problem("elastica_lever_arm")
    n = base.n
    mod = types.ModuleType("stacked")
    mod.STATES = tuple(f"{x}{j}" for j in range(copies) for x in base.states)
    # one copy's period maps name its states ("theta"), not the stack's ("theta0", ...): left
    # out (the steps here are timed on fixed meshes, no branch repeats)
    mod.PARAMETERS = [dataclasses.replace(q, period_shift=(), period_flip=())
                      for q in base.parameters.values()]
    mod.ORDINATES = []

    def split(y):
        return [y[j * n:(j + 1) * n] for j in range(copies)]

    def diag(blocks, shape_tail=()):
        out = np.zeros((n * copies, n * copies) + shape_tail)
        for j, b in enumerate(blocks):
            out[j * n:(j + 1) * n, j * n:(j + 1) * n] = b
        return out

    mod.rhs = lambda s, y, p: np.vstack([base.rhs(s, x, p) for x in split(y)])
    mod.rhs_jac = lambda s, y, p: diag([base.rhs_jac(s, x, p) for x in split(y)],
                                       (y.shape[1],))
    mod.rhs_dp = lambda s, y, p, name: np.vstack([base.rhs_dp(s, x, p, name) for x in split(y)])
    mod.bc = lambda ya, yb, p: np.concatenate([base.bc(a, b, p)
                                               for a, b in zip(split(ya), split(yb))])

    def bc_jac(ya, yb, p):
        pairs = [base.bc_jac(a, b, p) for a, b in zip(split(ya), split(yb))]
        return diag([a for a, _ in pairs]), diag([b for _, b in pairs])

    mod.bc_jac = bc_jac
    mod.bc_dp = lambda ya, yb, p, name: np.concatenate([base.bc_dp(a, b, p, name)
                                                        for a, b in zip(split(ya), split(yb))])
    mod.exact_start = lambda s, p: (None if (y := base.exact_start(s, p)) is None
                                    else np.vstack([y] * copies))
    return Problem(mod, f"{copies} x elastica_lever_arm")


def _size_systems():
    """(label, problem, parameter, start State on 100 intervals, ds, counts the index)."""
    import numpy as np

    import elastica_auto as ea
    from elastica_auto.branches.codim2 import fold_problem
    from elastica_auto.numerics.correctors import Collocation
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.model.problem import load_problem
    from elastica_auto.core.solution import State

    s = np.linspace(0.0, 1.0, 101)
    out = []
    elastica = load_problem("elastica_lever_arm")
    params = {**elastica.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    out.append(("n = 4, elastica", elastica, "psi",
                State.from_values(elastica, s, elastica.exact_start(s, params), params), 0.03,
                True))
    disk = load_problem(str(REPO / "examples" / "karman_disk.py")).with_free(("inflow",))
    p = disk.defaults()
    guess = State.from_values(disk, s, disk.guess(s, p), p)
    point = Collocation(disk, "a", ContinuationOptions(tol=0.99)).point(guess)
    out.append((f"n = {disk.n}, rotating disk", disk, "a", point.state, 0.05, False))
    rod = load_problem("kirchhoff_lever_arm")
    params = {**rod.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    out.append((f"n = {rod.n}, spatial rod", rod, "psi",
                State.from_values(rod, s, rod.exact_start(s, params), params), 0.03, True))
    cosserat = load_problem("cosserat_rod")
    params = {**cosserat.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    out.append((f"n = {cosserat.n}, Cosserat rod", cosserat, "psi",
                State.from_values(cosserat, s, cosserat.exact_start(s, params), params), 0.03,
                True))
    arm = ea.continuation(elastica, {"eps": 0.25, "P": math.pi ** 2 / 4}, "psi",
                          bounds=(-2 * math.pi, 2 * math.pi))
    (curve,) = ea.continuation(elastica, arm.label("LP1"), ["psi", "eps"], bounds=(0, 1),
                               max_points=4)
    end = curve.points[-1].state
    folds = fold_problem(elastica, "psi")
    out.append((f"n = {folds.n}, elastica fold curve", folds, "eps",
                State.from_values(folds, s, end(s), end.params), 0.02, False))
    stacked = _stacked_elastica(5)
    params = {**stacked.defaults(), "eps": 0.5, "P": 9 * math.pi ** 2 / 4}
    out.append((f"n = {stacked.n}, 5 x elastica", stacked, "psi",
                State.from_values(stacked, s, stacked.exact_start(s, params), params), 0.03,
                False))
    return out


def size_cost(steps=30, schemes=(0, 4)):
    """Section 8: the step cost at 100 intervals by system size, split into phases."""
    import dataclasses

    import numpy as np

    from elastica_auto.numerics import correctors
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.numerics.stability import index
    from elastica_auto.branches.stepper import start_solution
    from elastica_auto.core.solution import Tangent, secant
    # the corrector a run makes (Gauss for ncol > 0), on commits before make_corrector too
    make = getattr(correctors, "make_corrector", None)

    def curvature(a, b, name):
        """The stepper's second-order predictor term after the step a -> b: the change of the
        unit tangent per unit secant length (`branches.stepper`, as a run computes it)."""
        _, dist = secant(a.state, b.state, name)
        tb, ta = b.tangent.on(b.mesh), a.tangent.on(b.mesh)
        return Tangent(b.mesh, (tb.y - ta.y) / dist, (tb.yp - ta.yp) / dist,
                       (tb.lam - ta.lam) / dist)

    has_ncol = "ncol" in {f.name for f in dataclasses.fields(ContinuationOptions)}
    if not has_ncol:
        schemes = (0,)
    print("one continuation step on a fixed mesh of 100 intervals, by system size, predicted "
          "as a run predicts it (tangent and curvature): median CPU ms, the mean number of "
          "Newton iterations, and the mean split (ms)")
    head = ["system", "ncol", "ms/step", "newton", "assembly", "factor", "solves",
            "estimate+tests", "index", "rest"]
    print(f"{head[0]:>28} {head[1]:>4} " + " ".join(f"{h:>9}" for h in head[2:]))
    for label, problem, name, start, ds, counted in _size_systems():
        for ncol in schemes:
            # tol just below 1: no regridding, the mesh stays as given
            opt = ContinuationOptions(tol=0.99, ds_max=1.0, **({"ncol": ncol} if has_ncol
                                                               else {}))
            corr = (make(problem, name, opt) if make is not None
                    else correctors.Collocation(problem, name, opt))
            a = start_solution(corr, start, 1, None, False)
            for _ in range(3):                                  # warm-up
                a, before = corr.step(a, ds), a
            # a run's steps after its first: the predictor a + ds t + ds^2 / 2 k, with the
            # curvature k from the last two points (a tangent predictor alone needs a third
            # Newton iteration on the spatial rods, which no run's step makes)
            bend = curvature(before, a, name)
            times, idx, niter = [], 0.0, 0
            with _Phases() as phases:
                for _ in range(steps):
                    t0 = time.process_time()
                    b = corr.step(a, ds, bend)
                    _ = b.sign
                    if counted:
                        t1 = time.process_time()
                        index(problem, b.state)
                        idx += time.process_time() - t1
                    bend = curvature(a, b, name)
                    times.append(time.process_time() - t0)
                    niter += b.niter
                    a = b
            split = {k: 1e3 * v / steps for k, v in phases.total.items()}
            split["index"] = 1e3 * idx / steps
            rest = 1e3 * float(np.mean(times)) - sum(split.values())
            print(f"{label:>28} {ncol:>4} {1e3 * statistics.median(times):>9.2f} "
                  f"{niter / steps:>9.2f} "
                  + " ".join(f"{split[k]:>9.2f}" for k in head[4:-1]) + f" {rest:>9.2f}")
