"""The interactive viewer (``elastica-auto view``, ``ea.view``): a branch file's bifurcation
diagram and the configuration of the point under the mouse, side by side, in one
self-contained HTML page (Plotly's JavaScript embedded: it works offline and can be mailed).

The page holds the file's columns (every parameter and ordinate of every point, the index,
the labels and their index transitions), one PNG per labelled point drawn by the equation
module's ``draw`` hook, and the snap-back table. The module is the shipped one the file names,
or one the caller gives: a module the file names by a path is not imported
(`layout.equation_problem`; docs/trust.md), and the page says why it has no configurations.
Plotly draws, zooms, pans, toggles branches from the legend and finds the point under the
mouse; the page's own script (`viewer.js` beside this module) only builds the traces of the
chosen panel and columns, in the styles of ``elastica-auto plot`` (`style`), and links a
point to the side panel. Nothing is computed but pictures of stored profiles.
"""

from __future__ import annotations

import base64
import ctypes
import html
import io
import json
import math
import os
import re
import signal
import sys
import tempfile
import threading
import warnings
from importlib.resources import files
from pathlib import Path

import numpy as np

from ..core.labels import FOLDS, TURNS, compact, label_order
from ..core.errors import USER_ERRORS
from ..storage.outputs import check_output as _check_output
from ..storage.outputs import write_output
from ..storage.store import BranchFile
from .diagram import (MARKED, MARKER_TEXT, default_columns, fixed_parameters, panel_groups,
                      period_of)
from .style import MARKERS, SNAP_COLOR, UNLOCATED, index_label, index_style

#: Size of a configuration image: inches at dots per inch (the side panel shows it at 240 px).
IMAGE_INCHES, IMAGE_DPI = 3.0, 80
#: Colours kept per image: the drawings are a few flat colours, and a palette PNG of them is
#: about 1 kB against 4 kB in full colour (340 labels fit beside Plotly's 4.8 MB in 8 MB).
IMAGE_COLORS = 32
#: Matplotlib marker -> Plotly symbol, for the labelled points (`style.MARKERS`).
SYMBOLS = {"o": "circle", "x": "x-thin", "s": "square", "D": "diamond", "X": "x"}
#: Height of the page inline in a notebook (pixels).
NOTEBOOK_HEIGHT = 760


class View:
    """A viewer page: ``html`` (the whole document), the ``path`` it was written to, if any,
    and its ``images`` (`Images`: what was drawn, and what is missing). In a Jupyter notebook
    the object shows the page inline (in an iframe, so that the page's script and ids stay
    its own)."""

    def __init__(self, html_text: str, path: Path | None = None, images: Images | None = None):
        self.html, self.path = html_text, path
        self.images = images if images is not None else Images()

    def _repr_html_(self) -> str:
        return (f'<iframe srcdoc="{html.escape(self.html)}" style="width:100%; '
                f'height:{NOTEBOOK_HEIGHT}px; border:0"></iframe>')

    def __repr__(self) -> str:
        where = f" written to {self.path}" if self.path else ""
        return f"<elastica-auto view{where}: {len(self.html) / 1e6:.1f} MB>"


def _png(fig) -> str:
    """The figure's canvas as a palette PNG data URI."""
    from PIL import Image
    fig.canvas.draw()
    rgb = Image.frombuffer("RGBA", fig.canvas.get_width_height(),
                           fig.canvas.buffer_rgba()).convert("RGB")
    buf = io.BytesIO()
    rgb.quantize(IMAGE_COLORS, method=Image.Quantize.FASTOCTREE).save(buf, format="png")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


