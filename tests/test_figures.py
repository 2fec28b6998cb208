"""Every figure target of the Makefile writes its PNG and PDF, from the runs it names, and make
redraws a figure only when its branch files or the plotting code changed. The figure registry
is the one source of which figure reads which runs: the Makefile's rules are generated from
it, and docs/figures.md lists the same.

The figures are drawn by ``make figures`` from the same (reduced) branch files as
tests/test_paper_runs.py; see there.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.figure import Figure
from PIL import Image

from elastica_auto.plots.__main__ import make_rules
from elastica_auto.plots.paper import FIGURES, in_paper_order
from elastica_auto.model.problem import load_problem
from elastica_auto.storage.store import BranchFile
from test_paper_runs import REPO, build_paper, make

#: one worker of `pytest -n` builds the reduced paper runs for both files (make test)
pytestmark = pytest.mark.xdist_group("paper")


@pytest.fixture(scope="session")
def drawn(tmp_path_factory, rotating_arm):
    root = tmp_path_factory.getbasetemp() / "paper"
    build_paper(root, rotating_arm.result.path, targets=("runs",))
    return build_paper(root, rotating_arm.result.path, targets=("figures",))


def _stem(name):
    return name.replace("-", "_")


def test_the_make_rules_give_each_figure_its_runs_and_each_run_its_restarts():
    rules = make_rules(REPO / "runs")
    calls = re.findall(r"^\$\(eval \$\(call FIGURE,([a-z0-9-]+),([a-z0-9_ ]+)\)\)", rules, re.M)
    assert calls == [(f.name, " ".join(f.runs)) for f in in_paper_order()]
    assert [f.paper for f in in_paper_order()] == [str(n) for n in range(3, 13)] + [""] * (
        len(FIGURES) - 10)
    chains = dict(re.findall(r"^\$\(OUT\)/(\w+)\.h5: (.+)$", rules, re.M))
    for path in (REPO / "runs").glob("*.toml"):
        text = "\n".join(ln for ln in path.read_text().splitlines()
                         if not ln.lstrip().startswith("#"))
        needs = sorted({a or b for a, b in re.findall(r'file = "(\w+)\.h5"|"(\w+)\.h5:', text)})
        assert chains.get(path.stem, "") == " ".join(f"$(OUT)/{r}.h5" for r in needs), path.stem
    runs = re.search(r"^PAPER_RUNS = (.+)$", rules, re.M).group(1).split()
    assert set(runs) >= {r for f in FIGURES.values() for r in f.runs}
    for run in runs:       # every run after the runs it restarts from
        for need in re.findall(r"\$\(OUT\)/(\w+)\.h5", chains.get(run, "")):
            assert runs.index(need) < runs.index(run)
    assert "buckled_load" in runs     # read by no figure, restarted from by one


def test_the_docs_list_the_figures_of_the_registry():
    """docs/figures.md: the targets table is the registry, row by row, and the gallery has a
    heading and the image of every figure."""
    text = (REPO / "docs" / "figures.md").read_text()
    rows = [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in text.splitlines() if line.startswith("| `fig-")]
    expected = [[f"`fig-{f.name}`", f.paper, f.shows, ", ".join(f.runs)]
                for f in in_paper_order()]
    assert rows == expected, "docs/figures.md targets table: expected\n" + "\n".join(
        "| " + " | ".join(r) + " |" for r in expected)
    for f in FIGURES.values():
        which = f"Figure {f.paper}" if f.paper else "Beyond the paper"
        assert re.search(rf"^### {which}: .* \u2014 `make fig-{f.name}`$", text, re.M)
        assert f"(img/{_stem(f.name)}.png)" in text


@pytest.mark.parametrize("name", sorted(FIGURES))
def test_figure_target_writes_png_and_pdf(drawn, name):
    png, pdf = drawn / "fig" / f"{_stem(name)}.png", drawn / "fig" / f"{_stem(name)}.pdf"
    assert png.is_file() and pdf.is_file(), f"make fig-{name} wrote no {png.name}/{pdf.name}"
    with Image.open(png) as im:
        im.verify()
    with Image.open(png) as im:
        assert im.format == "PNG" and im.width >= 1200 and im.height >= 600
    head = pdf.read_bytes()[:5]
    assert head == b"%PDF-" and pdf.stat().st_size > 10_000
    # up to date once drawn
    assert make(drawn, f"fig-{name}", check=False, extra=("-q",)).returncode == 0


def _commands(root, *args):
    proc = make(root, *args, check=False, extra=("-n",))
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_a_changed_run_file_redraws_only_the_figures_that_need_it(drawn):
    """``make -n -W runs/load_magnitude.toml figures``: load_magnitude is recomputed and the
    two figures reading it are redrawn, nothing else."""
    out = _commands(drawn, "figures", "-W", str(drawn / "runs" / "load_magnitude.toml"))
    runs = re.findall(r"elastica-auto run \S*?/(\w+)\.toml", out)
    figs = re.findall(r"elastica_auto\.plots ([a-z0-9-]+)", out)
    assert runs == ["load_magnitude"]
    assert sorted(figs) == ["load-magnitude-tilted", "load-magnitude-vertical"]


def test_a_changed_restart_file_recomputes_the_chain(drawn):
    """rotating_load restarts from rotating_arm, load_magnitude from rotating_load."""
    out = _commands(drawn, "fig-load-magnitude-tilted", "-W",
                    str(drawn / "runs" / "rotating_load.toml"))
    assert re.findall(r"elastica-auto run \S*?/(\w+)\.toml", out) == ["rotating_load",
                                                                       "load_magnitude"]


def test_a_changed_registry_rewrites_the_rules_but_draws_nothing_new(drawn):
    """The generated rules follow the registry; regenerating them is silent and redraws
    nothing that is up to date."""
    out = _commands(drawn, "figures", "-W", "elastica_auto/plots/paper.py")
    assert "elastica-auto run" not in out and "--make-rules" not in out
    assert sorted(re.findall(r"elastica_auto\.plots ([a-z0-9-]+)", out)) == sorted(FIGURES)
    assert (drawn / "out" / ".paper-rules.mk").read_text() == make_rules(drawn / "runs")


def test_changed_plotting_code_redraws_every_figure_and_recomputes_nothing(drawn):
    out = _commands(drawn, "figures", "-W", "elastica_auto/plots/layout.py")
    assert "elastica-auto run" not in out
    assert sorted(re.findall(r"elastica_auto\.plots ([a-z0-9-]+)", out)) == sorted(FIGURES)


@pytest.mark.parametrize("run", ["rotating_arm", "arm_length", "rotating_load",
                                 "load_magnitude", "rotating_base"])
def test_drawn_lever_arm_and_load_balance_the_tip_moment(drawn, run):
    """The configurations are drawn the right way round: the lever arm and the load arrow as
    the module's draw hook draws them satisfy the free-end moment balance of the paper,
    m(1).e_z = (Psi x F).e_z, on every stored point; an arm drawn at theta(1) + psi, or a
    reversed load, would not."""
    bf = BranchFile(drawn / "out" / f"{run}.h5")
    problem = load_problem(bf.equation)
    n = 0
    ax = Figure().add_subplot()     # one axes, emptied after each configuration (a new one
    for b in bf.branches:           # costs twice the drawing)
        for i in range(0, len(b), 7):
            p = {q: float(b.columns[q][i]) for q in bf.parameters}
            for artist in [*ax.lines, *ax.texts, *ax.patches, *ax.collections]:
                artist.remove()
            problem.draw(ax, b.profiles[i], p)
            (arm,) = [ln for ln in ax.lines if ln.get_gid() == "lever arm"]
            tip, end = np.array(arm.get_xydata())
            assert tip == pytest.approx(b.profiles[i][2:4, -1], abs=1e-12)
            arm = end - tip
            (load,) = [t for t in ax.texts if t.get_gid() == "load"]
            head, tail = np.array(load.xy), np.array(load.xyann)
            assert head == pytest.approx(end, abs=1e-12)
            F = abs(p["P"]) * (head - tail) / np.hypot(*(head - tail))
            moment = arm[0] * F[1] - arm[1] * F[0]
            assert abs(np.hypot(*arm) - abs(p["eps"])) < 1e-12
            assert moment == pytest.approx(b.profiles[i][1, -1], abs=1e-5 * (1 + abs(p["P"])))
            n += 1
    assert n > 20


def test_a_changed_c_file_recomputes_the_runs(tmp_path):
    """The compiled banded LU is part of the engine: a change to its C file (rebuilt by
    make's install step) recomputes a branch file as a change to a Python module does, and
    nothing else does. An up-to-date stand-in file is enough: ``make -n`` only decides."""
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "rotating_arm.toml").write_text(
        (REPO / "runs" / "rotating_arm.toml").read_text())
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "rotating_arm.h5").write_bytes(b"")
    target = str(tmp_path / "out" / "rotating_arm.h5")
    assert "elastica-auto run" not in _commands(tmp_path, target)
    for changed in ("elastica_auto/numerics/_banded.c", "elastica_auto/numerics/newton.py"):
        assert re.findall(r"elastica-auto run \S*?/(\w+)\.toml",
                          _commands(tmp_path, target, "-W", changed)) == ["rotating_arm"]
