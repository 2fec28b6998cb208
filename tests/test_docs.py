"""The docs describe the code as it is: the design's module table names every module, the
index links every page, and the figure pages count the registry's figures."""

from __future__ import annotations

import re

from elastica_auto.plots.paper import FIGURES
from helpers import REPO

DOCS = REPO / "docs"
WORDS = {4: "four", 5: "five", 6: "six", 7: "seven", 8: "eight"}


def test_the_design_lists_every_module():
    table = (DOCS / "design.md").read_text()
    modules = [p.relative_to(REPO).as_posix()
               for d in ("elastica_auto", "elastica_auto/plots", "equations")
               for p in sorted((REPO / d).glob("*.py")) if p.name != "__init__.py"]
    assert modules
    missing = [m for m in modules if f"| `{m}` |" not in table]
    assert not missing, f"docs/design.md, module layout: no row for {missing}"


def test_the_index_links_every_page():
    index = (DOCS / "index.md").read_text()
    linked = set(re.findall(r"\]\(([\w-]+\.md)\)", index))
    pages = {p.name for p in DOCS.glob("*.md")} - {"index.md"}
    assert pages and pages == linked, (pages - linked, linked - pages)


def test_the_figure_pages_count_the_figures_beyond_the_paper():
    beyond = WORDS[len(FIGURES) - 10]       # the paper's figures 3-12 are ten
    for page in ("index.md", "figures.md"):
        text = " ".join((DOCS / page).read_text().split())
        assert f"and {beyond} beyond it" in text, page