class Images(dict):
    """Label -> PNG data URI of each configuration drawn, and what is missing: ``failed``
    {label: the ``draw`` hook's error, on one line} for the labels whose drawing raised, and
    ``reason``, why there are none at all ("" where the module draws); ``untrusted``: the
    reason is that the file names a module that is not shipped (and none was given)."""

    def __init__(self, images=(), failed: dict | None = None, reason: str = "",
                 untrusted: bool = False):
        super().__init__(images)
        self.failed, self.reason, self.untrusted = failed or {}, reason, untrusted

    def failure_line(self) -> str:
        """The labels whose drawing raised and the hook's errors, on one line ("" if none)."""
        by_error: dict[str, list[str]] = {}
        for label, error in self.failed.items():
            by_error.setdefault(error, []).append(label)
        return "; ".join(f"{compact(sorted(labels, key=label_order))}: draw hook "
                         f"failed ({error})" for error, labels in by_error.items())


def configuration_images(bf: BranchFile, problem=None, workers: int | None = None) -> Images:
    """One PNG data URI per label of ``bf``: its stored profile drawn by the ``draw`` hook of
    ``problem`` (default: the shipped equation module the file names; a module it names by a
    path is not imported), filling a square image. A label whose drawing raises gets none
    (`Images.failed`); none at all if the module is not shipped and not given, or has no
    ``draw`` hook (`Images.reason`).

    ``workers``: processes that draw (each a fork of this one, given every ``workers``-th
    label); default `drawing_workers` of the labels' count. The images are the same
    whichever process drew them."""
    from .layout import UntrustedEquation, equation_problem
    if problem is None:
        try:
            problem = equation_problem(bf.equation)
        except UntrustedEquation as exc:
            return Images(reason=str(exc), untrusted=True)
        except USER_ERRORS as exc:
            return Images(reason=str(exc))
    if not problem.has_draw:
        return Images(reason="the equation module has no draw hook")
    if not bf.labels:
        return Images()
    by_number = {b.number: b for b in bf.branches}
    # what each drawing needs, read here (a drawing process reads no file): the labels'
    # profiles, those of a branch at one reading
    rows: dict[int, list[int]] = {}
    for br, pt in bf.labels.values():
        rows.setdefault(br, []).append(pt - 1)
    profiles = {br: iter(by_number[br].profiles_at(r)) for br, r in rows.items()}
    drawings = []
    for br, pt in bf.labels.values():
        b = by_number[br]
        drawings.append((next(profiles[br]),
                         {q: float(b.columns[q][pt - 1]) for q in bf.parameters}))
    workers = drawing_workers(len(drawings)) if workers is None else workers
    if workers > 1:
        drawn = _draw_forked(problem, drawings, workers)
    else:
        drawn = _draw(problem, drawings)
    return Images({name: image for name, (image, _) in zip(bf.labels, drawn) if image},
                  {name: error for name, (_, error) in zip(bf.labels, drawn) if error})


#: Drawings per process below which `drawing_workers` adds no process: starting and ending
#: one costs about 25 ms here, five of the elastica's drawings (two of the spatial rod's);
#: 16 labels drew in 0.060 s on two processes against 0.078 s on one.
DRAWINGS_PER_WORKER = 16
#: At most this many drawing processes: each holds about 100 MB resident (matplotlib and
#: its figure; rotating_arm_3d's), and past a few the page's other work (about 1 s of
#: imports and data for that file) is most of what is left.
MAX_DRAWING_WORKERS = 8


def drawing_workers(count: int) -> int:
    """How many processes draw ``count`` configurations: one per core this process may use,
    at most one per DRAWINGS_PER_WORKER drawings and MAX_DRAWING_WORKERS in all, and 1 (this
    process) unless it runs on Linux with no other thread (a forked child inherits only the
    forking thread, and a lock another thread held stays held in it: a notebook's kernel, a
    Dask client)."""
    if not sys.platform.startswith("linux") or threading.active_count() > 1:
        return 1
    return max(1, min(len(os.sched_getaffinity(0)), count // DRAWINGS_PER_WORKER,
                      MAX_DRAWING_WORKERS))


