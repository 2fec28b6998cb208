"""Issue 48 item 3: one problem interface (`elastica_auto.model.interface`). The module's
problem, the square problem with free parameters (a run of the pinned arm; a fold curve's
extended system), the phase-conditioned problem along a symmetry's circles and the straight
path in parameter space all implement it; a problem built around the module's forwards every
optional hook it does not change, or refuses it with a reason: none is dropped silently. The
hooks forwarded give the module's answers at the same states and parameters (the path's at
its effective values), checked against the module's own problem."""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.analysis.path import path_problem
from elastica_auto.branches.codim2 import fold_problem
from elastica_auto.core.solution import State
from elastica_auto.model.interface import OPTIONAL_HOOKS, ProblemInterface, Wrapper
from elastica_auto.model.symmetry import Phased


def _has(problem, hook) -> bool:
    return problem.mirror is not None if hook == "mirror" else getattr(problem, f"has_{hook}")


@pytest.fixture(scope="module")
def rod():
    """The spatial rod: a mirror, a symmetry and symmetric values, a drawing, a shooting
    scan, a second variation."""
    return ea.load_problem("kirchhoff_lever_arm")


@pytest.fixture(scope="module")
def kinds(rod, elastica):
    """(name, problem, base) of each kind: the base is the module's problem it is built on."""
    s = np.linspace(0.0, 1.0, 11)
    p = {**rod.defaults(), "P": 9.0}
    straight = State.from_values(rod, s, rod.exact_start(s, p), p)
    pinned = ea.load_problem("elastica_pinned")
    return [("module", rod, rod),
            ("free parameters", pinned.with_free(), pinned),
            ("fold curve", fold_problem(elastica, "psi"), None),
            ("phase condition", Phased(rod, straight), rod),
            ("path", path_problem(rod, p, {**p, "psi": 1.0}), rod)]


def test_every_kind_implements_the_interface(kinds):
    for name, problem, _ in kinds:
        assert isinstance(problem, ProblemInterface), name
        assert isinstance(problem.solved, tuple) and isinstance(problem.approximate_start, bool)
        assert problem.n0 <= problem.n and problem.parameter_names
    free = dict((n, p) for n, p, _ in kinds)
    assert free["free parameters"].solved == free["free parameters"].free
    assert free["fold curve"].solved == ("psi",) and free["module"].solved == ()


def test_the_module_problem_is_the_one_a_kind_is_built_on(kinds, elastica):
    """``module_problem``: the module's own problem, whose states are the first ``n0`` of the
    kind's, and whose ordinates at a kind's state (its first ``n0`` rows, at the parameters
    the kind reads from it) are the kind's own."""
    for name, problem, base in kinds:
        own = problem.module_problem
        assert own.module_problem is own, name
        assert tuple(problem.states[: own.n]) == tuple(own.states), name
        if base is not None and name != "path":
            assert own is base, name
    fold = dict((n, p) for n, p, _ in kinds)["fold curve"]
    # the fold system is a module of its own (states y and the null vector v), not the
    # elastica's: its ordinates are the elastica's of y
    assert fold.module_problem is not elastica and fold.module_problem.n == 2 * elastica.n
    # through two wrappers: the phase condition around the pinned arm's free parameters
    free, module = next((p, b) for n, p, b in kinds if n == "free parameters")
    twice = Phased(free, None)       # (its reference state is read only when it is solved)
    assert twice.module_problem is module and twice.n0 == free.n > module.n


def test_no_hook_is_dropped_silently(kinds):
    """For each hook the module has: the built problem has it too, or says why not."""
    for name, problem, base in kinds:
        if base is None:
            continue
        for hook in OPTIONAL_HOOKS:
            why = problem.refusal(hook)
            if why is not None:
                assert not _has(problem, hook) and len(why) > 20, (name, hook)
            else:
                assert _has(problem, hook) == _has(base, hook), (name, hook)


def test_the_wrapped_spatial_rod_keeps_its_mirror_and_symmetric_values_or_says_why(kinds, rod):
    assert rod.mirror is not None and rod.has_symmetric_values and rod.refusal("mirror") is None
    for name, problem, base in kinds:
        if base is not rod or problem is rod:
            continue
        for hook in ("mirror", "symmetric_values"):
            assert _has(problem, hook) or "the" in (problem.refusal(hook) or ""), (name, hook)
    phased = {n: p for n, p, _ in kinds}["phase condition"]
    assert isinstance(phased, Wrapper)
    with pytest.raises(ValueError, match="no optional hook"):
        phased.refusal("rhs")


def test_forwarded_hooks_answer_as_the_module(kinds, rod):
    """The drawing and the second variation of the phase-conditioned rod are the module's on
    its own states; the path's second variation and dynamics are the module's at the path's
    effective parameter values (t = 0.25 of psi from 0 to 1: psi = 0.25)."""
    k = {n: p for n, p, _ in kinds}
    phased, path = k["phase condition"], k["path"]
    assert phased.has_draw and phased.draw_projection == rod.draw_projection == "3d"
    s = np.linspace(0.0, 1.0, 21)
    p = {**rod.defaults(), "P": 9.0, "psi": 0.25}
    y = rod.exact_start(s, {**p, "psi": 0.0})
    y = y + 0.01 * np.sin(np.pi * s)              # any state: the forms are pointwise
    at_t = {**p, "t": 0.25, "psi": 0.0}
    ours, theirs = path.second_variation(s, y, at_t), rod.second_variation(s, y, p)
    for field in ("A", "B", "C"):
        np.testing.assert_array_equal(getattr(ours, field), getattr(theirs, field))
    assert path.has_gradient_flow == rod.has_gradient_flow
    lifted = np.vstack((y, np.zeros((2, len(s)))))
    np.testing.assert_array_equal(phased.second_variation(s, lifted, p).B,
                                  rod.second_variation(s, y, p).B)
    assert math.isclose(path.effective(at_t)["psi"], 0.25)
