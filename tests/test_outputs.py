"""The files the reading commands write: `export`'s CSV, `plot`'s figure, `view`'s page.

An output that is another branch file (an HDF5 file) or a folder is refused, one line and exit
2, before anything is made (hostile turn 5, L4); a write that fails leaves the earlier file
as it was and no temporary beside it, one line and exit 5 (hostile turn 5, M6).
"""

from __future__ import annotations

import resource
import subprocess

import h5py
import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.core.errors import EXIT_USER, EXIT_WRITE, StoreError
from elastica_auto.storage.outputs import is_hdf5
from helpers import run_cli
from test_robustness_files import read_only


def one_line(proc, status, *needles):
    assert proc.returncode == status, (proc.returncode, proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr
    err = proc.stderr.strip()
    assert len(err.splitlines()) == 1 and err.startswith("elastica-auto: error: "), err
    for n in needles:
        assert n in err, (n, err)


def command(name, h5, output):
    return {"export": ["export", h5, "-o", output], "view": ["view", h5, "-o", output],
            "plot": ["plot", h5, "-o", output]}[name]


@pytest.mark.parametrize("name", ["export", "view", "plot"])
def test_another_branch_file_is_not_overwritten(good_file, cli_exe, tmp_path, name):
    """Hostile L4's reproduction: `export out/t/small.h5 -o out/other.h5` replaced another
    run's branch file by a CSV (and `view -o` by a page). Refused now, whatever its name."""
    for victim in (tmp_path / "other.h5", tmp_path / "other.csv"):
        victim.write_bytes(good_file.read_bytes())
        before = victim.read_bytes()
        proc = run_cli(cli_exe, *command(name, good_file, victim))
        one_line(proc, EXIT_USER, str(victim), "is an HDF5 file")
        assert victim.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.csv", "other.h5"]


def test_an_hdf5_file_with_a_user_block_is_recognised(tmp_path):
    """HDF5 looks for its signature at 0, 512, 1024, ...: so does the check."""
    with h5py.File(tmp_path / "ub.h5", "w", userblock_size=1024) as f:
        f["x"] = np.arange(3)
    assert is_hdf5(tmp_path / "ub.h5")
    (tmp_path / "text.csv").write_text("a,b\n" * 1000)
    assert not is_hdf5(tmp_path / "text.csv")
    (tmp_path / "empty").write_bytes(b"")
    assert not is_hdf5(tmp_path / "empty")


def test_other_files_are_replaced(good_file, cli_exe, tmp_path):
    """An earlier CSV, page or figure (not HDF5) is replaced, as before."""
    for name, suffix in (("export", "csv"), ("view", "html"), ("plot", "png")):
        out = tmp_path / f"old.{suffix}"
        out.write_text("old\n")
        assert run_cli(cli_exe, *command(name, good_file, out)).returncode == 0
        assert out.read_bytes() != b"old\n"


def test_a_folder_is_refused_in_python(good_file, tmp_path):
    """ea.view's page: a folder, an HDF5 file and the file itself are refused alike."""
    for output in (tmp_path, good_file):
        with pytest.raises(StoreError):
            ea.view(good_file, output)


def _small_files(limit):
    def set_limit():      # files past ``limit`` bytes cannot be written (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return set_limit


@pytest.mark.parametrize("name, suffix", [("plot", "png"), ("plot", "pdf"), ("view", "html")])
def test_a_failed_write_keeps_the_earlier_file(good_file, cli_exe, tmp_path, name, suffix):
    """Hostile M6: `plot` wrote in place (a full disk truncated the earlier figure) and a
    failed write was a traceback. Now the earlier file stands, no temporary is left, and the
    failure is one line with exit status 5 (EXIT_WRITE); `view`'s page likewise."""
    out = tmp_path / f"figure.{suffix}"
    out.write_bytes(b"old")
    proc = subprocess.run([cli_exe, *map(str, command(name, good_file, out))],
                          capture_output=True, text=True, timeout=300,
                          preexec_fn=_small_files(2048))
    one_line(proc, EXIT_WRITE, str(out), "cannot write")
    assert out.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]


@pytest.mark.parametrize("name", ["plot", "view"])
def test_a_read_only_folder(good_file, cli_exe, tmp_path, name):
    """Hostile M6's reproduction (`plot -o` into a read-only folder): an OSError traceback.
    One line and exit 5 now."""
    folder = tmp_path / "ro"
    folder.mkdir()
    with read_only(folder):
        proc = run_cli(cli_exe, *command(name, good_file, folder / "x.out.png"
                                         if name == "plot" else folder / "x.html"))
    one_line(proc, EXIT_WRITE, "cannot write")
    assert list(folder.iterdir()) == []


def test_an_unknown_figure_format_is_one_line(good_file, cli_exe, tmp_path):
    proc = run_cli(cli_exe, "plot", good_file, "-o", tmp_path / "x.xyz")
    one_line(proc, EXIT_USER, "x.xyz", "'xyz'", ".png")
    assert list(tmp_path.iterdir()) == []


def test_a_figure_name_without_a_suffix_is_written_as_png(good_file, cli_exe, tmp_path):
    """docs/cli.md: `plot` writes its output's suffix's format, and PNG for a name without
    one (matplotlib's default format, which the style does not change)."""
    proc = run_cli(cli_exe, "plot", good_file, "-o", tmp_path / "figure")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "figure").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
