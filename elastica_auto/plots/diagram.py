"""Bifurcation diagrams of a branch file (``elastica-auto plot``): an ordinate against a
parameter, one panel per combination of the values of the parameters that stay fixed along
the branches and differ between them.

Line style and colour follow the stability index (`style.INDEX_STYLE`); folds, branch points
and failed ends are marked (`style.MARKERS`) and named (``LP3``) where the name has room.
Each panel's title gives its fixed values, the figure's title the values every branch shares.
Drawn on a `matplotlib.figure.Figure`, without pyplot; nothing is recomputed.
"""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..core.labels import BP, CP, FOLDS, LP, MX, TURNS
from ..core.values import same_value
from ..storage.outputs import check_output, write_output
from ..storage.store import BranchFile
from .style import RC, UNLOCATED, index_label, index_style, marker_style

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Labelled points that are marked, in the order their names get room.
MARKED = (MX, CP, BP, LP)
MARKER_TEXT = {LP: "fold (LP)", UNLOCATED: "fold not located", BP: "branch point (BP)",
               MX: "failed end (MX)", CP: "cusp (CP)"}
FONTSIZE = 7.0



def line_index(index, types) -> np.ndarray:
    """The index that styles the line at each point: its own, but at a fold or branch point
    (`core.labels.TURNS`) the index of the point after it. The index stored at such a point
    is that of one side (the count there has a zero eigenvalue); the line leaving it is on the
    side of the next point, so the style changes at the point itself, not one segment
    later."""
    out = np.array(index, dtype=int)
    turn = np.flatnonzero(np.isin(np.asarray(types)[:-1], list(TURNS)))
    out[turn] = out[turn + 1]
    return out


def index_runs(x, y, index, period):
    """Split a branch into runs of equal index (joined at the change) and, when x is folded
    into [0, period), break it where x wraps around. ``index`` styles the lines: see
    `line_index`."""
    if period is not None:
        x = np.mod(x, period)
    wrap = np.abs(np.diff(x)) > period / 2 if period else np.zeros(len(x) - 1, bool)
    change = np.diff(index) != 0
    start = 0
    for i in range(len(x) - 1):
        if wrap[i] or change[i]:
            stop = i + 1 if wrap[i] else i + 2
            yield x[start:stop], y[start:stop], int(index[start])
            start = i + 1
    yield x[start:], y[start:], int(index[start])


def fixed_parameters(bf: BranchFile, xname: str) -> list[str]:
    """The parameters other than ``xname`` that keep one value along every branch of ``bf``."""
    return [q for q in bf.parameters if q != xname
            and all(np.ptp(b.columns[q].astype(float)) == 0 for b in bf.branches if len(b))]


def panel_groups(bf: BranchFile, xname: str):
    """``(varying, groups)``: the fixed parameters whose value differs between branches, and
    the branches grouped by those values, ``[(values, branches)]`` sorted by the values."""
    fixed = fixed_parameters(bf, xname)
    branches = [b for b in bf.branches if len(b)]

    def first(b, q):
        return float(b.columns[q][0])

    varying = [q for q in fixed if any(not same_value(first(b, q), first(branches[0], q),
                                                      bf.periods.get(q)) for b in branches)]
    groups: list[tuple[tuple, list]] = []
    for b in branches:
        key = tuple(first(b, q) for q in varying)
        for k, members in groups:
            if all(same_value(u, v, bf.periods.get(q)) for u, v, q in zip(key, k, varying)):
                members.append(b)
                break
        else:
            groups.append((key, [b]))
    groups.sort(key=lambda g: g[0])
    return varying, [(dict(zip(varying, k)), members) for k, members in groups]


def value_tex(v: float) -> str:
    """``v`` in TeX for a title: a small fraction of pi or pi^2 as such (``\\pi/12``,
    ``9\\pi^2/4``), else with four significant digits."""
    if v == 0:
        return "0"
    for power, pi in ((1, r"\pi"), (2, r"\pi^2")):
        r = Fraction(v / math.pi ** power).limit_denominator(12)
        if abs(r.numerator) <= 100 and abs(float(r) * math.pi ** power - v) <= 1e-12 * abs(v):
            num = {1: "", -1: "-"}.get(r.numerator, str(r.numerator))
            return num + pi + (f"/{r.denominator}" if r.denominator > 1 else "")
    return f"{v:.4g}"


