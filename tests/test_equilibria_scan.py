"""The 1D equilibrium scan is a search on a grid, with the grid's resolution (issue 45 item 5):
two roots within one cell of its grid, with no grid value between them, are not found; one
cell apart they are. The shooting hook here is written for it: y' = 0, so y(1) = y(0) = k,
and the residual (k - a)(k - b) has its roots at a and b, on k in [-1, 1], whose grid
(SCAN_POINTS = 1201 values) has cells of 1/600.
"""

from __future__ import annotations

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.analysis.equilibria import SCAN_POINTS, enumerate_equilibria

PAIR = '''\
"""y' = 0; its shooting residual r(k) = (k - a)(k - b) on [-1, 1]."""
import numpy as np
from elastica_auto import Ordinate, Parameter

STATES = ("y",)
PARAMETERS = [Parameter("a", 0.0, "a", "ode"), Parameter("b", 0.5, "b", "ode")]


def rhs(s, y, p):
    return np.zeros_like(y)


def bc(ya, yb, p):
    return np.array([ya[0] - yb[0]])


def shooting(p):
    def residual(y0, y1):
        return (y1[0] - p["a"]) * (y1[0] - p["b"])
    return -1.0, 1.0, lambda k: np.atleast_2d(np.asarray(k, dtype=float)), residual


ORDINATES = [Ordinate("y0", "$y$", lambda s, y, p: y[0, 0], None)]
'''


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    path = tmp_path_factory.mktemp("pair") / "pair.py"
    path.write_text(PAIR)
    return ea.load_problem(str(path))


def test_the_grid_is_the_documented_one():
    cell = 2.0 / (SCAN_POINTS - 1)
    grid = np.linspace(-1.0, 1.0, SCAN_POINTS)
    # the cell [0.1, 0.1 + 1/600] of the tests below is one of the grid's
    assert np.min(np.abs(grid - 0.1)) < 1e-15 and cell == pytest.approx(1 / 600)


@pytest.mark.parametrize("a, b, found", [
    (0.1001, 0.1009, []),                    # both inside the cell [0.1, 0.10167]: missed
    (0.1001, 0.1002, []),
    (0.1001, 0.1030, [0.1001, 0.1030]),      # in two cells: both found
    (0.1010, 0.1020, [0.1010, 0.1020]),      # a grid value (0.10167) between them
    (-0.7, 0.4, [-0.7, 0.4]),
])
def test_two_roots_in_one_cell_are_not_found(pair, a, b, found):
    """The behaviour docs/design.md ("Searching for the equilibria") states: a cell with the
    same sign at both ends hides its two roots; roots with a grid value between them are
    found, to the scan's accuracy."""
    ks = [e.k for e in enumerate_equilibria(pair, {"a": a, "b": b})]
    np.testing.assert_allclose(ks, found, atol=1e-12)