def _draw(problem, drawings) -> list[tuple[str, str]]:
    """(image, "") of each of ``drawings`` ((profile, parameters) pairs) by ``problem``'s
    draw hook, in order, on one figure; ("", the hook's error) where the hook raised."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .layout import data_box, hook_error
    fig = Figure(figsize=(IMAGE_INCHES, IMAGE_INCHES), dpi=IMAGE_DPI)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1), projection=getattr(problem, "draw_projection", None))
    ax.set_axis_off()
    out = []
    for profile, params in drawings:
        # removing the last drawing's artists is 50x faster than clearing the axes; the data
        # limits then start afresh (2D: by the flag; 3D: each plot call starts them anew on
        # axes without data)
        for artist in [*ax.lines, *ax.patches, *ax.texts, *ax.collections, *ax.images]:
            artist.remove()
        ax.ignore_existing_data_limits = True
        try:
            problem.draw(ax, profile, params)
        except (Exception, SystemExit) as exc:   # the module's: this label gets no image
            out.append(("", hook_error(exc, problem)))
            continue
        box = data_box(ax)
        if np.all(np.isfinite(box)):
            # a square (cube) around the drawing, 8% margin each side: one scale for all
            # would need every drawing twice (the hook's artists cost more than the rendering)
            centre = box.mean(axis=1)
            half = max(np.max(box[:, 1] - box[:, 0]), 1e-12) * (0.5 + 0.08)
            for k, set_lim in enumerate((ax.set_xlim, ax.set_ylim, getattr(ax, "set_zlim",
                                                                            None))[:len(box)]):
                set_lim(centre[k] - half, centre[k] + half)
            if ax.name == "3d":
                ax.set_box_aspect((1, 1, 1))
        out.append((_png(fig), ""))
    return out


#: What the forked drawing processes draw: (problem, drawings, workers), set while they run.
_FORKED = None


def _draw_share(k: int) -> list[tuple[str, str]]:
    """In drawing process ``k``: its share of the drawings, every ``workers``-th from the
    k-th (alternate ones, so that slow stretches of a branch are shared)."""
    problem, drawings, workers = _FORKED
    return _draw(problem, drawings[k::workers])


#: prctl(2)'s option that sends the calling process a signal when its parent ends.
PR_SET_PDEATHSIG = 1


def _die_with(parent: int):
    """In a drawing process, first: end when ``parent`` (the command) ends, however it ends.
    A drawing process blocks on its pipe to a parent that is gone, and a SIGKILLed command
    runs no code that could end it: the kernel sends it SIGKILL then (Linux, where the
    processes are forked at all; `drawing_workers`). If the parent ended before that was
    set, this process ends at once. Ctrl-C and SIGTERM are the parent's to act on (it ends
    these processes), not each drawing process's."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    libc = ctypes.CDLL(None)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:
        os._exit(1)