def values_tex(bf: BranchFile, values: dict) -> str:
    """Parameter values as a panel title: ``$name=value$`` in the file's TeX names (each
    checked: `checked_tex`)."""
    return ", ".join(checked_tex(bf, q, rf"${bf.tex.get(q, q).strip('$')}={value_tex(v)}$")
                     for q, v in values.items())


def _grid(n: int, varying: list, groups) -> tuple[int, int]:
    """Rows and columns: with two or more varying parameters, a column per value of the last
    one (up to four); else two columns up to four panels, three beyond."""
    ncols = min(n, 2 if n <= 4 else 3)
    if len(varying) > 1:
        last = len({round(v[varying[-1]], 9) for v, _ in groups})
        if 1 < last <= 4:
            ncols = last
    return math.ceil(n / ncols), ncols


def _draw_panel(ax, branches, xname, yname, period, index_column="index"):
    """The branches as lines styled by index and their labelled points marked; returns the
    indices drawn, the marker types drawn and the points to name [(priority, x, y, name,
    type)]."""
    indices, kinds, names = set(), set(), []
    for b in branches:
        x, y = b.columns[xname].astype(float), b.columns[yname].astype(float)
        styled = line_index(b.columns[index_column], b.columns["type"])
        for xs, ys, k in index_runs(x, y, styled, period):
            color, dash, lw = index_style(k)
            ax.plot(xs, ys, color=color, ls=dash, lw=lw, solid_capstyle="round",
                    dash_capstyle="butt", zorder=3 if k == 0 else 2)
            indices.add(max(k, -1))
        xm = np.mod(x, period) if period else x
        label = b.label_names()
        for i, t in enumerate(b.columns["type"]):
            if t not in MARKED:
                continue
            if not (np.isfinite(xm[i]) and np.isfinite(y[i])):
                continue
            kind = UNLOCATED if t in FOLDS and not np.isfinite(b.columns["fold_residual"][i]) \
                else t
            ax.plot(xm[i], y[i], zorder=5, **marker_style(kind))
            kinds.add(kind)
            names.append((MARKED.index(t), xm[i], y[i], label[i], kind))
    return indices, kinds, names


def _name_points(ax, names):
    """Write the names beside their points, in order of priority, where a name overlaps no
    name written before and stays inside the axes (positions in points, after the layout)."""
    to_points = 72.0 / ax.figure.dpi
    box = ax.get_window_extent()
    x0, y0, x1, y1 = (v * to_points for v in box.extents)
    placed = []
    for _, x, y, name, kind in sorted(names, key=lambda n: n[0]):
        px, py = ax.transData.transform((x, y)) * to_points
        w, h = 0.62 * FONTSIZE * len(name), FONTSIZE
        left, bottom = px + 3, py + 2
        if left + w > x1 or bottom + h > y1 or px < x0 or py < y0:
            continue
        if any(left < r and left + w > q and bottom < t and bottom + h > s
               for q, s, r, t in placed):
            continue
        placed.append((left - 1.5, bottom - 1.5, left + w + 1.5, bottom + h + 1.5))
        ann = ax.annotate(name, (x, y), xytext=(3, 2), textcoords="offset points",
                          fontsize=FONTSIZE, color=marker_style(kind)["mec"], zorder=6,
                          bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none",
                                    alpha=0.8))
        ann.set_in_layout(False)


def _numeric(values) -> bool:
    return np.asarray(values).dtype.kind in "iuf"


