"""The interactive viewer (``elastica-auto view``, ``ea.view``): a branch file's bifurcation
diagram and the configuration of the point under the mouse, side by side, in one
self-contained HTML page (Plotly's JavaScript embedded: it works offline and can be mailed).

The page holds the file's columns (every parameter and ordinate of every point, the index,
the labels and their index transitions), one PNG per labelled point drawn by the equation
module's ``draw`` hook, and the snap-back table. Plotly draws, zooms, pans, toggles branches
from the legend and finds the point under the mouse; the page's own script (`viewer.js`
beside this module) only builds the traces of the chosen panel and columns, in the styles of
``elastica-auto plot`` (`style`), and links a point to the side panel. Nothing is computed
but pictures of stored profiles.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
import os
import re
import sys
import tempfile
import threading
from importlib.resources import files
from pathlib import Path

import numpy as np

from ..core.errors import USER_ERRORS, StoreError
from ..storage.store import BranchFile, same_file, write_atomically
from .diagram import MARKED, MARKER_TEXT, default_columns, fixed_parameters, panel_groups
from .style import MARKERS, SNAP_COLOR, index_label, index_style

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
    """A viewer page: ``html`` (the whole document) and the ``path`` it was written to, if
    any. In a Jupyter notebook the object shows the page inline (in an iframe, so that the
    page's script and ids stay its own)."""

    def __init__(self, html_text: str, path: Path | None = None):
        self.html, self.path = html_text, path

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


def configuration_images(bf: BranchFile, problem=None, workers: int | None = None
                         ) -> dict[str, str]:
    """One PNG data URI per label of ``bf``: its stored profile drawn by the ``draw`` hook of
    ``problem`` (default: the equation module the file names), filling a square image.
    Empty if the module cannot be loaded or has no ``draw`` hook.

    ``workers``: processes that draw (each a fork of this one, given every ``workers``-th
    label); default `drawing_workers` of the labels' count. The images are the same
    whichever process drew them."""
    from .layout import equation_problem
    if problem is None:
        try:
            problem = equation_problem(bf.equation)
        except USER_ERRORS:
            return {}
    if not problem.has_draw or not bf.labels:
        return {}
    by_number = {b.number: b for b in bf.branches}
    # what each drawing needs, read here: a drawing process reads no file
    drawings = []
    for name, (br, pt) in bf.labels.items():
        b = by_number[br]
        drawings.append((b.profiles[pt - 1],
                         {q: float(b.columns[q][pt - 1]) for q in bf.parameters}))
    workers = drawing_workers(len(drawings)) if workers is None else workers
    if workers > 1:
        images = _draw_forked(problem, drawings, workers)
    else:
        images = _draw(problem, drawings)
    return dict(zip(bf.labels, images))


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


def _draw(problem, drawings) -> list[str]:
    """The images of ``drawings`` ((profile, parameters) pairs) by ``problem``'s draw hook,
    in order, on one figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .layout import data_box
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
        problem.draw(ax, profile, params)
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
        out.append(_png(fig))
    return out


#: What the forked drawing processes draw: (problem, drawings, workers), set while they run.
_FORKED = None


def _draw_share(k: int) -> list[str]:
    """In drawing process ``k``: its share of the drawings, every ``workers``-th from the
    k-th (alternate ones, so that slow stretches of a branch are shared)."""
    problem, drawings, workers = _FORKED
    return _draw(problem, drawings[k::workers])


def _draw_forked(problem, drawings, workers: int) -> list[str]:
    """`_draw` shared among ``workers`` forked processes, which inherit the problem and the
    drawings (nothing pickled but the images); drawn here if a process fails to start or
    dies."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    global _FORKED
    _FORKED = (problem, drawings, workers)
    try:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork")) as pool:
            shares = list(pool.map(_draw_share, range(workers)))
    except (BrokenProcessPool, OSError):
        return _draw(problem, drawings)
    finally:
        _FORKED = None
    out = [None] * len(drawings)
    for k, share in enumerate(shares):
        out[k::workers] = share
    return out


def _numbers(a) -> list:
    """A column as JSON numbers, ``None`` (a gap) where not finite."""
    return [float(v) if math.isfinite(v) else None for v in np.asarray(a, dtype=float)]


def _style(k: int) -> dict:
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
              fold: bool = False, file_name: str | None = None) -> dict:
    """What the page shows, as JSON-ready data: the columns and labels of every branch, the
    panels (`diagram.panel_groups`), the styles, the snap-back table and the configurations.
    ``file_name``: the branch file as the restart strings name it (default: ``bf.path``)."""
    xname, yname = default_columns(bf, xname, yname)
    if fold and xname not in bf.periods:
        raise ValueError(f"--fold: {xname!r} is not a periodic parameter of {bf.path} "
                         f"(periodic: {', '.join(bf.periods) or 'none'})")
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
                kind = "LP?" if t == "LP" and not np.isfinite(c["fold_residual"][i]) else t
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
              "target": {o: float(r["target_" + o]) for o in bf.ordinates
                         if "target_" + o in r}}
             for r in bf.snaps]
    return {
        "title": f"{bf.run}: {len(branches)} branch{'es' if len(branches) != 1 else ''} "
                 f"of {Path(bf.equation).name}",
        "file": str(file_name or bf.path),
        "parameters": bf.parameters, "ordinates": bf.ordinates, "columns": columns,
        "x": xname, "y": yname, "fold": fold, "periods": bf.periods,
        "panels": panels, "branches": branches,
        "labels": {name: list(where) for name, where in bf.labels.items()},
        "styles": {str(k): _style(k) for k in sorted(indices, key=lambda k: (k < 0, k))},
        "markers": {kind: _marker(kind) for kind in MARKERS},
        "snaps": snaps, "snap_color": SNAP_COLOR,
        "images": configuration_images(bf),
    }