def _draw_forked(problem, drawings, workers: int) -> list[tuple[str, str]]:
    """`_draw` shared among ``workers`` forked processes, which inherit the problem and the
    drawings (nothing pickled but the images); drawn here if a process fails to start or
    dies. Interrupted (Ctrl-C, or SIGTERM where the command raises KeyboardInterrupt for
    it), the drawing processes are ended at once, not waited for."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    global _FORKED
    _FORKED, pool = (problem, drawings, workers), None
    try:
        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                                   initializer=_die_with, initargs=(os.getpid(),))
        shares = list(pool.map(_draw_share, range(workers)))
    except BaseException as exc:
        broken = isinstance(exc, (BrokenProcessPool, OSError))
        if pool is not None and not broken:
            # each process holds a share of every drawing: waiting for them would take as
            # long as the drawing itself (no public way to end them before Python 3.14)
            for process in list((getattr(pool, "_processes", None) or {}).values()):
                process.kill()
        if not broken:
            raise
        shares = None
    finally:
        if pool is not None:
            pool.shutdown(wait=True)
        _FORKED = None
    if shares is None:
        return _draw(problem, drawings)
    out = [None] * len(drawings)
    for k, share in enumerate(shares):
        out[k::workers] = share
    return out


def _numbers(a) -> list:
    """A column as JSON numbers, ``None`` (a gap) where not finite."""
    return [float(v) if math.isfinite(v) else None for v in np.asarray(a, dtype=float)]


def trace_style(k: int) -> dict:
    """Plotly line keywords of stability index ``k``: `style.index_style`, its dashes (in
    line widths, as matplotlib scales them) in pixels."""
    from matplotlib.colors import to_hex
    color, dash, width = index_style(k)
    dashes = "solid" if dash == "-" else ",".join(f"{v * width:.3g}px" for v in dash[1])
    return {"color": to_hex(color), "dash": dashes, "width": width, "label": index_label(k)}


def _marker(kind: str) -> dict:
    from matplotlib.colors import to_hex
    symbol, face, edge, size, width = MARKERS[kind]
    return {"symbol": SYMBOLS[symbol], "color": to_hex(face), "size": 2.4 * size,
            "line": {"color": to_hex(edge), "width": 1.5 * width}, "text": MARKER_TEXT[kind]}


def _nearest_labelled(arclength: np.ndarray, labelled: np.ndarray) -> list[int]:
    """For each point, the row of the labelled point nearest in arclength (-1: none)."""
    rows = np.flatnonzero(labelled)
    if not len(rows):
        return [-1] * len(arclength)
    order = np.argsort(arclength[rows], kind="stable")
    rows, s = rows[order], arclength[rows][order]
    right = np.searchsorted(s, arclength).clip(0, len(s) - 1)
    left = (right - 1).clip(0)
    # the one before on a tie, as the nearer of the two neighbours among the labelled
    before = np.abs(arclength - s[left]) <= np.abs(arclength - s[right])
    return np.where(before, rows[left], rows[right]).tolist()


def page_data(bf: BranchFile, xname: str | None = None, yname: str | None = None,
              fold: bool = False, file_name: str | None = None, problem=None) -> dict:
    """What the page shows, as JSON-ready data: the columns and labels of every branch, the
    panels (`diagram.panel_groups`), the styles, the snap-back table and the configurations
    (``images``, an `Images`, drawn by ``problem``: see `configuration_images`) with, for
    each label without one, why (``missing``, and ``no_images`` for all of them).
    ``file_name``: the branch file as the restart strings name it (default: ``bf.path``).
    ValueError (one line) for a column the file lacks or that is not numeric, and for a
    period that is not a positive finite number."""
    xname, yname = default_columns(bf, xname, yname)
    periods = {q: period_of(bf, q) for q in bf.periods}     # each checked: the page folds any
    if fold:
        period_of(bf, xname, "--fold")
    varying, groups = panel_groups(bf, xname)
    # any other column asked for (arclength, say) is shown too
    columns = [*bf.parameters, *bf.ordinates,
               *dict.fromkeys(q for q in (xname, yname) if q not in bf.parameters + bf.ordinates)]
    branches, indices = [], set()
    for b in bf.branches:
        if not len(b):
            continue
        c = b.columns
        c.load([*columns, "index", "type", "label", "transition", "fold_residual",
                "arclength"])
        labels = [str(s) for s in c["label"]]
        types = [str(t) for t in c["type"]]
        marks = {}
        for i, t in enumerate(types):
            if t in MARKED:
                kind = UNLOCATED if t in FOLDS and not np.isfinite(c["fold_residual"][i]) else t
                marks.setdefault(kind, []).append(i)
        index = [int(k) if k >= 0 else -1 for k in c["index"]]
        indices |= set(index)
        branches.append({
            "number": b.number,
            "name": f"branch {b.number} ({'+' if b.attrs['direction'] > 0 else '-'})",
            "columns": {q: _numbers(c[q]) for q in columns},
            "index": index,
            "labels": labels,
            "transitions": [str(s) for s in c["transition"]],
            "marks": marks,
            "near": _nearest_labelled(np.asarray(c["arclength"], float),
                                      np.array([bool(t) for t in types])),
        })
    fixed = [q for q in fixed_parameters(bf, xname) if q not in varying]
    panels = [{"title": ", ".join(f"{q}={float(members[0].columns[q][0]):.6g}"
                                  for q in [*varying, *fixed]),
               "branches": [b.number for b in members]} for _, members in groups]
    snaps = [{"lp": r["lp"], "branch": int(r["branch"]),
              "target": {o: _numbers([r["target_" + o]])[0] for o in bf.ordinates
                         if "target_" + o in r}}
             for r in bf.snaps]
    images = configuration_images(bf, problem)
    if images.untrusted:
        no_images = (f"{images.reason}; pass the module to draw them (elastica-auto view "
                     "--equation PATH)")
    else:
        no_images = images.reason
    return {
        "title": f"{bf.run}: {len(branches)} branch{'es' if len(branches) != 1 else ''} "
                 f"of {Path(bf.equation).name}",
        "file": str(file_name or bf.path),
        "parameters": bf.parameters, "ordinates": bf.ordinates, "columns": columns,
        "x": xname, "y": yname, "fold": fold, "periods": periods,
        "panels": panels, "branches": branches,
        "labels": {name: list(where) for name, where in bf.labels.items()},
        "styles": {str(k): trace_style(k) for k in sorted(indices, key=lambda k: (k < 0, k))},
        "markers": {kind: _marker(kind) for kind in MARKERS},
        "turns": [*sorted(TURNS), UNLOCATED],
        "snaps": snaps, "snap_color": SNAP_COLOR,
        "images": images,
        "missing": {label: f"draw hook failed ({error})" for label, error in images.failed.items()},
        "no_images": no_images,
    }


#: What `_script_json` escapes: "<" (so that neither "</script" nor "<!--" can change how
#: the HTML parser reads the element: "<!--<script" anywhere puts it in a state where the
#: next "</script>" does not end it, and the viewer's own script is swallowed), and ">" and
#: "&" with it, so that no text of the data is markup in any context. JSON.parse reads the
#: escapes back as the characters.
SCRIPT_ESCAPES = {ord("<"): "\\u003c", ord(">"): "\\u003e", ord("&"): "\\u0026"}


def _script_json(data) -> str:
    """JSON to put inside a <script> element: no "<", ">" or "&" (`SCRIPT_ESCAPES`)."""
    return json.dumps(data, separators=(",", ":"), allow_nan=False).translate(SCRIPT_ESCAPES)


def page(bf: BranchFile, xname: str | None = None, yname: str | None = None,
         fold: bool = False, file_name: str | None = None, problem=None) -> str:
    """The viewer's HTML document for ``bf`` (see `page_data` for the arguments)."""
    return render(page_data(bf, xname, yname, fold, file_name, problem))