def default_columns(bf: BranchFile, xname: str | None = None,
                    yname: str | None = None) -> tuple[str, str]:
    """The columns of a diagram of ``bf``: ``xname`` and ``yname`` if given, checked (a
    ValueError names the numeric columns, those a diagram accepts, for a name that is not a
    column or a column of text such as ``type``); by default the first branch's continued
    parameter against its distinguished ordinate."""
    if not bf.branches:
        raise ValueError(f"{bf.path}: the file has no branches")
    b0 = bf.branches[0]
    xname = xname or b0.parameter
    # a fold curve's natural ordinate is the parameter solved for along it
    solved = [q[len("free:"):] for q in bf.states if q.startswith("free:")]
    yname = yname or (solved[0] if solved else None) or b0.attrs.get("ordinate") \
        or bf.ordinates[0]
    for name in (xname, yname):
        if name not in b0.columns:
            # every numeric column is accepted (index, arclength, ... too): name them all
            numeric = [q for q, v in b0.columns.items() if _numeric(v)]
            raise ValueError(f"{name!r} is not a column of {bf.path}; columns: "
                             f"{', '.join(numeric)}")
        if not _numeric(b0.columns[name]):
            numeric = [q for q, v in b0.columns.items() if _numeric(v)]
            raise ValueError(f"{name!r} is not a numeric column of {bf.path}; numeric "
                             f"columns: {', '.join(numeric)}")
    return xname, yname


def period_of(bf: BranchFile, name: str, option: str = "") -> float:
    """The period of parameter ``name`` of ``bf``. ValueError (one line, starting with
    ``option`` if given) if it has none, or if the file's is not a positive finite number
    (a damaged or edited file: a fold into it would put every point nowhere)."""
    where = f"{option}: " if option else ""
    if name not in bf.periods:
        raise ValueError(f"{where}{name!r} is not a periodic parameter of {bf.path} "
                         f"(periodic: {', '.join(bf.periods) or 'none'})")
    period = bf.periods[name]
    if isinstance(period, bool) or not isinstance(period, (int, float)) \
            or not math.isfinite(period) or period <= 0:
        raise ValueError(f"{where}{bf.path}: the period of parameter {name!r} is {period!r}, "
                         "not a positive finite number (a damaged or edited file)")
    return float(period)


def checked_tex(bf: BranchFile, name: str, text: str) -> str:
    """``text``, the TeX of column ``name`` (its label, or a title with its value), if
    matplotlib can typeset it: else a ValueError of one line naming the column, its label
    and the module, found before anything is drawn (matplotlib's own error is a few lines
    of parser output at the save, naming neither)."""
    from matplotlib import cbook
    from matplotlib.mathtext import MathTextParser
    if not cbook.is_math_text(text):
        return text
    try:
        MathTextParser("path").parse(text)
    except ValueError as exc:
        kind = ("parameter" if name in bf.parameters else
                "ordinate" if name in bf.ordinates else "column")
        # the parser's last line says what it met ("ParseFatalException: Unknown symbol:
        # \\foo, found ..."); the lines before repeat the text with a caret under it
        why = next((line.strip() for line in reversed(str(exc).splitlines())
                    if line.strip()), type(exc).__name__).removeprefix("ParseFatalException: ")
        label = " ".join(bf.tex.get(name, name).split())
        raise ValueError(f"{bf.equation}: {kind} {name!r}: its TeX label {label} cannot be "
                         f"typeset ({why})") from None
    return text