def _script_json(data) -> str:
    """JSON to put inside a <script> element: no "</" to end it early."""
    return json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")


def page(bf: BranchFile, xname: str | None = None, yname: str | None = None,
         fold: bool = False, file_name: str | None = None) -> str:
    """The viewer's HTML document for ``bf`` (see `page_data` for the arguments)."""
    data = page_data(bf, xname, yname, fold, file_name)
    from plotly.offline import get_plotlyjs     # after page_data has checked the columns
    here = files(__package__)
    parts = {"TITLE": html.escape(data["title"]), "PLOTLY": get_plotlyjs(),
             "DATA": _script_json(data), "VIEWER": (here / "viewer.js").read_text()}
    # in one pass: what is put in is not searched for the next placeholder
    return re.sub(r"\{\{([A-Z]+)\}\}", lambda m: parts[m[1]],
                  (here / "viewer.html").read_text())


def check_output(output, source: Path | None) -> Path:
    """``output`` as a Path; StoreError if it is the branch file ``source`` (checked before
    the page is made, and again as it is written)."""
    output = Path(output)
    if source is not None and same_file(source, output):
        raise StoreError(f"{output} is the branch file being viewed; choose another name for "
                         "the page")
    return output


def write_page(text: str, output: Path, source: Path | None = None) -> Path:
    """Write ``text`` to ``output`` through a temporary file renamed over it, so that a failed
    write leaves ``output`` as it was. StoreError if ``output`` is the branch file ``source``
    or cannot be written."""
    output = check_output(output, source)
    return write_atomically(output, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def view(branches_or_file, path: str | os.PathLike | None = None, *, x: str | None = None,
         y: str | None = None, fold: bool = False) -> View:
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

    Returns
    -------
    View
        The page; a notebook cell that ends with it shows it inline.
    """
    source = branches_or_file
    if isinstance(source, (str, os.PathLike)):
        bf = BranchFile(source)
    elif isinstance(source, BranchFile):
        bf = source
    else:
        from ..api import save
        with tempfile.TemporaryDirectory() as tmp:
            text = page(BranchFile(save(source, Path(tmp) / "branches.h5")), x, y, fold,
                        file_name="FILE.h5")       # not saved: the restarts name FILE.h5
        return View(text, write_page(text, Path(path)) if path else None)
    text = page(bf, x, y, fold)
    return View(text, write_page(text, Path(path), bf.path) if path else None)
