"""Run-file input that was let through badly: a stop with ">=" (issue 45 item 8), values that
exhaust memory (hostile M2), a ``--set`` value over several lines (hostile L3) and a UTF-8
byte-order mark (hostile L15).

Each refusal is a user error: one line naming the file and the key, exit status 2, nothing
computed.
"""

from __future__ import annotations

import pytest

from elastica_auto.core.errors import RunFileError
from elastica_auto.core.expressions import evaluate
from elastica_auto.execution import runfile
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
    ("u > 1", "'u' is not an ordinate or a free parameter (m1, beta, mA, gamma, m0)"),
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


def test_a_bad_stop_is_one_line_from_the_command_line(tmp_path, cli_exe):
    path = tmp_path / "stop.toml"
    path.write_text(SMALL + 'stop = ["m1 >= 1"]\n')
    one_line_error(run_cli(cli_exe, "run", path, "--out", tmp_path / "out"),
                   "stop.toml: [continuation] stop: 'm1 >= 1'", "write 'm1 > 1'", FORMS)
    assert not (tmp_path / "out").exists()
