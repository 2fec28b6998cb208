"""The engine's plots: `elastica-auto plot` draws one panel per combination of fixed parameter
values, names labelled points without overlap, and configurations are drawn only through an
equation module's ``draw`` hook."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import elastica_auto as ea
from elastica_auto.core.errors import ProblemError
from elastica_auto.plots.diagram import diagram_figure, panel_groups, value_tex
from elastica_auto.plots.layout import Inset, Panel, Pt, draw_panel
from elastica_auto.storage.store import BranchFile
from helpers import EXAMPLES

P1, P2 = math.pi ** 2 / 4, 9 * math.pi ** 2 / 4


@pytest.fixture(scope="module")
def arm_figure(rotating_arm):
    bf = BranchFile(rotating_arm.result.path)
    fig = diagram_figure(bf)
    fig.draw_without_rendering()
    return bf, fig


def test_rotating_arm_has_one_panel_per_eps_and_P(arm_figure):
    bf, fig = arm_figure
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 4
    titles = sorted(ax.get_title() for ax in axes)
    assert titles == sorted(rf"$P={p}$, $\epsilon={e}$" for p in (r"\pi^2/4", r"9\pi^2/4")
                            for e in ("0.25", "0.5"))
    assert r"$\alpha=0$" in fig.get_suptitle() and r"$\theta_0=0$" in fig.get_suptitle()


def test_each_panel_holds_the_branches_of_its_values(rotating_arm):
    bf = BranchFile(rotating_arm.result.path)
    varying, groups = panel_groups(bf, "psi")
    assert varying == ["P", "eps"]
    assert [(round(v["P"], 6), v["eps"]) for v, _ in groups] == [
        (round(P1, 6), 0.25), (round(P1, 6), 0.5), (round(P2, 6), 0.25), (round(P2, 6), 0.5)]
    for values, branches in groups:
        assert len(branches) == 2                       # both directions
        for b in branches:
            assert b.columns["eps"][0] == values["eps"] and b.columns["P"][0] == values["P"]


@pytest.mark.parametrize("period", [None, 2 * math.pi])
def test_point_names_do_not_overlap(rotating_arm, period):
    """Folded into [0, 2 pi), the folds of each branch repeat at the same place: only one of
    each gets its name."""
    fig = diagram_figure(BranchFile(rotating_arm.result.path), period=period)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    for ax in fig.axes:
        boxes = [t.get_window_extent(renderer) for t in ax.texts if t.get_text()]
        assert len(boxes) >= 2, "folds left unnamed"
        for i, a in enumerate(boxes):
            assert ax.bbox.contains(a.x0, a.y0) and ax.bbox.contains(a.x1, a.y1)
            for b in boxes[i + 1:]:
                assert not a.overlaps(b), "two point names overlap"


def test_value_tex_writes_fractions_of_pi():
    assert value_tex(P2) == r"9\pi^2/4"
    assert value_tex(-math.pi / 12) == r"-\pi/12"
    assert value_tex(0.25) == "0.25" and value_tex(0.0) == "0" and value_tex(2.5e-7) == "2.5e-07"


def test_importing_the_plots_selects_no_backend():
    """No module of the plots calls matplotlib.use: the backend chosen before stays."""
    code = ("import matplotlib; matplotlib.use('svg'); import elastica_auto.plots, "
            "elastica_auto.plots.paper, elastica_auto.plots.__main__, elastica_auto.cli; "
            "print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "svg"


# ------------------------------------------------------------------------------ the draw hook
DRAW = '''

CALLS = []


def draw(ax, profile, p):
    CALLS.append((profile.shape, dict(p)))
    ax.plot(np.linspace(0, 1, profile.shape[1]), profile[0], color="black")
'''


@pytest.fixture(scope="module")
def bratu_files(tmp_path_factory):
    """One Bratu branch saved with a module that has a draw hook and one that has none:
    {name: (file, problem)} (the files name their module by its path: a figure of them
    draws configurations with the problem given, docs/trust.md)."""
    root = tmp_path_factory.mktemp("bratu_draw")
    text = (EXAMPLES / "bratu.py").read_text()
    files = {}
    for name, source in (("with_draw", text + DRAW), ("without_draw", text)):
        module = root / f"{name}.py"
        module.write_text(source)
        problem = ea.load_problem(str(module))
        branches = ea.continuation(problem, {"lam": 0.0}, "lam", bounds=(-1, 4), uz=[1, 2, 3],
                                   max_points=40)
        files[name] = BranchFile(ea.save(branches, root / f"{name}.h5")), problem
    return files


def _panel(bf, problem):
    br = bf.branches[0]
    rows = [i for i, t in enumerate(br.columns["type"]) if t == "UZ"]
    insets = [Inset(str(k + 1), Pt(bf, br, i).configuration(problem=problem),
                    (float(br.columns["lam"][i]), float(br.columns["du0"][i])))
              for k, i in enumerate(rows)]
    assert len(insets) >= 3
    return Panel([(bf, br)], "lam", "du0", "lam", "du0", insets=insets)


def test_the_draw_hook_gets_each_configuration_on_the_profile_grid(bratu_files):
    bf, problem = bratu_files["with_draw"]
    module = problem.module
    module.CALLS.clear()
    fig = Figure(layout="constrained")
    draw_panel(fig, _panel(bf, problem))
    n = len(_panel(bf, problem).insets)
    assert len(fig.axes) == n + 1                  # the configurations and the diagram
    assert [shape for shape, _ in module.CALLS] == [(2, len(bf.profile_grid))] * n
    uz = [i for i, t in enumerate(bf.branches[0].columns["type"]) if t == "UZ"]
    assert [p for _, p in module.CALLS] == [{"lam": float(bf.branches[0].columns["lam"][i])}
                                            for i in uz]


def test_a_module_without_draw_gives_the_diagram_alone(bratu_files):
    bf, problem = bratu_files["without_draw"]
    assert not problem.has_draw
    fig = Figure(layout="constrained")
    ax = draw_panel(fig, _panel(bf, problem))
    assert fig.axes == [ax]
    assert len(ax.lines) > 1                        # branch and markers, no numbered points
    assert not any(t.get_text() in ("1", "2", "3") for t in ax.texts)


def test_draw_must_be_a_function_and_gets_a_profile_of_the_states(tmp_path, bratu_files):
    bad = tmp_path / "bad_draw.py"
    bad.write_text((EXAMPLES / "bratu.py").read_text() + "\ndraw = 3\n")
    with pytest.raises(ProblemError, match="draw must be a function"):
        ea.load_problem(str(bad))
    problem = bratu_files["with_draw"][1]
    fig = Figure()
    with pytest.raises(ProblemError, match=r"profile of shape \(2, len\(grid\)\)"):
        problem.draw(fig.add_subplot(), np.zeros((1, 10)), {"lam": 1.0})   # fewer rows than states



# ------------------------------------------------- messages that name their cause (L14)
def _with_tex(source, target, **tex):
    import json
    import shutil

    import h5py
    shutil.copy(source, target)
    with h5py.File(target, "r+") as f:
        f.attrs["tex"] = json.dumps({**json.loads(f.attrs["tex"]), **tex})
    return target


@pytest.mark.parametrize("name, kind", [("m1", "ordinate"), ("psi", "parameter"),
                                        ("P", "parameter")])
def test_a_bad_tex_label_is_one_line_naming_it(viewer_file, cli_exe, tmp_path, name, kind):
    """Hostile turn 5, L14: an invalid TeX label made `plot` print four lines of parser
    output naming neither the module nor the column. One line now, naming both and the
    label; m1 is the ordinate drawn, psi the abscissa, P a value in the figure's title."""
    from helpers import run_cli
    bad = r"$\undefinedcommand{x}$"
    h5 = _with_tex(viewer_file, tmp_path / "tex.h5", **{name: bad})
    proc = run_cli(cli_exe, "plot", h5, "-o", tmp_path / "x.png")
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith(f"elastica-auto: error: {BranchFile(h5).equation}: {kind} "
                                  f"{name!r}: its TeX label {bad} cannot be typeset (")
    assert r"\undefinedcommand" in proc.stderr.split("cannot be typeset")[1]
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("column", ["type", "label", "note", "transition"])
def test_a_text_column_is_not_an_axis(viewer_file, cli_exe, tmp_path, column):
    """Hostile turn 5, L14: `plot -x type` said "could not convert string to float: 'EP'".
    One line now naming the column and listing the numeric ones (read with h5py)."""
    import h5py

    from helpers import run_cli
    with h5py.File(viewer_file, "r") as f:
        g = f["branches/001/columns"]
        numeric = {k for k, d in g.items() if d.dtype.kind in "iuf"} - {"label"}
    for option in ("-x", "-y"):
        proc = run_cli(cli_exe, "plot", viewer_file, option, column, "-o", tmp_path / "x.png")
        assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
        head, _, listed = proc.stderr.strip().partition("; numeric columns: ")
        assert head.endswith(f"{column!r} is not a numeric column of {viewer_file}")
        assert numeric <= set(listed.split(", ")) and column not in listed.split(", ")