def diagram_figure(bf: BranchFile, xname: str | None = None, yname: str | None = None,
                   period: float | None = None, index_column: str = "index") -> Figure:
    """The figure of ``yname`` against ``xname`` for every branch of ``bf``, one panel per
    combination of fixed parameter values (see `panel_groups`).

    Defaults: see `default_columns`. ``period`` folds x into [0, period). The line styles
    follow ``index_column`` (default the index; ``index_direct``: the direct count alone).
    """
    # matplotlib is imported here, not with the module: the viewer and the commands' checks
    # use the module's panel grouping and column defaults, and an error should not wait for it
    import matplotlib
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    xname, yname = default_columns(bf, xname, yname)
    xlabel, ylabel = (checked_tex(bf, q, bf.tex.get(q, q)) for q in (xname, yname))
    b0 = bf.branches[0]
    varying, groups = panel_groups(bf, xname)
    if not groups:
        raise ValueError(f"{bf.path}: the branches have no points")
    common = {q: float(b0.columns[q][0]) for q in fixed_parameters(bf, xname)
              if q not in varying}
    nrows, ncols = _grid(len(groups), varying, groups)
    with matplotlib.rc_context(RC):
        width = 4.4 if ncols > 1 else 6.4
        fig = Figure(figsize=(0.6 + width * ncols, 1.0 + 3.0 * nrows), layout="constrained")
        axes = fig.subplots(nrows, ncols, squeeze=False, sharex=True).ravel()
        indices, kinds, names = set(), set(), []
        for ax, (values, branches) in zip(axes, groups):
            i, k, n = _draw_panel(ax, branches, xname, yname, period, index_column)
            indices |= i
            kinds |= k
            names.append(n)
            if values:
                ax.set_title(values_tex(bf, values), fontsize=9)
            if period is not None:
                ax.set_xlim(0, period)
            ax.grid(alpha=0.25)
        for j, ax in enumerate(axes):
            if j >= len(groups):
                ax.remove()
            elif j + ncols >= len(groups):    # no panel below: this one shows the x axis
                ax.xaxis.set_tick_params(labelbottom=True)
                ax.set_xlabel(xlabel)
        fig.supylabel(ylabel)
        count = f"{len(bf.branches)} branch{'es' if len(bf.branches) != 1 else ''}"
        fig.suptitle(f"{bf.run}: {count}" + (f"; {values_tex(bf, common)}" if common else ""),
                     fontsize=10)
        handles = [Line2D([], [], color=c, ls=d, lw=w, label=index_label(k))
                   for k in sorted(indices, key=lambda k: (k < 0, k))
                   for c, d, w in [index_style(k)]]
        handles += [Line2D([], [], label=MARKER_TEXT[k], **marker_style(k))
                    for k in (LP, UNLOCATED, CP, BP, MX) if k in kinds]
        fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 6),
                   handlelength=2.6)
        fig.draw_without_rendering()
        for ax, n in zip(axes, names):
            _name_points(ax, n)
        # the names are placed for this layout: kept, not solved again at each save (the
        # same file, 0.05-0.1 s sooner for rotating_arm's)
        fig.set_layout_engine("none")
    return fig


def bifurcation_diagram(bf: BranchFile, output: Path, xname: str | None = None,
                        yname: str | None = None, period: float | None = None) -> Path:
    """Draw `diagram_figure` and save it to ``output`` (.png, .pdf, .svg), through a
    temporary file renamed over it (`save_figure`)."""
    output = check_output(output, bf.path, "the figure", "plotted")
    return save_figure(diagram_figure(bf, xname, yname, period), output, dpi=150)


def save_figure(fig, output: Path, **kwargs) -> Path:
    """``fig.savefig(output, **kwargs)`` in the format of ``output``'s suffix, written to a
    temporary file beside it and renamed over it: a failed save leaves an earlier figure as
    it was (a figure truncated by a full disk would be newer than its sources for make).
    ValueError for a format matplotlib does not write, StoreError for an output refused
    (`storage.outputs.check_output`), WriteError if it cannot be written."""
    import matplotlib
    output = Path(output)
    fmt = output.suffix[1:].lower() or matplotlib.rcParams["savefig.format"]
    supported = fig.canvas.get_supported_filetypes()
    if fmt not in supported:
        raise ValueError(f"{output}: matplotlib writes no {fmt!r} figures; use one of "
                         f"{', '.join('.' + f for f in supported)}")
    def write(tmp):
        try:
            fig.savefig(tmp, format=fmt, **kwargs)
        except Exception as exc:
            # matplotlib's PDF writer, cleaning up after a failed write, raises an error of
            # its own (AttributeError) with the OSError as its context: that is what failed
            failed = exc
            while failed is not None and not isinstance(failed, OSError):
                failed = failed.__context__
            if failed is None:
                raise
            raise failed from None

    with matplotlib.rc_context(RC):
        return write_output(output, write, what="the figure")
