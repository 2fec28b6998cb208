"""The table of label kinds (`elastica_auto.core.labels`) against what says the same thing
independently: the events that make the points (their actions on the branch) and the names a
branch file gives its labelled points (its own ``type`` column)."""

from __future__ import annotations

import numpy as np

from elastica_auto.branches import extrema, kinds, registry, user_events
from elastica_auto.core import labels


def test_each_kind_is_what_the_event_making_it_does():
    """A fold is a turn and a fold; every branch point (located, placed at a symmetric value,
    of even multiplicity) a turn where other branches start; the kinds that neither change
    the index nor start branches (user values, bounds, user events, extrema) none of these;
    no event makes a failure (MX comes from the stepper's giving up)."""
    assert registry.FOLD.label in labels.FOLDS & labels.TURNS
    assert registry.FOLD.label not in labels.SWITCHES
    shipped = [registry.FOLD, registry.BRANCH_POINT, registry.SYMMETRIC_BRANCH_POINT,
               registry.EVEN_BRANCH_POINT, registry.USER_VALUE, registry.BOUND]
    requested = [user_events.EVENT, extrema.EVENT]
    for event in shipped + requested:
        assert (event.action == kinds.SWITCH) == (event.label in labels.SWITCHES), event
        assert event.label not in labels.FAILED
        if event.action == kinds.SWITCH:
            assert event.label in labels.TURNS and event.label in labels.SINGULAR
        elif event is not registry.FOLD:
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
