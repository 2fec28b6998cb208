"""Every figure target of the Makefile writes its PNG and PDF, from the runs it names, and make
redraws a figure only when its branch files or the plotting code changed.

The figures are drawn by ``make figures`` from the same (reduced) branch files as
tests/test_paper_runs.py; see there.
"""

from __future__ import annotations

import re

import pytest
from PIL import Image

from elastica_auto.plots.paper import FIGURES
from test_paper_runs import REPO, build_paper, make


@pytest.fixture(scope="session")
def drawn(tmp_path_factory, rotating_arm):
    root = tmp_path_factory.getbasetemp() / "paper"
    build_paper(root, rotating_arm.result.path, targets=("runs",))
    return build_paper(root, rotating_arm.result.path, targets=("figures",))


def _stem(name):
    return name.replace("-", "_")


def test_every_paper_figure_has_a_make_target():
    text = (REPO / "Makefile").read_text()
    listed = set(re.findall(r"\$\(eval \$\(call FIGURE,([a-z0-9-]+),", text))
    assert listed == set(FIGURES)
    assert {f.paper for f in FIGURES.values()} == {str(n) for n in range(3, 13)}


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


def test_changed_plotting_code_redraws_every_figure_and_recomputes_nothing(drawn):
    out = _commands(drawn, "figures", "-W", "elastica_auto/plots/layout.py")
    assert "elastica-auto run" not in out
    assert sorted(re.findall(r"elastica_auto\.plots ([a-z0-9-]+)", out)) == sorted(FIGURES)


@pytest.mark.parametrize("run", ["rotating_arm", "arm_length", "rotating_load",
                                 "load_magnitude", "rotating_base"])
def test_drawn_lever_arm_and_load_balance_the_tip_moment(drawn, run):
    """The configurations are drawn the right way round: the lever arm and the load arrow as
    drawn (elastica_auto.plots.config) satisfy the free-end moment balance of the paper,
    m(1).e_z = (Psi x F).e_z, on every stored point; an arm drawn at theta(1) + psi, or a
    reversed load, would not."""
    from elastica_auto.plots.config import geometry
    from elastica_auto.store import BranchFile
    import numpy as np

    bf = BranchFile(drawn / "out" / f"{run}.h5")
    n = 0
    for b in bf.branches:
        for i in range(0, len(b), 7):
            p = {q: float(b.columns[q][i]) for q in bf.parameters}
            g = geometry(b.profiles[i], p)
            arm = g.arm_end - g.tip
            F = abs(p["P"]) * g.load
            moment = arm[0] * F[1] - arm[1] * F[0]
            assert abs(np.hypot(*arm) - abs(p["eps"])) < 1e-12
            assert moment == pytest.approx(b.profiles[i][1, -1], abs=1e-5 * (1 + abs(p["P"])))
            n += 1
    assert n > 20
