"""The table of label kinds (`elastica_auto.core.labels`) against what says the same thing
independently: the events that make the points (their actions on the branch) and the names a
branch file gives its labelled points (its own ``type`` column)."""

from __future__ import annotations

import numpy as np
import pytest

from elastica_auto.branches import extrema, kinds, registry, user_events
from elastica_auto.core import labels


def test_each_kind_is_what_the_event_making_it_does():
    """A fold (located, or the fold stop's) is a turn and a fold; every branch point
    (located, placed at a symmetric value, of even multiplicity) a turn where other branches
    start; the kinds that neither change the index nor start branches (user values, bounds,
    the closed loop, user events, extrema) none of these; no event makes a failure (MX comes
    from the stepper's giving up)."""
    assert registry.FOLD.label in labels.FOLDS & labels.TURNS
    assert registry.FOLD.label not in labels.SWITCHES
    shipped = [registry.FOLD, registry.BRANCH_POINT, registry.SYMMETRIC_BRANCH_POINT,
               registry.EVEN_BRANCH_POINT, registry.USER_VALUE, registry.BOUND,
               registry.CLOSURE, registry.FOLD_STOP]
    requested = [user_events.EVENT, extrema.EVENT]
    for event in shipped + requested:
        assert (event.action == kinds.SWITCH) == (event.label in labels.SWITCHES), event
        assert event.label not in labels.FAILED
        if event.action == kinds.SWITCH:
            assert event.label in labels.TURNS and event.label in labels.SINGULAR
        elif event not in (registry.FOLD, registry.FOLD_STOP):
            assert event.label not in labels.TURNS | labels.SINGULAR | labels.FOLDS, event
    assert set(labels.MEANING) == set(labels.KINDS)
    assert labels.TURNS <= labels.SINGULAR


def test_a_labels_name_gives_its_kind(trivial_buckling):
    """Every label name of a run's file (numbered through the file, "BP2", "LP13") read back
    as its kind is the ``type`` of the row it names."""
    bf = trivial_buckling.file
    seen = set()
    for name, (br, pt) in bf.labels.items():
        kind = labels.kind_of(name)
        assert kind == str(bf.branches[br - 1].columns["type"][pt - 1]), name
        assert name[len(kind):].isdigit()
        seen.add(kind)
    assert {labels.BP, labels.EP} <= seen
    assert np.all(np.isin(np.unique(np.concatenate(
        [np.asarray(b.columns["type"], dtype=str) for b in bf.branches])),
        ["", *labels.KINDS]))


def _turn_step(fold_sigma: float):
    """A step of length 1 on a stand-in branch and a walk with no folds yet: only what the
    turn kinds read of them (the fold's sigma is read off the state the locator returns)."""
    from types import SimpleNamespace

    from elastica_auto.core.solution import Tangent
    s = np.linspace(0.0, 1.0, 5)
    unit = Tangent(s, np.zeros((1, 5)), np.zeros((1, 5)), 1.0)
    end = SimpleNamespace(lam=1.0, state="b", tangent=unit, extra={})
    step = SimpleNamespace(a=SimpleNamespace(lam=0.0, extra={}), b=end, secant=unit, dist=1.0,
                           ds=1.0, sigma=lambda state: fold_sigma)
    walk = SimpleNamespace(branch=SimpleNamespace(points=[], warnings=[]), name="lam",
                           problem=None, corr=None, refolded={})
    fold = SimpleNamespace(phi=unit, state="fold", residual=1e-12)
    return step, walk, fold


def _reconciled(monkeypatch, fold_sigma, bp_sigma, can_retry=True):
    """The registry's turn kinds, in their order, on a step where the parameter turns at
    ``fold_sigma`` and the determinant changes sign at ``bp_sigma`` (None: not located)."""
    from types import SimpleNamespace

    from elastica_auto.numerics.correctors import CorrectorFailure
    step, walk, fold = _turn_step(fold_sigma)

    def located(self, walk, step):
        if bp_sigma is None:
            raise CorrectorFailure("no root")
        return SimpleNamespace(sigma=bp_sigma, state="bp", value=1e-13)

    # the locators stood in for on the classes (restored after the test)
    monkeypatch.setattr(kinds.SymmetricBranchPoint, "locate", lambda self, walk, step: None)
    monkeypatch.setattr(kinds.BranchPoint, "locate", located)
    monkeypatch.setattr(kinds.Fold, "locate", lambda self, walk, step, before: fold)
    scan = kinds.Scan(step, None, 0, 1, False, {labels.LP: True, labels.BP: True}, can_retry,
                      None, "ode", crossed={labels.LP: True, labels.BP: True})
    for event in registry.DETECTION:
        event.detect(walk, scan)
    return [(h.kind, h.sigma, h.state) for h in scan.found], walk.branch.warnings


def test_a_fold_and_a_branch_point_in_one_step_are_reconciled_as_the_docs_say(monkeypatch):
    """docs/design.md's table of the turn kinds' order: in one step where the parameter turns
    and the determinant changes sign, a branch point located apart from the fold (more than
    SAME_EVENT of the step) is a BP of its own beside the LP; within SAME_EVENT the two are
    one BP at the fold; a branch point that cannot be located retries the step (spending a
    retry), and once retries are spent the turn is that BP, at the fold, with a warning."""
    found, _ = _reconciled(monkeypatch, 0.3, 0.6)
    assert found == [(labels.LP, 0.3, "fold"), (labels.BP, 0.6, "bp")]
    found, _ = _reconciled(monkeypatch, 0.3, 0.3 + kinds.SAME_EVENT / 2)
    assert found == [(labels.BP, 0.3, "fold")]
    with pytest.raises(kinds.Retry, match="branch point not located") as retry:
        _reconciled(monkeypatch, 0.3, None)
    assert retry.value.spends
    found, warnings = _reconciled(monkeypatch, 0.3, None, can_retry=False)
    assert found == [(labels.BP, 0.3, "fold")]
    assert len(warnings) == 1 and "branch point between lam = 0" in warnings[0]
