"""Hostile input through the CLI: non-finite numbers, undecodable or pathological run files,
equation modules that break the protocol, and points whose values are not finite.

Each case checks the exit status (2), that the message is one line naming the file and the
key or module, and, where a run computes, what the branch file holds.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from elastica_auto.execution import runfile
from elastica_auto.numerics import stability
from elastica_auto.model.problem import load_problem
from elastica_auto.core.solution import State
from elastica_auto.storage.store import BranchFile
from helpers import run_cli
from test_robustness import SMALL, one_line_error


def _run_file(tmp_path, name, text):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _bad_run(tmp_path, cli_exe, name, text, *needles):
    """Run ``text`` as a run file, expect a one-line user error naming it, and no output."""
    path = _run_file(tmp_path, name, text)
    proc = run_cli(cli_exe, "run", path, "--out", tmp_path / "out")
    err = one_line_error(proc, path.name, *needles)
    assert not (tmp_path / "out" / f"{name}.h5").exists()
    return err


# -- 1. non-finite numbers and absurd steps -------------------------------------------------------

NON_FINITE = {
    "toml_nan_parameter": (SMALL.replace("eps = 0.25", "eps = nan"), "[parameters] eps"),
    "toml_nan_option": (SMALL + "[options]\nds = nan\n", "[options] ds"),
    "toml_inf_parameter": (SMALL.replace('P = "pi^2/4"', "P = inf"), "[parameters] P"),
    "string_inf_parameter": (SMALL.replace('P = "pi^2/4"', 'P = "inf"'), "[parameters] P"),
    "overflowing_literal": (SMALL.replace('P = "pi^2/4"', 'P = "1e400"'), "[parameters] P"),
    "overflowing_product": (SMALL.replace('P = "pi^2/4"', 'P = "1e300*1e300"'),
                            "[parameters] P"),
    "nan_in_grid": (SMALL.replace("eps = 0.25", "eps = [0.25, nan]"), "[parameters] eps"),
    "nan_user_value": (SMALL.replace('uz = ["pi/6"]', "uz = [nan]"), "[continuation] uz"),
    "inf_user_value": (SMALL.replace('uz = ["pi/6"]', "uz = [inf]"), "[continuation] uz"),
    "nan_bound": (SMALL.replace('bounds = ["-pi", "pi"]', 'bounds = [nan, "pi"]'),
                  "[continuation] bounds"),
    "inf_bound": (SMALL.replace('bounds = ["-pi", "pi"]', 'bounds = ["-pi", inf]'),
                  "[continuation] bounds"),
    "inf_bound_expression": (SMALL.replace('bounds = ["-pi", "pi"]', 'bounds = ["-inf", "pi"]'),
                             "[continuation] bounds"),
    "inf_period": (SMALL.replace('uz_period = "2*pi"', "uz_period = inf"),
                   "[continuation] uz_period"),
}


@pytest.mark.parametrize("case", sorted(NON_FINITE))
def test_non_finite_values_are_refused(case, tmp_path, cli_exe):
    text, key = NON_FINITE[case]
    assert text != SMALL
    _bad_run(tmp_path, cli_exe, case, text, key)


def test_an_absurd_step_is_refused(tmp_path, cli_exe):
    text = SMALL + "[options]\nds = 1e300\nds_max = 1e300\n"
    _bad_run(tmp_path, cli_exe, "huge_step", text, "[options]", "ds_max must be <= 1000")


def test_omitted_bounds_still_mean_unbounded(tmp_path):
    """Refusing ``inf`` in run files must not take away the unbounded default."""
    text = SMALL.replace('bounds = ["-pi", "pi"]\n', "")
    plan = runfile.load(_run_file(tmp_path, "unbounded", text))
    assert (plan.stops.lower, plan.stops.upper) == (-math.inf, math.inf)


# -- 2. no stability index for a point with non-finite values -----------------------------------

def test_index_of_a_state_with_nan_is_unknown(elastica):
    s = np.linspace(0.0, 1.0, 11)
    params = {**elastica.defaults(), "eps": 0.25, "P": 1.0}
    straight = State.from_values(elastica, s, np.zeros((4, len(s))), params)
    assert stability.index(elastica, straight) == 0      # below the first critical load
    y = np.zeros((4, len(s)))
    y[0, 5] = np.nan
    assert stability.index(elastica, State.from_values(elastica, s, y, params)) == -1
    assert stability.index(elastica, State(s, straight.y, straight.yp,
                                           {**params, "P": np.nan})) == -1


NAN_MODULE = textwrap.dedent('''\
    """u'' + k u = 0, u(0) = u'(1) = 0, with k = lam up to lam = 1 and undefined (NaN) beyond."""
    import numpy as np
    from elastica_auto.model.problem import Ordinate, Parameter

    STATES = ("u", "v")
    PARAMETERS = [Parameter("lam", 0.0, r"\\lambda", "ode")]


    def _k(p):
        return np.nan if p["lam"] > 1 else p["lam"]


    def rhs(s, y, p):
        return np.vstack((y[1], -_k(p) * y[0]))


    def bc(ya, yb, p):
        return np.array((ya[0], yb[1]))


    def second_variation(s, y, p):
        return 1.0, -_k(p) + 0 * y[0], 0.0


    # v'(1), read off the right-hand side: NaN wherever the module is
    ORDINATES = [Ordinate("vp1", "v'(1)", lambda s, y, p: rhs(s, y, p)[1, -1], "lam")]


    def exact_start(s, p):
        return np.zeros((2, len(s)))
    ''')


def test_index_with_non_finite_coefficients_is_unknown(tmp_path):
    """A finite state at which the module's second variation is NaN has no index either."""
    (tmp_path / "nanmod.py").write_text(NAN_MODULE)
    problem = load_problem(str(tmp_path / "nanmod.py"))
    s = np.linspace(0.0, 1.0, 11)
    zero = np.zeros((2, len(s)))
    assert stability.index(problem, State(s, zero, zero, {"lam": 0.5})) == 0
    assert stability.index(problem, State(s, zero, zero, {"lam": 2.0})) == -1


def test_points_with_non_finite_values_get_no_index(tmp_path, cli_exe):
    """One branch walks from lam = 0 into the range where the module returns NaN, the other
    starts inside it. Whether the engine ends them with MX or refuses the start, no stored
    point with a non-finite parameter or ordinate may carry a stability index."""
    (tmp_path / "nanmod.py").write_text(NAN_MODULE)
    path = _run_file(tmp_path, "nan", textwrap.dedent("""\
        equation = "nanmod.py"
        [parameters]
        lam = [0, 2]
        [continuation]
        parameter = "lam"
        directions = "+"
        bounds = [-1, 3]
        [options]
        ds = 0.1
        ds_max = 0.2
        max_points = 40
        """))
    proc = run_cli(cli_exe, "run", path, "--out", tmp_path / "out", "-j", "1")
    assert "Traceback" not in proc.stderr
    if proc.returncode == 2:
        one_line_error(proc)
    else:
        assert proc.returncode == 1, (proc.returncode, proc.stderr)
        assert "MX" in proc.stdout + proc.stderr
    out = tmp_path / "out" / "nan.h5"
    if not out.exists():
        return
    bf = BranchFile(out)
    finite_rows = 0
    for b in bf.branches:
        c = b.columns
        values = np.array([c[k] for k in bf.parameters + bf.ordinates])
        finite = np.all(np.isfinite(values), axis=0)
        for k in ("index", "index_direct"):
            assert np.all(c[k][~finite] < 0), (b.number, k, values, c[k])
        finite_rows += int(finite.sum())
    assert finite_rows > 0      # the points before lam = 1 are there, with their index


# -- 3. undecodable and pathological run files ----------------------------------------------------

def test_a_run_file_that_is_not_utf8(tmp_path, cli_exe):
    path = tmp_path / "latin1.toml"
    path.write_bytes(SMALL.replace('"small"', '"Stäbe"').encode("latin-1"))
    one_line_error(run_cli(cli_exe, "run", path, "--out", tmp_path / "out"), "latin1.toml",
                   "UTF-8")


@pytest.mark.parametrize("expression", ["1+" * 5000 + "1", "-" * 5000 + "1", "2**" * 5000 + "1",
                                        "(" * 5000 + "1" + ")" * 5000])
def test_deeply_nested_expressions(expression, tmp_path, cli_exe):
    text = SMALL.replace('P = "pi^2/4"', f'P = "{expression}"')
    _bad_run(tmp_path, cli_exe, "deep", text, "[parameters] P", "cannot evaluate")


@pytest.mark.parametrize("stop", ["LP²", "LP٣", "LP\uff14"])
def test_fold_counts_take_ascii_digits_only(stop, tmp_path, cli_exe):
    text = SMALL + f'stop = ["{stop}"]\n'
    _bad_run(tmp_path, cli_exe, "stop", text, "[continuation] stop", "LP4")


# -- 4. and 5. equation modules that break the protocol ------------------------------------------

GOOD_MODULE = textwrap.dedent('''\
    import numpy as np
    from elastica_auto.model.problem import Ordinate, Parameter

    STATES = ("u", "v")
    PARAMETERS = [Parameter("lam", 0.0, "lam", "ode")]
    ORDINATES = [Ordinate("du0", "du0", lambda s, y, p: y[1, 0], "lam")]


    def rhs(s, y, p):
        return np.vstack((y[1], -p["lam"] * y[0]))


    def bc(ya, yb, p):
        return np.array((ya[0], yb[1]))
    ''')

BROKEN_MODULES = {
    "states_not_a_sequence": (('STATES = ("u", "v")', "STATES = 5"), ["STATES", "int"]),
    "states_a_string": (('STATES = ("u", "v")', 'STATES = "uv"'), ["STATES", "str"]),
    "parameter_not_a_parameter": (('PARAMETERS = [Parameter("lam", 0.0, "lam", "ode")]',
                                   'PARAMETERS = ["lam"]'), ["PARAMETERS[0]", "Parameter"]),
    "default_not_a_number": (("0.0", '"zero"'), ["'lam'", "default", "'zero'"]),
    "default_nan": (("0.0", "float('nan')"), ["'lam'", "default", "nan"]),
    "default_inf": (("0.0", "float('inf')"), ["'lam'", "default", "inf"]),
    "ordinate_not_an_ordinate": (('ORDINATES = [Ordinate("du0", "du0", lambda s, y, p: y[1, 0], '
                                  '"lam")]', 'ORDINATES = [lambda s, y, p: y[1, 0]]'),
                                 ["ORDINATES[0]", "Ordinate"]),
    "exits_at_import": (("STATES =", "import sys\nsys.exit(0)\nSTATES ="), ["sys.exit(0)"]),
    "raises_system_exit": (("STATES =", "raise SystemExit('bye')\nSTATES ="),
                           ["sys.exit('bye')"]),
    "reserved_parameter_name": (('"ode")]', '"ode"), Parameter("index", 0.0, "i", "free")]'),
                                ["parameter name 'index'", "branch files"]),
    "reserved_ordinate_name": (('Ordinate("du0"', 'Ordinate("type"'),
                               ["ordinate name 'type'", "branch files"]),
    "slash_in_a_name": (('Ordinate("du0"', 'Ordinate("u/0"'), ["ordinate name 'u/0'", "'/'"]),
}


@pytest.mark.parametrize("case", sorted(BROKEN_MODULES))
def test_broken_modules_are_refused_at_load(case, tmp_path, cli_exe):
    (old, new), needles = BROKEN_MODULES[case]
    assert old in GOOD_MODULE
    (tmp_path / "mine.py").write_text(GOOD_MODULE.replace(old, new, 1))
    path = _run_file(tmp_path, "run", 'equation = "mine.py"\n[continuation]\nparameter = "lam"\n')
    one_line_error(run_cli(cli_exe, "run", path, "--out", tmp_path / "out"), "run.toml",
                   "mine.py", *needles)
    assert not (tmp_path / "out").exists()


def test_the_good_module_loads(tmp_path):
    """The base of the cases above is itself valid, so each case fails for its own reason."""
    (tmp_path / "mine.py").write_text(GOOD_MODULE)
    problem = load_problem(str(tmp_path / "mine.py"))
    assert problem.parameter_names == ["lam"] and problem.ordinate_names == ["du0"]