def test_an_unknown_column_lists_every_column_plot_accepts(viewer_file, cli_exe, tmp_path):
    """User round: `plot -x nope` listed the parameters and ordinates only, while `-y index`
    works. The list is every numeric column of the file (read with h5py), and each one
    listed is accepted as an axis."""
    import h5py

    from helpers import run_cli
    with h5py.File(viewer_file, "r") as f:
        g = f["branches/001/columns"]
        numeric = {k for k, d in g.items() if d.dtype.kind in "iuf"} - {"label"}
    assert {"index", "arclength"} <= numeric
    proc = run_cli(cli_exe, "plot", viewer_file, "-x", "nope", "-o", tmp_path / "x.png")
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
    head, _, listed = proc.stderr.strip().partition("; columns: ")
    assert head.endswith(f"'nope' is not a column of {viewer_file}")
    # the stored numeric columns, and the branch's and point's numbers the reader adds
    assert set(listed.split(", ")) == numeric | {"branch", "pt"}
    proc = run_cli(cli_exe, "plot", viewer_file, "-y", "index", "-x", "arclength",
                   "-o", tmp_path / "y.png")
    assert proc.returncode == 0, proc.stderr


# ------------------------------------- the line style changes at the fold (issue 45, item 8)
def _style_of(line):
    """The (colour, dash) of a drawn line, to compare with `style.index_style`'s."""
    from matplotlib.colors import to_hex
    return to_hex(line.get_color()), line.get_linestyle()


