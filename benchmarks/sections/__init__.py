"""The sections of `make bench` (``benchmarks/bench.py``), one module per kind of cost:
`steps` (a continuation step, the direct count, a step as the system grows), `runs` (whole
runs in one process and as processes, memory, saves, the rotating disk), `two_parameter`
(a fold curve, the map runs), `sweep` (branches on local Dask clusters), `landing` (where a
snap lands) and `energy` (energy-first modules against their references). Each section
prints its numbers and asserts nothing; they import only the package's public names and
its modules' public names (no name starting with ``_``)."""

import sys
from pathlib import Path

#: The repository (the run files, the examples, the hand-written reference modules).
REPO = Path(__file__).resolve().parents[2]
#: The correctors sections 2 and 3 compare.
CORRECTORS = ("collocation", "solve_bvp")
#: The command of this interpreter's environment.
CLI = [str(Path(sys.executable).parent / "elastica-auto")]
