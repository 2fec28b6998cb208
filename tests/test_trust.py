"""The trust model (docs/trust.md): reading a branch file never executes anything the user did
not name on the command line (hostile turn 5, H1).

A branch file names its equation module in its ``equation`` attribute, and can come from
anyone. Each command, and each Python path that reads a file, is run here on a crafted copy of
a real file whose attribute names a payload: a working copy of the shipped elastica module,
named like it (``elastica_lever_arm.py``, so that a check by module name passes), that writes
a marker file when it is imported. No command may create the marker; those that draw
configurations say, in one line, that they drew none and why.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import warnings

import h5py
import pytest

import elastica_auto as ea
from elastica_auto.plots import viewer
from elastica_auto.plots.layout import (Inset, NotDrawn, Panel, Pt, UntrustedEquation,
                                        draw_panel, equation_problem)
from elastica_auto.storage.store import BranchFile
from helpers import ELASTICA, REPO, run_cli
from test_robustness import SMALL
from test_view import page_json

#: What the payload does on import, before it defines the elastica module.
MARK = "import pathlib\npathlib.Path({marker!r}).write_text('ran')\n"


@pytest.fixture
def crafted(tmp_path, good_file):
    """(folder, crafted file, marker): ``good_file`` copied to ``folder/small.h5``, its
    ``equation`` attribute set to ``evil/elastica_lever_arm.py`` (relative to ``folder``,
    where the commands run), the payload there."""
    marker = tmp_path / "PWNED"
    (tmp_path / "evil").mkdir()
    (tmp_path / "evil" / "elastica_lever_arm.py").write_text(
        MARK.format(marker=str(marker)) + ELASTICA)
    h5 = tmp_path / "small.h5"
    shutil.copy(good_file, h5)
    with h5py.File(h5, "r+") as f:
        f.attrs["equation"] = "evil/elastica_lever_arm.py"
    (tmp_path / "small.toml").write_text(SMALL)
    return tmp_path, h5, marker


def run_here(cli_exe, folder, *args):
    return run_cli(cli_exe, *args, cwd=folder)


@pytest.mark.parametrize("args", [
    ["show", "small.h5"], ["show", "--all", "small.h5"], ["snaps", "small.h5"],
    ["export", "small.h5", "-o", "small.csv"], ["plot", "small.h5", "-o", "small.png"],
    ["plot", "small.h5", "-o", "small.png", "--fold"], ["list"],
], ids=lambda a: " ".join(a[:1] + [x for x in a[1:] if x.startswith("-")]))
def test_the_reading_commands_import_nothing(crafted, cli_exe, args):
    """show, snaps, export, plot (with and without --fold) and list: as documented, they
    never load a module; the crafted file reads as any other."""
    folder, _, marker = crafted
    proc = run_here(cli_exe, folder, *args)
    assert proc.returncode == 0, proc.stderr
    assert not marker.exists()


def test_view_draws_no_configuration_of_a_module_the_file_names(crafted, cli_exe):
    """Hostile H1's reproduction: `view` wrote the page having run the payload. Now the page
    is written without configurations, exit 0, one line on stderr says why and how to
    trust the module; the page says so too."""
    folder, _, marker = crafted
    proc = run_here(cli_exe, folder, "view", "small.h5")
    assert proc.returncode == 0, proc.stderr
    assert not marker.exists()
    assert proc.stderr.splitlines() == [
        "elastica-auto: configurations not drawn: the file names equation module "
        "'evil/elastica_lever_arm.py', which is not shipped; pass --equation PATH to trust it"]
    data = page_json((folder / "small.html").read_text())
    assert data["images"] == {} and "is not shipped" in data["no_images"]


def test_view_with_equation_runs_the_module_named_on_the_command_line(crafted, cli_exe):
    """The module given with --equation is the one run (here the payload itself: the user
    named it), and it draws every label."""
    folder, h5, marker = crafted
    proc = run_here(cli_exe, folder, "view", "small.h5", "--equation",
                    "evil/elastica_lever_arm.py")
    assert proc.returncode == 0 and proc.stderr == ""
    assert marker.exists()
    data = page_json((folder / "small.html").read_text())
    assert sorted(data["images"]) == sorted(BranchFile(h5).labels)


def test_view_with_the_shipped_module_named_on_the_command_line(crafted, cli_exe):
    """--equation with a shipped name: drawn by the shipped module, the payload not run."""
    folder, h5, marker = crafted
    proc = run_here(cli_exe, folder, "view", "small.h5", "--equation", "elastica_lever_arm")
    assert proc.returncode == 0 and proc.stderr == ""
    assert not marker.exists()
    assert sorted(page_json((folder / "small.html").read_text())["images"]) == \
        sorted(BranchFile(h5).labels)


def test_view_with_another_module_is_refused(crafted, cli_exe):
    """A module that is not the file's (by its file name, as for a restart) is refused
    before it is imported."""
    folder, _, marker = crafted
    (folder / "other.py").write_text(MARK.format(marker=str(marker)))
    proc = run_here(cli_exe, folder, "view", "small.h5", "--equation", "other.py")
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1
    assert "was computed with 'evil/elastica_lever_arm.py', not 'other.py'" in proc.stderr
    assert not (folder / "small.html").exists()


@pytest.mark.parametrize("how", ["--from", "start", "--resume"])
def test_restarts_and_resumes_import_only_the_run_files_module(crafted, cli_exe, how):
    """A restart from a crafted file's label (--from, and a run file's start) and a --resume
    onto a crafted output read its data, checked against the run's own module, which is the
    one run (the shipped elastica here); the module the file names is never imported."""
    folder, h5, marker = crafted
    if how == "--from":
        args = ["small.toml", "--from", "small.h5:UZ1", "--out", "restarted"]
    elif how == "start":
        (folder / "restart.toml").write_text(SMALL.replace(
            '[parameters]\neps = 0.25\nP = "pi^2/4"\n', 'start = "small.h5:UZ1"\n'))
        args = ["restart.toml", "--out", "restarted"]
    else:
        (folder / "out").mkdir()
        shutil.copy(h5, folder / "out" / "small.h5")
        args = ["small.toml", "--out", "out", "--resume"]
    proc = run_here(cli_exe, folder, "run", *args, "-j", "1", "-q")
    assert proc.returncode == 0, proc.stderr
    assert not marker.exists()
    if how == "--resume":
        assert "every cell is in out/small.h5 already" in proc.stdout


def test_the_paper_figures_draw_no_configuration_of_a_module_a_file_names(
        rotating_arm, tmp_path):
    """`python -m elastica_auto.plots`: a figure with configurations (rotating-arm-long) of a
    crafted rotating_arm.h5 is drawn without them, one line on stderr per figure."""
    marker = tmp_path / "PWNED"
    payload = tmp_path / "evil" / "elastica_lever_arm.py"
    payload.parent.mkdir()
    payload.write_text(MARK.format(marker=str(marker)) + ELASTICA)
    data = tmp_path / "data"
    data.mkdir()
    shutil.copy(rotating_arm.result.path, data / "rotating_arm.h5")
    with h5py.File(data / "rotating_arm.h5", "r+") as f:
        f.attrs["equation"] = str(payload)
    proc = subprocess.run([sys.executable, "-m", "elastica_auto.plots", "rotating-arm-long",
                           "--data", str(data), "--out", str(tmp_path / "fig")],
                          capture_output=True, text=True, cwd=REPO, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert not marker.exists()
    assert proc.stderr.splitlines() == [
        f"rotating-arm-long: configurations not drawn: the file names equation module "
        f"{str(payload)!r}, which is not shipped; the figures import no module named by a "
        "path"]
    assert (tmp_path / "fig" / "rotating_arm_long.png").is_file()


def test_python_readers_import_nothing(crafted):
    """BranchFile (columns, profiles, a label's solution), ea.view and the layout's panels
    of a crafted file (here named by an absolute path): nothing imported; ea.view and the
    panels warn (NotDrawn) and draw no configuration."""
    folder, h5, marker = crafted
    with h5py.File(h5, "r+") as f:
        f.attrs["equation"] = str(folder / "evil" / "elastica_lever_arm.py")
    bf = BranchFile(h5)
    bf.label("UZ1")
    for b in bf.branches:
        b.columns.load()
        assert len(b.profiles) == len(b)
    with pytest.warns(NotDrawn, match="is not shipped; pass equation=PATH"):
        page = ea.view(h5, folder / "page.html")
    assert page.images == {} and page.images.untrusted
    with pytest.raises(UntrustedEquation):
        equation_problem(bf.equation)
    br = bf.branches[0]
    i = list(br.columns["type"]).index("UZ")
    fig_panel = Panel([(bf, br)], "psi", "m1", "psi", "m1",
                      insets=[Inset("1", Pt(bf, br, i).configuration(),
                                    (float(br.columns["psi"][i]), float(br.columns["m1"][i])))])
    from matplotlib.figure import Figure
    fig = Figure()
    with pytest.warns(NotDrawn, match="is not shipped"):
        ax = draw_panel(fig, fig_panel)
    assert fig.axes == [ax]
    assert not marker.exists()


def test_python_draws_with_a_module_given(crafted, elastica):
    """ea.view(..., equation=problem) and Pt.configuration(problem=...) draw with the
    problem given, and warn of nothing."""
    folder, h5, marker = crafted
    bf = BranchFile(h5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        page = ea.view(h5, equation=elastica)
        assert sorted(page.images) == sorted(bf.labels)
        br = bf.branches[0]
        i = list(br.columns["type"]).index("UZ")
        c = Pt(bf, br, i).configuration(problem=elastica)
        assert equation_problem(c.equation) is elastica
        assert viewer.configuration_images(bf, elastica, workers=1) == page.images
    assert not marker.exists()


def test_the_files_tex_is_never_given_to_tex(viewer_file, monkeypatch):
    """A branch file's TeX labels are typeset by matplotlib's parser even where the user's
    matplotlib settings turn usetex on: a TeX installation would run what the label says."""
    import matplotlib

    from elastica_auto.plots.diagram import diagram_figure
    monkeypatch.setitem(matplotlib.rcParams, "text.usetex", True)
    fig = diagram_figure(BranchFile(viewer_file))
    texts = [fig.axes[0].xaxis.label, fig._supylabel, fig._suptitle]
    assert texts and not any(t.get_usetex() for t in texts)


def test_the_paper_figures_report_a_raising_draw_hook(rotating_arm, tmp_path, monkeypatch,
                                                       capsys, elastica):
    """Hostile turn 5, M8, for the figures: a draw hook that raises leaves those
    configurations blank, the figure is written, one line names the error and the command
    exits 3 (EXIT_ANALYSIS_FAILED)."""
    from elastica_auto.plots import __main__ as figures
    from elastica_auto.plots import layout

    class Raising:            # the shipped elastica, its draw hook raising
        module, has_draw, draw_projection = elastica.module, True, None

        def draw(self, ax, profile, params):
            raise RuntimeError("broken hook")

    monkeypatch.setattr(layout, "equation_problem", lambda equation: Raising())
    data = tmp_path / "data"
    data.mkdir()
    shutil.copy(rotating_arm.result.path, data / "rotating_arm.h5")
    status = figures.main(["rotating-arm-long", "--data", str(data), "--out",
                           str(tmp_path / "fig")])
    err = capsys.readouterr().err
    assert status == 3
    assert err.splitlines() == ["rotating-arm-long: draw hook failed: RuntimeError: broken "
                                f"hook at {__file__.rsplit('/', 1)[1]}:"
                                f"{Raising.draw.__code__.co_firstlineno + 1} in draw"]
    assert (tmp_path / "fig" / "rotating_arm_long.png").is_file()