def render(data: dict) -> str:
    """The viewer's HTML document of `page_data`'s ``data``."""
    from plotly.offline import get_plotlyjs     # after page_data has checked the columns
    here = files(__package__)
    parts = {"TITLE": html.escape(data["title"]), "PLOTLY": get_plotlyjs(),
             "DATA": _script_json(data), "VIEWER": (here / "viewer.js").read_text()}
    # in one pass: what is put in is not searched for the next placeholder
    return re.sub(r"\{\{([A-Z]+)\}\}", lambda m: parts[m[1]],
                  (here / "viewer.html").read_text())


def check_output(output, source: Path | None) -> Path:
    """``output`` as a Path; StoreError if it is the branch file ``source``, a folder or an
    HDF5 file (`storage.outputs.check_output`; checked before the page is made, and again as
    it is written)."""
    return _check_output(output, source, "the page", "viewed")


def write_page(text: str, output: Path, source: Path | None = None) -> Path:
    """Write ``text`` to ``output`` through a temporary file renamed over it, so that a failed
    write leaves ``output`` as it was. StoreError if ``output`` is refused (`check_output`),
    WriteError if it cannot be written."""
    return write_output(output, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"),
                        source, "the page", "viewed")


def equation_module(equation, bf: BranchFile | None = None):
    """The problem ``equation`` names (a problem, a shipped name or a ``.py`` path, which is
    imported: the caller trusts it), checked to be the module of ``bf`` by its file name, as
    for a restart (before it is imported). ProblemError (one line) otherwise."""
    from ..core.errors import ProblemError
    from ..model.interface import ProblemInterface
    from ..model.problem import load_problem
    given = equation.source if isinstance(equation, ProblemInterface) else os.fspath(equation)
    if bf is not None and Path(bf.equation).stem != Path(given).stem:
        raise ProblemError(f"{bf.path} was computed with {bf.equation!r}, not {given!r}")
    return equation if isinstance(equation, ProblemInterface) else load_problem(equation)


