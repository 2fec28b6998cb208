"""Run-file input that was let through badly: a stop with ">=" (issue 45 item 8), values that
exhaust memory (hostile M2), a ``--set`` value over several lines (hostile L3) and a UTF-8
byte-order mark (hostile L15).

Each refusal is a user error: one line naming the file and the key, exit status 2, nothing
computed.
"""

from __future__ import annotations

import os
import resource
import subprocess
import tomllib
import tracemalloc

import pytest

import elastica_auto as ea
from elastica_auto.core.errors import RunFileError
from elastica_auto.core.expressions import evaluate
from elastica_auto.execution import runfile
from elastica_auto.execution.plan import MAX_BRANCHES, MAX_USER_POINTS
from helpers import run_cli
from test_robustness import SMALL, one_line_error

FORMS = '"LPn" (such as "LP4"), "NAME > VALUE" or "NAME < VALUE"'


def _load(tmp_path, text, *overrides, name="r"):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return runfile.load(path, overrides=overrides)


def _refused(tmp_path, text, *overrides) -> str:
    with pytest.raises(RunFileError) as info:
        _load(tmp_path, text, *overrides)
    message = str(info.value)
    assert "\n" not in message
    return message


# -- stop entries (issue 45 item 8) ---------------------------------------------------------------

@pytest.mark.parametrize("entry, words", [
    ("m1 >= 1", "a stop has no \"or equal\" (the branch ends where NAME = VALUE): write "
                "'m1 > 1'"),
    ("m1 => 1", "write 'm1 > 1'"),
    ("m1 <= -0.5", "write 'm1 < -0.5'"),
    ("m1 == 1", "got 'm1 == 1'"),
    ("m1 = 1", "got 'm1 = 1'"),
    ("m1 <> 1", "got 'm1 <> 1'"),
    ("m1 ≥ 1", "got 'm1 ≥ 1'"),
    ("m1 > 1 > 2", "one comparison only"),
    ("LP0", "got 'LP0'"),
])
def test_a_stop_that_is_no_stop_names_what_is_accepted(tmp_path, entry, words):
    """``stop = ["x >= 1"]`` gave Python's parse error of "= 1"; now every malformed entry is
    refused with the forms a stop takes (and, for >=, the entry to write)."""
    message = _refused(tmp_path, SMALL + f'stop = ["{entry}"]\n')
    assert "[continuation] stop" in message and words in message, message
    assert FORMS in message and "<unknown>" not in message and "invalid syntax" not in message


@pytest.mark.parametrize("entry, words", [
    ("m1 > ", "'m1 > ': VALUE cannot evaluate '': invalid syntax"),
    ("m1 > pi/2)", "VALUE cannot evaluate 'pi/2)': unmatched ')'"),
    ("m1 > foo", "VALUE cannot evaluate 'foo': unknown name 'foo' (the constants are pi, e)"),
    ("u > 1", "'u' is not an ordinate or a free parameter (gamma, beta, m1, mA, m0, E)"),
    # the continued parameter's stop is its bound: say so, not only what it is not
    ("psi > 1", "'psi' is not an ordinate or a free parameter (gamma, beta, m1, mA, m0, E); "
     "psi is a parameter: a branch ends at a value of the continued parameter by bounds = "
     "[lower, upper]"),
])
def test_a_stop_with_a_bad_name_or_value_says_which(tmp_path, entry, words):
    message = _refused(tmp_path, SMALL + f'stop = ["{entry}"]\n')
    assert words in message and "<unknown>" not in message, message


def test_the_stops_that_are_stops_still_load(tmp_path):
    plan = _load(tmp_path, SMALL + 'stop = ["LP2", "m1 > 0.5", "beta < -pi"]\n')
    assert plan.stops.at_fold == 2
    assert [(lim.name, lim.sign, lim.value) for lim in plan.stops.limits] == [
        ("m1", 1, 0.5), ("beta", -1, -3.141592653589793)]


@pytest.mark.parametrize("text, words", [
    ("1 > 2", "compare not allowed"), ("x.y", "attribute not allowed"),
    ("sqrt(1, 2)", "not one of the functions"), ("1j", "1j is not a real number"),
])
def test_expressions_say_what_they_do_not_take(text, words):
    with pytest.raises(ValueError) as info:
        evaluate(text)
    assert words in str(info.value) and "ctx=" not in str(info.value), str(info.value)


@pytest.mark.parametrize("override, words", [
    ("ncol=true", "[options] ncol: expected an integer or \"auto\", got true"),
    ("tol=false", "[options] tol: expected a number or an expression string, got false"),
    ("map=1", "[continuation] map: expected true or false, got 1"),
    ('damping="x"', '[continuation] damping: expected a list of damping values, got "x"'),
    ("damping=[true]", "expected a number or an expression string, got true"),
])
def test_a_refused_value_is_spelled_as_the_run_file_spells_it(tmp_path, override, words):
    """``ncol = true`` was refused with "got True", Python's spelling of what the user did
    not write: a refused value is quoted in TOML's."""
    message = _refused(tmp_path, SMALL, override)
    assert words in message, message


