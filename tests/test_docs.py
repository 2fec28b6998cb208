"""The docs describe the code as it is: the design's module table names every module, the
index links every page, and the figure pages count the registry's figures."""

from __future__ import annotations

import re

from elastica_auto.plots.paper import FIGURES
from helpers import REPO

DOCS = REPO / "docs"
#: Folders of the package that are not the engine's (links to the shipped equations and runs).
NOT_ENGINE = {"equations", "runs"}
WORDS = {4: "four", 5: "five", 6: "six", 7: "seven", 8: "eight"}


def test_the_design_lists_every_module():
    """Issue 48 item 5: every module of the package, in every folder (not only the top and
    plots: branches/mirror.py and numerics/ode.py went unnoticed), and every equation module
    has a row; a layer's ``__init__.py`` is its line in the layers' diagram instead."""
    table = (DOCS / "design.md").read_text()
    package = REPO / "elastica_auto"
    modules = [p.relative_to(REPO).as_posix() for p in sorted(package.rglob("*.py"))
               if p.parent.name not in NOT_ENGINE and "__pycache__" not in p.parts
               and (p.name != "__init__.py" or p.parent == package)]
    modules += [p.relative_to(REPO).as_posix() for p in sorted((REPO / "equations").glob("*.py"))
                if p.name != "__init__.py"]
    assert {"elastica_auto/branches/mirror.py", "elastica_auto/numerics/ode.py",
            "elastica_auto/__init__.py"} <= set(modules)
    missing = [m for m in modules if f"| `{m}` |" not in table]
    assert not missing, f"docs/design.md, module layout: no row for {missing}"
    diagram = table[table.index("### Layers"):]
    folders = {p.parent.name for p in package.glob("*/__init__.py")} - NOT_ENGINE
    assert sorted(f for f in folders if not re.search(rf"^ *{f}\b", diagram, re.M)
                  and f != "plots") == []


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


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading: its text (a link's text for a link), lower case,
    every character but letters, digits, ``_``, ``-`` and spaces dropped, each space a ``-``."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(page) -> set[str]:
    """The anchors of a Markdown page's headings (outside code blocks); a repeated heading's
    second anchor gets ``-1``, its third ``-2``, as on GitHub."""
    found, seen, fence = set(), {}, False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            fence = not fence
        m = None if fence else re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)
        if m:
            s = slug(m.group(1))
            found.add(f"{s}-{seen[s]}" if s in seen else s)
            seen[s] = seen.get(s, 0) + 1
    return found


def broken_anchors(pages) -> list[str]:
    """Every link ``[text](#anchor)`` or ``[text](page.md#anchor)`` in ``pages`` whose page
    has no heading with that anchor."""
    bad = []
    for page in pages:
        for m in re.finditer(r"\]\(([\w./-]*)#([^)\s]+)\)", page.read_text()):
            target = (page.parent / m.group(1)) if m.group(1) else page
            if not target.is_file() or m.group(2) not in anchors(target):
                bad.append(f"{page.name}: {m.group(0)[1:]}")
    return bad


def test_the_slugs_are_githubs():
    """Headings of these pages with the anchors GitHub gives them (their links work there)."""
    assert slug("Gauss collocation (`ncol = 2 .. 7`)") == "gauss-collocation-ncol--2--7"
    assert slug("`uz`, `uz_period`") == "uz-uz_period"
    assert slug("Worked example: the rotating arm") == "worked-example-the-rotating-arm"
    assert slug("The [rod](three-d.md) in 3D") == "the-rod-in-3d"


def test_every_anchor_of_a_link_between_the_docs_is_a_heading(tmp_path):
    """Issue 45 item 8: kirchhoff.md linked #checks, a heading lost when sections were put
    before it. Every anchor of a link in docs/, README.md and CHANGELOG.md names a heading of
    its page; the check sees a stale one (a heading inside a code block is no heading)."""
    pages = sorted(DOCS.glob("*.md")) + [REPO / "README.md", REPO / "CHANGELOG.md"]
    assert broken_anchors(pages) == []
    page = tmp_path / "page.md"
    page.write_text("# Page\n\n[checks](#checks), [ok](#page), [other](page.md#code)\n\n"
                    "```\n# code\n```\n")
    assert broken_anchors([page]) == ["page.md: (#checks)", "page.md: (page.md#code)"]


def test_the_api_page_names_everything_public():
    """Issue 45 item 1: docs/api.md names every top-level name, every name of the module
    protocol (as `Problem` reads them), every run-file key, every command and exit status,
    and every deprecated module of the flat layout."""
    import elastica_auto
    from elastica_auto.cli import main
    from elastica_auto.core import errors, moved
    from elastica_auto.core.options import ContinuationOptions
    from elastica_auto.execution import runfile
    from dataclasses import fields
    text = (DOCS / "api.md").read_text()
    source = (REPO / "elastica_auto" / "model" / "problem.py").read_text()
    protocol = set(re.findall(r'getattr\(module, "(\w+)"', source)) | {
        n for n in re.findall(r"\bmodule\.([A-Za-z]\w*)", source)}
    keys = (runfile.TOP_KEYS | runfile.CONTINUATION_KEYS | runfile.SELECTOR_KEYS
            | {"scheduler", "from", "to", "num"} | {f.name for f in fields(ContinuationOptions)})
    tables = {"parameters", "continuation", "options", "execution"}
    expected = {f"`[{n}]`" if n in tables else f"`{n}`"
                for n in [*elastica_auto.__all__, "FORMAT_VERSION", *protocol, *keys,
                          *main.commands]}
    expected |= {f"{code} (" for code in errors.EXIT_STATUSES}
    expected |= {f"`{old}`" if f"`elastica_auto.{old}`" not in text else f"`elastica_auto.{old}`"
                 for old in [*moved.MOVED, *moved.REMOVED_MODULES]}
    assert len(protocol) >= 24 and "shooting" in protocol
    assert sorted(n for n in expected if n not in text) == []


RUN_FILES = DOCS / "run-files.md"


def test_the_run_file_error_examples_print_what_the_program_prints(tmp_path, cli_exe):
    """Issue 45 item 8: run-files.md's error example listed [continuation]'s keys of an older
    version. Each run file the page shows (a ```toml block starting ``# NAME.toml``) is run as
    its ``$ elastica-auto run NAME.toml`` block says, and prints what the block shows."""
    from helpers import run_cli
    text = RUN_FILES.read_text()
    files = dict(re.findall(r"```toml\n# (\w+\.toml)\n(.*?)```", text, re.S))
    runs = re.findall(r"```\n\$ elastica-auto run (\w+\.toml)\n(.*?)```", text, re.S)
    assert len(files) >= 2 and sorted(f for f, _ in runs) == sorted(files)
    for name, body in files.items():
        (tmp_path / name).write_text(body)
    for name, shown in runs:
        proc = run_cli(cli_exe, "run", name, "--out", tmp_path / "out", cwd=tmp_path)
        assert proc.returncode == 2
        assert proc.stdout + proc.stderr == shown, name


def test_no_page_cites_an_outside_address():
    """The docs say things in the project's own words: no page links or names an http(s)
    address (docs/cluster.md linked the Dask and dask-jobqueue sites, docs/energy.md
    sympy's); a package is named by its name."""
    cited = [f"{p.relative_to(REPO)}:{n}: {m.group(0)}"
             for p in sorted(DOCS.rglob("*.md"))
             for n, line in enumerate(p.read_text().splitlines(), start=1)
             for m in re.finditer(r"(?i)\bhttps?://\S*", line)]
    assert not cited, cited