def view(branches_or_file, path: str | os.PathLike | None = None, *, x: str | None = None,
         y: str | None = None, fold: bool = False, equation=None) -> View:
    """The interactive viewer of a branch file or of branches computed in this session.

    Parameters
    ----------
    branches_or_file : str, Path, BranchFile or list of Branch
        A branch file (its path or opened), or the result of
        :func:`~elastica_auto.continuation` (written to a temporary branch file first).
    path : str or Path, optional
        Write the page there (an ``.html`` file); otherwise it is only returned.
    x, y : str, optional
        The columns shown first (default: as ``elastica-auto plot``); the page switches them.
    fold : bool
        Fold a periodic x into [0, period) at first (the page toggles it).
    equation : Problem, str or Path, optional
        The equation module whose ``draw`` hook draws the configurations: a problem, a
        shipped module's name or a ``.py`` file (imported, so give only one you trust).
        Default: the branches' own problem, or for a file the shipped module it names; a
        file that names another module (by a path) is not imported, and its page has no
        configurations (docs/trust.md).

    Returns
    -------
    View
        The page; a notebook cell that ends with it shows it inline. Configurations that
        could not be drawn (the module not given, a ``draw`` hook that raised) are missing
        from it, each case a `~elastica_auto.plots.layout.NotDrawn` warning; ``View.images``
        says which.
    """
    source = branches_or_file
    if isinstance(source, (str, os.PathLike)):
        bf = BranchFile(source)
    elif isinstance(source, BranchFile):
        bf = source
    else:
        from ..api import save
        problem = equation_module(equation) if equation is not None else \
            getattr(source, "problem", None)
        with tempfile.TemporaryDirectory() as tmp:
            data = page_data(BranchFile(save(source, Path(tmp) / "branches.h5")), x, y,
                             fold, "FILE.h5", problem)     # not saved: the restarts name FILE.h5
        return _viewed(data, Path(path) if path else None, None)
    problem = equation_module(equation, bf) if equation is not None else None
    if path:
        check_output(path, bf.path)          # before the page is made
    return _viewed(page_data(bf, x, y, fold, problem=problem), Path(path) if path else None,
                   bf.path)


def _viewed(data: dict, path: Path | None, source: Path | None) -> View:
    """The page of ``data``, written to ``path`` if given; a `NotDrawn` warning for each
    case of configurations missing."""
    from .layout import NotDrawn
    text = render(data)
    page = View(text, write_page(text, path, source) if path else None, data["images"])
    for line in not_drawn(page.images, "pass equation=PATH (or the problem) to trust it"):
        warnings.warn(NotDrawn(line), stacklevel=3)
    return page


def not_drawn(images: Images, hint: str) -> list[str]:
    """What is missing from a page's configurations, a line per case ([] if nothing):
    ``hint`` says how to give the module where the file names one that is not shipped."""
    lines = []
    if images.untrusted:
        lines.append(f"configurations not drawn: {images.reason}; {hint}")
    if images.failed:
        lines.append(f"configurations not drawn for {images.failure_line()}")
    return lines
