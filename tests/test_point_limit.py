"""A branch never has more than ``max_points`` points, labelled ones included, and says so
truly when it ends there (hostile L5)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import elastica_auto as ea
from helpers import elastica_run_file, run_cli

PI = math.pi


def _uz_values_crossed(first: float, last: float, value: float, period: float) -> list:
    """The values ``value + k period`` in [first, last] (either order), in the order met."""
    lo, hi = sorted((first, last))
    ks = range(math.ceil((lo - value) / period - 1e-9),
               math.floor((hi - value) / period + 1e-9) + 1)
    out = [value + k * period for k in ks]
    return out if first <= last else out[::-1]


@pytest.mark.parametrize("mirror", [True, False])
def test_dense_user_points_stop_at_max_points(cli_exe, tmp_path, mirror):
    """Hostile L5: `--set uz_period=0.01 --set max_points=50` gave branches of 38 and 54
    points, both "reached max_points = 50" (the UZ points a step met were all added after
    the count was checked, and those set aside for the mirror image counted). Now both have
    50, the last an EP after a UZ, and every UZ value the branch passes (psi is monotone
    there, from 0) is a UZ point, none skipped: pi/6 + 0.01 k."""
    path = elastica_run_file(tmp_path / "small.toml", directions="both",
                             bounds=("-pi", "pi"), uz=["pi/6"], mirror=mirror)
    out = run_cli(cli_exe, "run", path, "--set", "uz_period=0.01", "--set", "max_points=50",
                  "--out", tmp_path, "-j", "1", "-q")
    assert out.returncode == 0, out.stderr
    branches = ea.BranchFile(tmp_path / "small.h5").branches
    assert len(branches) == 2
    for br in branches:
        c = br.columns
        assert len(c["type"]) == 50 and br.attrs["message"] == "reached max_points = 50"
        assert c["type"][0] == c["type"][-1] == "EP"
        psi = c["psi"].astype(float)
        uz = psi[c["type"] == "UZ"]
        assert np.all(np.diff(psi) * np.sign(psi[-1]) >= 0)        # monotone from 0
        expected = _uz_values_crossed(0.0, float(uz[-1]), PI / 6, 0.01)
        np.testing.assert_allclose(uz, expected, atol=1e-12)


@pytest.mark.parametrize("max_points", [5, 20, 57, 100, 133])
def test_no_branch_exceeds_max_points(max_points):
    """The rotating arm's psi-branches, which repeat by the period (their copies are added by
    whole periods) and pass UZ values (each needing an EP after it where the branch ends
    there): at most max_points points, ending EP; a branch that ends one short says why."""
    problem = ea.load_problem("elastica_lever_arm")
    run = ea.continuation(problem, {"eps": 0.25, "P": PI ** 2 / 4}, "psi",
                          bounds=(-6 * PI, 6 * PI), directions="both", ds_max=1.0,
                          uz=[0, PI / 12, PI / 6, PI / 2], uz_period=2 * PI,
                          max_points=max_points, jobs=1)
    full = [br for br in run if br.message.startswith(f"reached max_points = {max_points}")]
    assert full
    for br in run:
        n = len(br.points)
        assert br.points[-1].type == "EP" and n <= max_points
        if br not in full:
            assert br.message.startswith("reached psi = ")
        else:
            _assert_full(br, max_points)


def _assert_full(br, max_points: int):
    """``br`` ended at ``max_points``: it has that many points, or one fewer where the next
    would have been a UZ point needing the EP after it too, and says which."""
    n = len(br.points)
    assert br.points[-1].type == "EP"
    if n < max_points:
        assert n == max_points - 1 and br.message == (
            f"reached max_points = {max_points} (the next point, UZ, and the EP after it "
            "would exceed it)")
    else:
        assert n == max_points and br.message == f"reached max_points = {max_points}"


def test_many_user_values_stop_at_max_points(tmp_path):
    """Hostile L5's 20 000 UZ values (and a tiny period, whose steps each crossed thousands of
    values, all solved for: the report's 1e-6 gave a branch of 29 743 points; 1e-4 here, the
    smallest within the run files' limit of 100 000 user points over the bounds):
    max_points, and the values past the room are not solved for (seconds, not minutes)."""
    problem = ea.load_problem("elastica_lever_arm")
    for uz, period in (([1e-4 * k for k in range(20000)], None), ([PI / 6], 1e-4)):
        run = ea.continuation(problem, {"eps": 0.25, "P": PI ** 2 / 4}, "psi",
                              bounds=(-PI, PI), directions="both", uz=uz, uz_period=period,
                              max_points=300, jobs=1)
        for br in run:
            _assert_full(br, 300)