def test_a_bad_stop_is_one_line_from_the_command_line(tmp_path, cli_exe):
    path = tmp_path / "stop.toml"
    path.write_text(SMALL + 'stop = ["m1 >= 1"]\n')
    one_line_error(run_cli(cli_exe, "run", path, "--out", tmp_path / "out"),
                   "stop.toml: [continuation] stop: 'm1 >= 1'", "write 'm1 > 1'", FORMS)
    assert not (tmp_path / "out").exists()


# -- sizes that exhaust memory (hostile M2) -------------------------------------------------------

def _peak_of_refusal(tmp_path, text, *overrides) -> tuple[str, int]:
    """The refusal of ``text`` and the most memory (bytes, Python's allocations) loading it
    took, the modules it needs imported first by a load of SMALL."""
    _load(tmp_path, SMALL, name="warm")
    tracemalloc.start()
    try:
        message = _refused(tmp_path, text, *overrides)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return message, peak


def test_a_range_longer_than_a_plan_is_refused_before_it_is_listed(tmp_path):
    """A range of 1e9 values took 35 s and 5.7 GB, then a MemoryError traceback. The limit is
    MAX_BRANCHES values (one more is refused here), checked before the values are listed:
    listing 100 001 floats alone takes 3 MB."""
    num = MAX_BRANCHES + 1
    message, peak = _peak_of_refusal(
        tmp_path, SMALL.replace("eps = 0.25", f"eps = {{ from = 0.1, to = 1, num = {num} }}"))
    assert f"[parameters] eps.num: {num:,} values; a plan has at most {MAX_BRANCHES:,} " \
           "branches" in message
    assert peak < 1_000_000


def test_a_grid_of_more_branches_than_a_plan_is_refused_before_it_is_listed(tmp_path):
    """Two ranges of 1e4 values (1e8 cells) took 70 s and 5.7 GB in the plan's list. Here 400 x
    400 cells both ways, 320 000 branches: refused with the count, before a branch is listed."""
    text = SMALL.replace("eps = 0.25", "eps = { from = 0.1, to = 1, num = 400 }").replace(
        'P = "pi^2/4"', "P = { from = 1, to = 2, num = 400 }")
    message, peak = _peak_of_refusal(tmp_path, text)
    assert "[parameters]: 400 eps x 400 P x 1 start(s) x 2 direction(s) is 320,000 branches; " \
           f"a plan has at most {MAX_BRANCHES:,}" in message, message
    assert peak < 1_000_000
    # the largest grid allowed is listed
    grid = text.replace("num = 400 }", "num = 100 }", 1).replace("num = 400 }", "num = 500 }")
    assert len(_load(tmp_path, grid).branches) == MAX_BRANCHES


@pytest.mark.parametrize("extra, words", [
    ("", "1e-300 puts 6.28e+300 user points within the bounds' span 6.28319, 1 uz value(s); "
         "a branch meets at most 100,000: raise uz_period or narrow the bounds"),
    ("nobounds", "1e-300 puts 1e+303 user points within max_points x ds_max = 1000 (no "
                 "bounds), 1 uz value(s); a branch meets at most 100,000: raise uz_period or "
                 "give bounds"),
])
def test_user_points_beyond_the_limit_are_refused(tmp_path, extra, words):
    """uz_period = 1e-300 grew each branch to 5.7 GB listing the crossings of one step."""
    text = SMALL.replace('uz_period = "2*pi"', "uz_period = 1e-300")
    if extra:
        text = text.replace('bounds = ["-pi", "pi"]\n', "")
    message = _refused(tmp_path, text)
    assert f"[continuation] uz_period: {words}" in message, message


def test_user_points_up_to_the_limit_are_allowed(tmp_path):
    """2 pi / 1e-4 is 62 832 user points within the bounds: loaded; 1e-5 (628 319) is not,
    nor an explicit list one longer than the limit."""
    text = SMALL.replace('uz_period = "2*pi"', "uz_period = 1e-4")
    assert _load(tmp_path, text).user_values[0].period == 1e-4
    assert "user points" in _refused(tmp_path, text.replace("1e-4", "1e-5"))
    values = ", ".join(["0.5"] * (MAX_USER_POINTS + 1))
    long_list = SMALL.replace('uz = ["pi/6"]\nuz_period = "2*pi"', f"uz = [{values}]")
    assert f"[continuation] uz: {MAX_USER_POINTS + 1:,} values" in _refused(tmp_path, long_list)


def test_the_python_api_has_the_same_limits(elastica):
    with pytest.raises(ea.PlanError) as info:
        ea.continuation(elastica, {"eps": 0.25, "P": 2.0}, "psi", bounds=(-1, 1), uz=[0],
                        uz_period=1e-9)
    assert info.value.key == "uz_period" and "at most 100,000" in str(info.value)
    with pytest.raises(ea.PlanError) as info:
        ea.continuation(elastica, {"eps": 0.25}, "psi",
                        params={"P": [1.0] * 1000, "alpha": [0.0] * 101}, directions="+")
    assert info.value.key == "params" and "101,000 branches" in str(info.value)