def _expected_style(k):
    from matplotlib.lines import Line2D

    from elastica_auto.plots.style import index_style
    color, dash, lw = index_style(k)
    return _style_of(Line2D([], [], color=color, ls=dash, lw=lw))


def _folds(path):
    """(x, y, index before, index after) of each fold of the file, in point order, read with
    h5py: psi and m1 at the LP, the index of the points on either side."""
    import h5py
    out = []
    with h5py.File(path, "r") as f:
        for g in f["branches"].values():
            c = {k: g[f"columns/{k}"][()] for k in ("psi", "m1", "index", "type")}
            for i in np.flatnonzero(c["type"] == b"LP"):
                out.append((c["psi"][i], c["m1"][i], int(c["index"][i - 1]),
                            int(c["index"][i + 1])))
    return out


def _check_style_changes_at_the_folds(lines, folds):
    ends = [(ln.get_xydata()[0], ln.get_xydata()[-1], _style_of(ln)) for ln in lines
            if len(ln.get_xydata()) > 1]
    assert folds and all(a != b for _, _, a, b in folds)
    for x, y, before, after in folds:
        assert any(np.array_equal(last, (x, y)) and style == _expected_style(before)
                   for _, last, style in ends), (x, y, before)
        assert any(np.array_equal(first, (x, y)) and style == _expected_style(after)
                   for first, _, style in ends), (x, y, after)


def test_plot_changes_the_line_style_at_the_fold(viewer_file):
    """Issue 45, item 8: the style changed one segment after the fold's circle. Each fold is
    the last point of a line in the style of the index before it and the first of a line in
    the style of the index after it."""
    fig = diagram_figure(BranchFile(viewer_file))
    _check_style_changes_at_the_folds(fig.axes[0].lines, _folds(viewer_file))


def test_the_figures_change_the_line_style_at_the_fold(viewer_file):
    """The same for the paper's diagrams (`layout.draw_branches`, smoothed lines through
    every point)."""
    from elastica_auto.plots.layout import draw_branches
    bf = BranchFile(viewer_file)
    ax = Figure().add_subplot()
    draw_branches(ax, [(bf, b) for b in bf.branches], "psi", "m1")
    _check_style_changes_at_the_folds(ax.lines, _folds(viewer_file))
