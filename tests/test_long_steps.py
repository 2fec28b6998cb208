"""Extreme but legal step options follow the same branches as the default ones (hostile M9):
the rotating arm's 50 folds, at the default run's locations.

With ds grown by 100 at a time, steps landed on other branches that lie near the tangent's
line farther on (a translate by a period, the mirror image across the straight rod), every
check passed: the closed-loop lookahead measured the start's distance from the tangent's line
against the grown, untried ds; the retries an event may take were spent by corrector
failures at lengths the branch never had; a UZ value the step's ends bracket but no solution
between them crosses was a warning. Now the lookahead measures against the start's own
distance, the retries count below the last accepted step, a step longer than 1.5 times it is
checked halfway (`stepper.Walk._arc_checked`) and such a UZ value rejects the step.
"""

from __future__ import annotations

import pytest

import elastica_auto as ea
from helpers import ROTATING_ARM, run_cli


def _folds(path):
    """[(branch, psi, m1)] of every LP of the file, in order."""
    out = []
    for br in ea.BranchFile(path).branches:
        c = br.columns
        out += [(br.number, float(c["psi"][i]), float(c["m1"][i]))
                for i, t in enumerate(c["type"]) if t == "LP"]
    return out


@pytest.fixture(scope="module")
def default_folds(tmp_path_factory, cli_exe):
    out = tmp_path_factory.mktemp("default")
    assert run_cli(cli_exe, "run", ROTATING_ARM, "--out", out, "-j", "1", "-q").returncode == 0
    folds = _folds(out / "rotating_arm.h5")
    assert len(folds) == 50
    return folds


def _assert_same_folds(folds, default):
    assert [b for b, _, _ in folds] == [b for b, _, _ in default]
    for (_, psi, m1), (_, psi0, m10) in zip(folds, default):
        assert psi == pytest.approx(psi0, rel=1e-9, abs=1e-9)
        assert m1 == pytest.approx(m10, rel=1e-9, abs=1e-9)


def test_the_hostile_step_options_give_the_default_folds(cli_exe, tmp_path, default_folds):
    """Hostile M9's command: 20 of the 50 folds, 6 of 8 branches "closed loops", exit 0.
    Now the 50, within 1e-9 of the default run's, and no warning."""
    out = run_cli(cli_exe, "run", "rotating_arm", "--out", tmp_path, "-j", "1", "-q",
                  "--set", "ds=5", "--set", "ds_max=1000", "--set", "growth=100",
                  "--set", "max_angle=1.57")
    assert out.returncode == 0 and "warning" not in out.stdout + out.stderr
    assert "closed loop" not in out.stdout
    _assert_same_folds(_folds(tmp_path / "rotating_arm.h5"), default_folds)


@pytest.mark.parametrize("options", [
    ("ds=5", "ds_max=1000", "growth=2", "max_angle=1.57"),
    ("ds_max=1000", "growth=100"),
])
def test_long_steps_without_user_points_keep_to_their_branch(cli_exe, tmp_path, options,
                                                              default_folds):
    """Without UZ values, whose location caught some of the jumps, the check halfway along a
    long step does: a step of 5 over a fold pair at growth 2, a step from a buckled rod to
    its mirror image (the straight rod halfway, crossing the chord at an angle) at 100."""
    path = tmp_path / "no_uz.toml"
    path.write_text("".join(line for line in ROTATING_ARM.read_text().splitlines(True)
                            if not line.startswith("uz")))
    args = [a for o in options for a in ("--set", o)]
    out = run_cli(cli_exe, "run", path, "--out", tmp_path, "-j", "1", "-q", *args)
    assert out.returncode == 0 and "warning" not in out.stdout + out.stderr
    _assert_same_folds(_folds(tmp_path / "no_uz.h5"), default_folds)