@pytest.mark.parametrize("setting", ["eps={from=0.1, to=1, num=1000000000}", "uz_period=1e-300"])
def test_sizes_that_took_all_memory_are_one_line_in_a_small_process(tmp_path, cli_exe, setting):
    """Hostile M2's reproductions through the command line: one line, exit 2, and the process
    stays as small as any run's start (its peak resident size, from the kernel). The
    address-space limit only keeps a regression from taking the machine's memory."""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))

    (tmp_path / "m2.toml").write_text(SMALL)
    with open(tmp_path / "stdout", "w") as out, open(tmp_path / "stderr", "w") as err:
        proc = subprocess.Popen([cli_exe, "run", tmp_path / "m2.toml", "--out", tmp_path / "out",
                                 "-j", "1", "--set", setting], stdout=out, stderr=err,
                                preexec_fn=limit)
    _, status, usage = os.wait4(proc.pid, 0)   # this child's own peak, not the others'
    proc.returncode = os.waitstatus_to_exitcode(status)
    done = subprocess.CompletedProcess(proc.args, proc.returncode,
                                       (tmp_path / "stdout").read_text(),
                                       (tmp_path / "stderr").read_text())
    one_line_error(done, "m2.toml", "at most 100,000")
    assert usage.ru_maxrss < 500_000     # kB


# -- what the command line records (hostile L3) ---------------------------------------------------

@pytest.mark.parametrize("value", ["eps=0.3\n[options]\nds_max=0.01", "eps=0.3\r\nds=0.1",
                                   "eps=0.3\n", "eps=0.3\u2028ds=0.1"])
def test_a_set_value_over_several_lines_is_refused(tmp_path, value):
    """``--set $'eps=0.3\\n[options]\\nds_max=0.01'`` applied eps = 0.3, dropped ds_max
    silently, and stored the rest as a live [options] table under ``# command line:``."""
    message = _refused(tmp_path, SMALL, value)
    assert message == f"--set {value!r}: a value cannot span lines; give each setting its " \
                      "own --set"


def test_a_set_value_over_several_lines_is_one_line_from_the_command_line(tmp_path, cli_exe):
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    proc = run_cli(cli_exe, "run", path, "--out", tmp_path / "out", "-j", "1",
                   "--set", "eps=0.3\n[options]\nds_max=0.01")
    one_line_error(proc, "--set 'eps=0.3\\n[options]\\nds_max=0.01': a value cannot span "
                         "lines")
    assert not (tmp_path / "out").exists()


def test_the_command_line_is_recorded_as_comments_only(tmp_path):
    """Whatever a --from path holds (a line break, a control character), the record under
    ``# command line:`` is comments: the stored text reads as the run file plus nothing, and
    each --set or --from is one line."""
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    doc = runfile.Document(path, None)
    restart = "x\n[options]\nds_max = 0.01\n\x1c\u2028/f.h5:UZ1"
    runfile.apply_overrides(doc, ["ds=0.1"], restart)
    record = doc.text[len(SMALL):]
    assert tomllib.loads(doc.text) == tomllib.loads(SMALL)
    assert record.splitlines() == [
        "", "# command line:",
        "#   --from x\\n[options]\\nds_max = 0.01\\n\\x1c\\u2028/f.h5:UZ1",
        "#   --set options.ds=0.1"]


# -- a byte-order mark (hostile L15) --------------------------------------------------------------

def test_a_run_file_with_a_byte_order_mark_reads_as_without(tmp_path, cli_exe):
    """Windows editors may start a UTF-8 file with a BOM, which TOML's parser reported as
    "Invalid statement (at line 1, column 1)". The mark says only that the file is UTF-8: the
    run file is read as without it, and the stored text has none."""
    plain, marked = tmp_path / "plain.toml", tmp_path / "marked.toml"
    plain.write_text(SMALL)
    marked.write_bytes(b"\xef\xbb\xbf" + SMALL.encode())
    a, b = runfile.load(plain), runfile.load(marked)
    assert b.text == a.text == SMALL
    assert (b.branches, b.parameter, b.stops) == (a.branches, a.parameter, a.stops)
    proc = run_cli(cli_exe, "run", marked, "--out", tmp_path / "out", "-q", "-j", "1")
    assert proc.returncode == 0, proc.stderr
    assert ea.BranchFile(tmp_path / "out" / "marked.h5").attrs["run_file"] == SMALL


def test_other_encodings_are_still_refused(tmp_path):
    path = tmp_path / "utf16.toml"
    path.write_bytes(SMALL.encode("utf-16"))
    with pytest.raises(RunFileError, match="not UTF-8 text"):
        runfile.load(path)
