"""The paper's figures 3-12 (and the stable family it leaves out), and two stability maps
beyond the paper, from the runs' branch files.

Each figure is a function ``(data_dir, out_dir) -> [png, pdf]`` registered in :data:`FIGURES`
under its make target name, with what it shows and the branch files it reads. The registry is
the one place that says which figure reads which runs: ``python -m elastica_auto.plots
--make-rules`` writes the Makefile's figure rules from it, and a test checks the table of
docs/figures.md against it. ``python -m elastica_auto.plots NAME --data out --out figures``
draws one figure.

Unlike the generic plots (`diagram`, `layout`), this module knows the elastica with a lever
arm: its parameters, ordinates and the path of the arm's end.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import matplotlib
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import ConnectionPatch
from matplotlib.ticker import MultipleLocator

from ..equations.elastica_lever_arm import arm_end
from ..core.labels import CP, SWITCHES, UZ, kind_of
from ..core.errors import StoreError
from ..storage.store import BranchFile, StoredBranch
from .layout import (Inset, Panel, Pt, Snap, branches_where, distinct_starts,
                     draw_configurations, draw_panel, find_equilibrium, label_point,
                     mark_number, same_value, save)
from .stability_map import map_figure
from .style import BP_COLOR, LANDED_FACE, RC, SNAP_COLOR

PI = math.pi
TWO_PI = 2 * PI
P1, P2 = PI ** 2 / 4, 9 * PI ** 2 / 4
LOADS = ((P1, r"P=\pi^2/4"), (P2, r"P=9\pi^2/4"))
TEX = {"psi": r"$\psi$", "eps": r"$\epsilon$", "alpha": r"$\alpha$", "P": r"$P$",
       "theta0": r"$\theta_0$",
       "m1": r"$\mathbf{m}(1)\cdot\mathbf{e}_z$", "beta": r"$\beta$",
       "mA": r"$(\mathbf{m}(1)+\mathbf{r}(1)\times\mathbf{n}(1))\cdot\mathbf{e}_z$",
       "gamma": r"$\gamma$", "m0": r"$\mathbf{m}(0)\cdot\mathbf{e}_z$"}


#: Colour of the path of the arm's end (the tip trace) drawn with a configuration at a fold.
TRACE_COLOR = "#1a9641"


@dataclass
class PaperFigure:
    """One figure of the paper: its make target ``fig-<name>`` (files ``<name with _>.png``
    and ``.pdf``), the paper's figure number, what it shows (the row of docs/figures.md), the
    runs whose branch files it reads (``out/<run>.h5``) and the function that draws it."""

    name: str
    paper: str
    shows: str
    runs: tuple[str, ...]
    draw: Callable


FIGURES: dict[str, PaperFigure] = {}


def figure(name, paper, shows, runs):
    """Register the decorated ``draw(data_dir, out_dir)`` as figure ``name`` in `FIGURES`."""
    def register(fn):
        FIGURES[name] = PaperFigure(name, paper, shows, tuple(runs), fn)
        return fn
    return register


def in_paper_order() -> list[PaperFigure]:
    """The registered figures, by the paper's figure number; then those beyond the paper
    (``paper`` empty), in the order they were registered."""
    return sorted(FIGURES.values(), key=lambda f: (not f.paper, int(f.paper or 0)))


def _open(data_dir, run) -> BranchFile:
    """The branch file of ``run``; StoreError if its run left something out (an analysis
    that failed, branches not computed: `BranchFile.missing`), which a figure would then be
    drawn without, silently."""
    bf = BranchFile(Path(data_dir) / f"{run}.h5")
    if bf.missing:
        raise StoreError(f"{bf.path}: incomplete: its run could not make "
                         + "; ".join(f"{m['what']} ({m.get('message', '')})"
                                     for m in bf.missing)
                         + f"; run it again (make {bf.path}) before drawing the figure")
    return bf


# ----------------------------------------------------------------------------- tip traces
def tip_trace(bf: BranchFile, br: StoredBranch, lp: int, side: str,
              span: float | None = None) -> np.ndarray:
    """Path (2, n) of the arm's end along the stable segment that ends at the fold in row
    ``lp`` (``side``: 'before' or 'after' it in the branch's point order), ending at the fold;
    with ``span``, only the part within ``span`` of the fold's parameter value."""
    idx = br.columns["index"]
    lo = hi = lp
    if side == "before":
        while lo > 0 and idx[lo - 1] == 0:
            lo -= 1
        rows = range(lo, hi + 1)
    else:
        while hi < len(br) - 1 and idx[hi + 1] == 0:
            hi += 1
        rows = range(hi, lo - 1, -1)
    lam = br.columns[br.parameter]
    rows = [i for i in rows if span is None or abs(lam[i] - lam[lp]) <= span]
    return np.array([arm_end(profile, Pt(bf, br, i).params)
                     for i, profile in zip(rows, br.profiles_at(rows))]).T


def traced(trace: np.ndarray) -> Callable:
    """``extra(ax)`` of a configuration: draws the path ``trace`` (2, n) of the arm's end."""
    def extra(ax):
        if trace.ndim == 2 and trace.shape[1] > 1:
            ax.plot(trace[0], trace[1], color=TRACE_COLOR, lw=1.3, zorder=2,
                    solid_capstyle="round")
    return extra


# ------------------------------------------------------------------------ family diagrams
def _in_window(x, window, period=None):
    if period:
        x = np.mod(x, period)
    return (x >= window[0] - 1e-9) & (x <= window[1] + 1e-9)


def main_branch(bf, branches, xname, window):
    """The branch with the most points inside ``window``."""
    return max(branches, key=lambda b: int(np.sum(_in_window(b.columns[xname], window))))


def family_insets(bf, br, xname, yname, window, n, index=0, numbering=1):
    """``n`` configurations spread along the index-``index`` points of ``br`` inside
    ``window``, evenly in the diagram's (scaled) arclength, numbered in branch order."""
    x = br.columns[xname].astype(float)
    y = br.columns[yname].astype(float)
    ok = _in_window(x, window) & (br.columns["index"] == index)
    rows = np.flatnonzero(ok)
    if len(rows) == 0:
        return []
    sx = (window[1] - window[0]) or 1.0
    sy = (np.ptp(y[rows]) or 1.0)
    d = np.zeros(len(rows))
    for j in range(1, len(rows)):
        a, b = rows[j - 1], rows[j]
        d[j] = d[j - 1] + (math.hypot((x[b] - x[a]) / sx, (y[b] - y[a]) / sy)
                           if b == a + 1 else 0.02)
    picks = []
    for t in np.linspace(0, d[-1], n):
        j = rows[int(np.argmin(np.abs(d - t)))]
        if j not in picks:
            picks.append(j)
    out = []
    for k, j in enumerate(picks):
        p = Pt(bf, br, j)
        out.append(Inset(str(numbering + k), p.configuration(), (p[xname], p[yname])))
    return out


def family_snaps(bf, br, xname, yname, window, sources, fixed, tags="AB", trace_span=PI / 2,
                 exclude=()):
    """Snap-back arrows for the folds of ``br`` inside ``window`` that end a stable segment
    (the file's /snaps table), one to every stable target. The first ``len(tags)`` distinct
    folds (``exclude``: fold keys tagged elsewhere) also get before/after configurations: the
    configuration at the fold with the tip trace along the stable segment leading to it
    (the last ``trace_span`` of the parameter), and the target the rod lands on if the file
    says which and it lies on a computed branch, else the nearest (in the ordinate) that
    does."""
    period = bf.periods.get(xname)
    by_lp: dict[str, list] = {}
    for r in sorted(bf.snaps, key=lambda r: r["value"]):
        if int(r["branch"]) == br.number and _in_window(np.array([r["value"]]), window)[0]:
            by_lp.setdefault(r["lp"], []).append(r)
    snaps, shown = [], list(exclude)
    for name, rows in by_lp.items():
        lp = label_point(bf, name)
        y0 = lp[yname]
        x = float(rows[0]["value"])
        rows.sort(key=lambda r: (-r.get("landed", 0), abs(float(r[f"target_{yname}"]) - y0)))
        key = (round(math.remainder(x, period) if period else x, 4), round(y0, 4))
        tagged = False
        for r in rows:
            s = Snap(x, y0, float(r[f"target_{yname}"]),
                     landed=bool(r["landed"]) if "landed" in r else None)
            if not tagged and len(shown) - len(exclude) < len(tags) and key not in shown:
                hit = find_equilibrium(sources, xname, x, "m0", float(r["k"]), fixed)
                if hit is not None:
                    tagged = True
                    shown.append(key)
                    s.tag = tags[len(shown) - len(exclude) - 1]
                    trace = tip_trace(bf, br, lp.i, r["stable_side"], trace_span)
                    s.before = lp.configuration(traced(trace))
                    s.after = hit
            snaps.append(s)
    return snaps


# ------------------------------------------------------------------ figures 4, 5, 8 and 11
def _family_panel(bf, fixed, xname, yname, window, title, extra_bf=None, n_insets=7):
    """The diagram of ``yname`` against ``xname`` over ``window`` of the branches of ``bf``
    with the ``fixed`` parameter values, with configurations along the stable family (along
    the index-1 points where there is none), snap-backs and before/after configurations.
    ``extra_bf``: a file with a further (stable) family at the same values."""
    items = [(bf, b) for b in branches_where(bf, **fixed)]
    fam_bf, fam = bf, [b for _, b in items]
    sources = [bf]
    if extra_bf is not None:
        more = branches_where(extra_bf, **fixed)
        items += [(extra_bf, b) for b in more]
        fam_bf, fam = extra_bf, more
        sources.append(extra_bf)
        title += "; with the stable family from the buckled rod (beyond the paper)"
    br = main_branch(fam_bf, fam, xname, window)
    insets = family_insets(fam_bf, br, xname, yname, window, n_insets)
    if not insets:  # no stable family: configurations along the branch
        insets = family_insets(fam_bf, br, xname, yname, window, n_insets, index=1)
    # snap-backs at the folds of every branch of the family, the main branch's first
    snaps = family_snaps(fam_bf, br, xname, yname, window, sources, fixed)
    for other in fam:
        if other is br:
            continue
        tagged = [(round(math.remainder(t.x, TWO_PI), 4), round(t.y0, 4))
                  for t in snaps if t.tag]
        more = family_snaps(fam_bf, other, xname, yname, window, sources, fixed,
                            tags="AB"[len(tagged):], exclude=tagged)
        snaps += [t for t in more if not any(
            abs(t.x - u.x) < 1e-6 and abs(t.y0 - u.y0) < 1e-6 and abs(t.y1 - u.y1)
            < 1e-6 for u in snaps)]
    return Panel(items, xname, yname, TEX[xname], TEX[yname], title, xlim=window,
                 xpi=True, insets=insets, snaps=snaps, legend_loc="lower right")


def _family_figure(out_dir, name, bf, xname, yname, window, fixed_by_load, title_by_load,
                   extra_bf=None, n_insets=7):
    """Two stacked diagrams (the two loads) of ``yname`` against ``xname`` over ``window``
    (`_family_panel`). ``extra_bf``: a file with a further (stable) family for the higher
    load."""
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(10.0, 8.6), layout="constrained")
        subs = fig.subfigures(2, 1, hspace=0.02)
        for sub, (P, ptex), tag in zip(subs, LOADS, "ab"):
            panel = _family_panel(bf, dict(fixed_by_load, P=P), xname, yname, window,
                                  rf"({tag}) {title_by_load}, ${ptex}$",
                                  extra_bf=extra_bf if P == P2 else None, n_insets=n_insets)
            draw_panel(sub, panel)
        return save(fig, out_dir, name)


@figure("rotating-arm-short", "4",
        "rotating arm, `eps = 0.25`: `m(1).e_z` against `psi`, (a) `P = pi^2/4`, (b) `P = 9 "
        "pi^2/4` with the stable family the straight rod's branch does not reach (beyond the "
        "paper)",
        ["rotating_arm", "rotating_arm_stable"])
def fig_rotating_arm_short(data_dir, out_dir):
    return _family_figure(out_dir, "rotating_arm_short", _open(data_dir, "rotating_arm"), "psi",
                          "m1", (0.0, 6 * PI), dict(eps=0.25), r"$\epsilon=0.25$",
                          extra_bf=_open(data_dir, "rotating_arm_stable"))


@figure("rotating-arm-long", "5",
        "rotating arm, `eps = 0.5`: (a) `P = pi^2/4`, (b) `P = 9 pi^2/4`",
        ["rotating_arm"])
def fig_rotating_arm_long(data_dir, out_dir):
    return _family_figure(out_dir, "rotating_arm_long", _open(data_dir, "rotating_arm"), "psi",
                          "m1", (0.0, 6 * PI), dict(eps=0.5), r"$\epsilon=0.5$")


@figure("rotating-load", "8",
        "rotating load, `eps = 0.5`, `psi = pi/2`: `(m(1) + r(1) x n(1)).e_z` against `alpha`, "
        "(a) `P = pi^2/4`, (b) `P = 9 pi^2/4`",
        ["rotating_load"])
def fig_rotating_load(data_dir, out_dir):
    return _family_figure(out_dir, "rotating_load", _open(data_dir, "rotating_load"), "alpha",
                          "mA", (0.0, 6 * PI), dict(eps=0.5, psi=PI / 2),
                          r"$\epsilon=0.5$, $\psi=\pi/2$")


@figure("rotating-base", "11",
        "rotating base, `eps = 0.5`, `psi = pi/2`: `m(0).e_z` against `theta0`, (a) `P = "
        "pi^2/4`, (b) `P = 9 pi^2/4`; the mirror image of figure 8",
        ["rotating_base"])
def fig_rotating_base(data_dir, out_dir):
    return _family_figure(out_dir, "rotating_base", _open(data_dir, "rotating_base"), "theta0",
                          "m0", (-6 * PI, 0.0), dict(eps=0.5, psi=PI / 2),
                          r"$\epsilon=0.5$, $\psi=\pi/2$")


# --------------------------------------------------------------------------------- figure 3
def _critical_curves(n_modes=4, eps_lim=1.0):
    """The roots of cot(sqrt P) = eps sqrt P as curves (eps(q), P = q^2), q = sqrt P in
    (n pi, (n + 1) pi): eps = cot(q) / q, explicit in q (docs/design.md, "The straight rod";
    paper section 3.2)."""
    out = []
    for n in range(n_modes):
        q = np.linspace(n * PI + 1e-4, (n + 1) * PI - 1e-4, 4000)
        eps = np.cos(q) / np.sin(q) / q
        keep = np.abs(eps) <= eps_lim * 1.05
        out.append((eps[keep], q[keep] ** 2))
    return out


def _computed_critical_curves(cl: BranchFile):
    """The critical-load curves of the critical_loads run as (eps, P), one per branch point
    it starts from (its two directions joined), in order of P at the start, eps decreasing
    (the order of `_critical_curves`)."""
    by_start: dict[str, list] = {}
    for b in cl.branches:
        by_start.setdefault(b.attrs["start"], []).append(b)
    out = []
    for pair in by_start.values():
        e = np.concatenate([b.columns["eps"].astype(float) for b in pair])
        P = np.concatenate([b.columns["P"].astype(float) for b in pair])
        order = np.argsort(-e)
        out.append((e[order], P[order]))
    return sorted(out, key=lambda c: float(np.interp(0.0, c[0][::-1], c[1][::-1])))


def _pitchfork_panel(tb, eps, title):
    items = [(tb, b) for b in branches_where(tb, eps=eps)]
    insets = []
    trivial = [b for _, b in items if np.all(b.columns["m0"] == 0)]
    bps = [Pt(tb, b, i) for b in trivial
           for i in np.flatnonzero(np.isin(b.columns["type"], list(SWITCHES)))]
    k = 1
    for bp in sorted(bps, key=lambda p: p["P"]):
        others = [b for _, b in items if b.columns["m0"].any()
                  and same_value(float(b.columns["P"][0]), bp["P"])]
        for b in sorted(others, key=lambda b: -float(b.columns["m0"][-1])):
            P = b.columns["P"].astype(float)
            target = bp["P"] + 0.45 * (P.max() - bp["P"])
            i = int(np.argmin(np.abs(P - target)))
            p = Pt(tb, b, i)
            off = (8, 7) if p["m0"] > 0 else (8, -8)
            insets.append(Inset(str(k), p.configuration(), (p["P"], p["m0"]), off))
            k += 1
    top = max(float(np.max(b.columns["m0"])) for _, b in items)
    return Panel(items, "P", "m0", TEX["P"], r"$\mathbf{m}(0)\cdot\mathbf{e}_z=\theta'(0)$",
                 title, insets=insets, legend_loc="upper left", ylim=(-1.1 * top, 2.1 * top),
                 legend_cols=2)


@figure("critical-loads", "3",
        "critical loads against `eps`, continued as branch-point curves (the closed form "
        "`cot sqrt(P) = eps sqrt(P)` overlaid), the pitchforks at `eps = 0.25` (a) and "
        "`-0.25` (b) with the buckled configurations",
        ["trivial_buckling", "critical_loads"])
def fig_critical_loads(data_dir, out_dir):
    tb = _open(data_dir, "trivial_buckling")
    cl = _open(data_dir, "critical_loads")
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(10.0, 8.4), layout="constrained")
        top, bottom = fig.subfigures(2, 1, height_ratios=[1.0, 0.95], hspace=0.03)
        left, right = top.subfigures(1, 2, wspace=0.03)
        for sub, eps, tag in ((left, 0.25, "a"), (right, -0.25, "b")):
            panel = _pitchfork_panel(tb, eps, rf"({tag}) $\epsilon={eps:g}$, $\psi=\alpha=0$")
            draw_panel(sub, panel, inset_height=1.0, main_height=2.2)
        ax = bottom.subplots()
        ax.set_yscale("function", functions=(lambda P: np.sqrt(np.maximum(P, 0)),
                                             lambda q: q ** 2))
        shade = ["#f7f7f7", "#e4e4e4", "#d0d0d0", "#bdbdbd"]
        curves = _computed_critical_curves(cl)
        eg = np.linspace(-1, 1, 801)
        lo = np.zeros_like(eg)
        for e, P in _critical_curves():
            ax.plot(e, P, color="white", lw=0.6, ls=(0, (3, 3)), zorder=4)
        for n, (e, P) in enumerate(curves):
            ax.plot(e, P, color="black", lw=1.4, zorder=3)
            # the straight rod's index is the number of critical loads below P
            hi = np.interp(eg, e[::-1], P[::-1])
            ax.fill_between(eg, lo, hi, color=shade[n], zorder=1, lw=0)
            lo = hi
        ax.fill_between(eg, lo, 100, color=shade[-1], zorder=1, lw=0)
        for n, (x, y) in enumerate(((-0.78, 3.9), (-0.78, 17.0), (0.75, 28.0), (0.55, 49.3))):
            ax.text(x, y, f"straight rod: index {n}", fontsize=8, ha="center", va="center",
                    color="0.2", zorder=4, style="italic")
        for P, s in ((P1, r"$P=\pi^2/4=P^o_{cr,1}$"), (P2, r"$P=9\pi^2/4=P^o_{cr,2}$")):
            ax.axhline(P, color="0.35", lw=0.8, ls=(0, (2, 2)), zorder=2)
            ax.text(-0.3, P * 1.02, s, fontsize=7.5, va="bottom", ha="right", color="0.25",
                    zorder=4)
        for e in (-0.25, 0.25):
            ax.axvline(e, color="#2c6fbb", lw=0.8, ls=(0, (4, 2)), zorder=2)
            ax.text(e, 51, " (a)" if e > 0 else " (b)", color="#2c6fbb", fontsize=8,
                    va="top", ha="left")
        # the branch points the continuation found on the straight rod
        bp_eps, bp_P = [], []
        for b in tb.branches:
            for i in np.flatnonzero(np.isin(b.columns["type"], list(SWITCHES))):
                bp_eps.append(float(b.columns["eps"][i]))
                bp_P.append(float(b.columns["P"][i]))
        ax.plot(bp_eps, bp_P, "s", ms=5, mfc="white", mec=BP_COLOR, mew=1.3, zorder=5,
                label="branch points of the straight rod's\nP-branches (trivial_buckling run)")
        ax.plot([], [], color="black", lw=1.4,
                label="critical loads continued in $(P, \\epsilon)$ (critical_loads run)")
        ax.plot([], [], color="0.5", lw=0.6, ls=(0, (3, 3)),
                label=r"$\cot\sqrt{P}=\epsilon\sqrt{P}$, $\sqrt{P}\neq n\pi$ (closed form)")
        for x, y, s in ((0.6, 1.5, r"$P^+_{cr,1}$"), (-0.6, 6.4, r"$P^-_{cr,1}$"),
                        (0.6, 14.0, r"$P^+_{cr,2}$"), (-0.6, 36.0, r"$P^-_{cr,2}$"),
                        (0.9, 40.6, r"$P^+_{cr,3}$")):
            ax.text(x, y, s, fontsize=9, ha="center", va="bottom", zorder=6,
                    bbox=dict(fc="white", ec="none", alpha=0.75, pad=0.6))
        ax.set_xlim(-1, 1)
        ax.set_ylim(0, 52)
        ax.set_yticks([0, 1, 2.5, 5, 10, 20, 30, 40, 50])
        ax.set_yticklabels(["0", "1", "2.5", "5", "10", "20", "30", "40", "50"])
        ax.set_xlabel(r"$\epsilon$", labelpad=1)
        ax.set_ylabel(r"$P$ (square-root scale)")
        ax.set_title(r"(c) critical loads of the straight rod ($\psi=\alpha=\theta_0=0$)",
                     loc="left", fontsize=9.5, pad=3)
        ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=7.5, ncol=2,
                  borderaxespad=0.2)
        return save(fig, out_dir, "critical_loads")


# ------------------------------------------------------------- families from labelled starts
def starts_panel(bf, fixed, xname, yname, title, xlim=None, tags="A", legend_loc="best",
                 trace_span=None, zoom=None):
    """The branches of ``bf`` with the ``fixed`` parameter values, their distinct start
    equilibria numbered in run order (the order the parent continuation crossed the
    parameter value) and drawn along the top, and the snap-backs at their folds."""
    brs = branches_where(bf, **fixed)
    items = [(bf, b) for b in brs]
    starts = distinct_starts(bf, brs, "m0")
    insets, used = [], []
    for k, p in enumerate(starts):
        xy = (p[xname], p[yname])
        n = sum(1 for q in used if abs(q[0] - xy[0]) < 1e-9 and abs(q[1] - xy[1]) <= 1e-6 * (
            1 + abs(xy[1])))
        used.append(xy)
        insets.append(Inset(str(k + 1), p.configuration(), xy, (8 + 13 * n, 0)))
    snaps, tagged = [], []
    lo, hi = xlim if xlim else (-np.inf, np.inf)
    for b in brs:
        found = family_snaps(bf, b, xname, yname, (lo, hi), [bf], fixed,
                             tags=tags[len(tagged):], trace_span=trace_span,
                             exclude=[(round(t.x, 4), round(t.y0, 4)) for t in tagged])
        for s in found:
            key = (round(s.x, 6), round(s.y0, 6), round(s.y1, 6))
            if any((round(t.x, 6), round(t.y0, 6), round(t.y1, 6)) == key for t in snaps):
                continue  # the same snap, from a branch computed twice
            if s.tag:
                tagged.append(s)
            snaps.append(s)
    return Panel(items, xname, yname, TEX[xname], TEX[yname], title, xlim=xlim, insets=insets,
                 snaps=snaps, legend_loc=legend_loc, zoom=zoom)


def folded_panel(bf, fixed, xname, yname, marks, title):
    """A periodic parameter's branches folded into [0, 2 pi), the crossings of the values in
    ``marks`` {value: label text or None} marked (numbered in run order where labelled)."""
    items = [(bf, b) for b in branches_where(bf, **fixed)]
    period = bf.periods.get(xname, 2 * PI)

    def extra(ax):
        for v, numbered in marks.items():
            ax.axvline(v, color="0.55", lw=0.6, ls=(0, (1, 2)), zorder=1)
    return Panel(items, xname, yname, TEX[xname], TEX[yname], title, period=period,
                 xpi=True, extra=extra, fold_text=False, legend_loc="lower right")


def _numbered_crossings(src, starts_bf, fixed, xname, value):
    """Insets marking the distinct start equilibria of ``starts_bf`` at ``xname`` = ``value``
    in the folded diagram of ``src``: (x, ordinate of the folded diagram)."""
    out = []
    brs = branches_where(starts_bf, **{xname: value}, **fixed)
    for k, p in enumerate(distinct_starts(starts_bf, brs, "m0")):
        out.append((k + 1, p))
    return out


def _folded_with_starts(src, starts_bf, fixed, xname, yname, number_at, other_values, title):
    """Panel: ``src``'s branches (``fixed``) folded into [0, 2 pi) in ``xname``; the distinct
    start equilibria of ``starts_bf`` at ``xname`` = ``number_at`` numbered in run order (the
    order the continuation crossed that value), the starts at ``other_values`` marked."""
    panel = folded_panel(src, fixed, xname, yname, {}, title)
    pick = {q: v for q, v in fixed.items() if q == "P"}
    numbered = _numbered_crossings(src, starts_bf, pick, xname, number_at)
    others = [p for v in other_values
              for _, p in _numbered_crossings(src, starts_bf, pick, xname, v)]

    def extra(ax):
        for v in (number_at, *other_values):
            ax.axvline(v, color="0.55", lw=0.6, ls=(0, (1, 2)), zorder=1)
        for p in others:
            ax.plot(np.mod(p[xname], 2 * PI), p[yname], "o", ms=2.6, color="0.45", zorder=7)
        lo, hi = ax.get_ylim()
        used = []
        for k, p in numbered:
            xy = (float(np.mod(p[xname], 2 * PI)), p[yname])
            n = sum(1 for q in used if abs(q[1] - xy[1]) < 0.035 * (hi - lo))
            used.append(xy)
            mark_number(ax, *xy, k, offset=(-9 - 12 * n, 0))
    panel.extra = extra
    panel.xlim = (-0.1 * 2 * PI, 2 * PI)   # a margin left of 0 for the numbers
    return panel


@figure("arm-length-straight", "6",
        "(a) the `eps = 0.5` psi-branches folded into `[0, 2 pi)`, the equilibria at `psi = 0` "
        "numbered in the order the continuation crosses `psi = 0`; (b) `beta` against `eps` "
        "from each of them, both loads",
        ["rotating_arm", "arm_length"])
def fig_arm_length_straight(data_dir, out_dir):
    ra, al = _open(data_dir, "rotating_arm"), _open(data_dir, "arm_length")
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(13.0, 10.2), layout="constrained")
        top, bottom = fig.subfigures(2, 1, height_ratios=[0.62, 1.0], hspace=0.03)
        for sub, (P, ptex), tag in zip(top.subfigures(1, 2, wspace=0.03), LOADS, "ab"):
            panel = _folded_with_starts(
                ra, al, dict(eps=0.5, P=P), "psi", "m1", 0.0, (PI / 12, PI / 6, PI / 2),
                rf"(a{'12'[tag == 'b']}) $\epsilon=0.5$, ${ptex}$: $\psi$ folded into "
                r"$[0,2\pi)$; numbered: the starts at $\psi=0$")
            draw_panel(sub, panel, main_height=2.6)
        for sub, (P, ptex), tag in zip(bottom.subfigures(1, 2, wspace=0.03), LOADS, "12"):
            panel = starts_panel(al, dict(P=P, psi=0.0), "eps", "beta",
                                 rf"(b{tag}) $\psi=0$, ${ptex}$", xlim=(-0.55, 0.62))
            draw_panel(sub, panel, side_width=0.3)
        return save(fig, out_dir, "arm_length_straight")


@figure("arm-length-tilted", "7",
        "`beta` against `eps` at `psi = pi/12` (a), `pi/6` (b), `pi/2` (c, with the folds "
        "enlarged), both loads",
        ["arm_length"])
def fig_arm_length_tilted(data_dir, out_dir):
    al = _open(data_dir, "arm_length")
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(13.0, 14.5), layout="constrained")
        rows = fig.subfigures(3, 1, hspace=0.03)
        for row, (psi, stex), tag in zip(rows, ((PI / 12, r"\pi/12"), (PI / 6, r"\pi/6"),
                                                (PI / 2, r"\pi/2")), "abc"):
            for sub, (P, ptex), k in zip(row.subfigures(1, 2, wspace=0.03), LOADS, "12"):
                zoom = None
                if psi == PI / 2 and P == P2:   # the paper enlarges the folds of (c)
                    zoom = dict(xlim=(0.27, 0.52), ylim=(-22.5, 6.0),
                                bounds=(0.13, 0.08, 0.36, 0.48), text=True)
                panel = starts_panel(al, dict(P=P, psi=psi), "eps", "beta",
                                     rf"({tag}{k}) $\psi={stex}$, ${ptex}$",
                                     xlim=(-0.55, 0.62), zoom=zoom)
                draw_panel(sub, panel, side_width=0.3)
        return save(fig, out_dir, "arm_length_tilted")


# ----------------------------------------------------------------------- figures 9 and 10
@figure("load-magnitude-vertical", "9",
        "(a) the `P = 9 pi^2/4` alpha-branch folded into `[0, 2 pi)`, the equilibria at `alpha "
        "= 0` numbered; (b) `gamma` against `P` from each of them",
        ["rotating_load", "load_magnitude"])
def fig_load_magnitude_vertical(data_dir, out_dir):
    rl, lm = _open(data_dir, "rotating_load"), _open(data_dir, "load_magnitude")
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(10.0, 9.4), layout="constrained")
        top, bottom = fig.subfigures(2, 1, height_ratios=[0.72, 1.0], hspace=0.03)
        panel = _folded_with_starts(
            rl, lm, dict(eps=0.5, psi=PI / 2, P=P2), "alpha", "mA", 0.0,
            (PI / 2, PI, 3 * PI / 2),
            r"(a) $\epsilon=0.5$, $\psi=\pi/2$, $P=9\pi^2/4$: $\alpha$ folded into "
            r"$[0,2\pi)$; numbered: the starts at $\alpha=0$")
        draw_panel(top, panel, main_height=2.6)
        panel = starts_panel(lm, dict(alpha=0.0), "P", "gamma",
                             r"(b) $\alpha=0$, $\epsilon=0.5$, $\psi=\pi/2$",
                             xlim=(-P2 * 1.05, P2 * 1.16), tags="AB", trace_span=P2 / 10)
        draw_panel(bottom, panel)
        return save(fig, out_dir, "load_magnitude_vertical")


@figure("load-magnitude-tilted", "10",
        "`gamma` against `P` at `alpha = pi/2` (a), `pi` (b), `3 pi/2` (c)",
        ["load_magnitude"])
def fig_load_magnitude_tilted(data_dir, out_dir):
    lm = _open(data_dir, "load_magnitude")
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(10.0, 13.0), layout="constrained")
        for sub, (a, atex), tag in zip(fig.subfigures(3, 1, hspace=0.02),
                                       ((PI / 2, r"\pi/2"), (PI, r"\pi"),
                                        (3 * PI / 2, r"3\pi/2")), "abc"):
            panel = starts_panel(lm, dict(alpha=a), "P", "gamma",
                                 rf"({tag}) $\alpha={atex}$, $\epsilon=0.5$, $\psi=\pi/2$",
                                 xlim=(-P2 * 1.05, P2 * 1.16), tags="AB", trace_span=P2 / 10)
            draw_panel(sub, panel)
        return save(fig, out_dir, "load_magnitude_tilted")


# -------------------------------------------------------------------------------- figure 12
@figure("rotating-base-snaps", "12",
        "rotating base, `P = 9 pi^2/4`: every snap-back of one period, the configuration at the"
        " fold with its tip trace and every stable configuration it can snap to",
        ["rotating_base"])
def fig_rotating_base_snaps(data_dir, out_dir):
    rb = _open(data_dir, "rotating_base")
    fixed = dict(eps=0.5, psi=PI / 2, P=P2)
    numbers = {b.number for b in branches_where(rb, **fixed)}
    rows: dict = {}
    for r in sorted(rb.snaps, key=lambda r: abs(r["value"] + PI)):  # nearest [-2 pi, 0] first
        if int(r["branch"]) not in numbers:
            continue
        lp = label_point(rb, r["lp"])
        key = (round(float(np.mod(r["value"], 2 * PI)), 3), round(lp["m0"], 3))
        row = rows.setdefault(key, (lp, r["stable_side"], []))
        if row[0].label == lp.label:   # periodic copies of a fold: the first one only
            row[2].append(r)
    snaps = []
    for (lp, side, targets) in sorted(rows.values(), key=lambda t: -np.mod(t[0]["theta0"],
                                                                          2 * PI)):
        trace = tip_trace(rb, lp.br, lp.i, side, PI)
        after = []
        for r in sorted(targets, key=lambda r: abs(r["target_m0"] - lp["m0"])):
            after.append((r, find_equilibrium([rb], "theta0", float(r["value"]), "m0",
                                              float(r["k"]), fixed)))
        nb = lp.i - 1 if side == "before" else lp.i + 1
        way = "increases" if lp.br.columns["theta0"][nb] < lp["theta0"] else "decreases"
        snaps.append((lp, lp.configuration(traced(trace)), after, way))
    ncol = 1 + max(len(a) for _, _, a, _ in snaps)
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(1.75 * ncol + 0.6, 1.95 * len(snaps) + 0.5), layout="constrained")
        subs = np.atleast_1d(fig.subfigures(len(snaps), 1, hspace=0.0))
        drawn: list[tuple] = []    # (axes, configuration), drawn at one scale below
        for k, (sub, (lp, before, after, way)) in enumerate(zip(subs, snaps)):
            axs = sub.subplots(1, ncol, gridspec_kw=dict(wspace=0.05))
            sub.suptitle(rf"S{k + 1}: fold at $\theta_0={lp['theta0']:.3f}$ "
                         rf"($\equiv{np.mod(lp['theta0'], 2 * PI):.3f}$ mod $2\pi$), "
                         rf"$\mathbf{{m}}(0)\cdot\mathbf{{e}}_z={lp['m0']:.2f}$; as "
                         rf"$\theta_0$ {way} past it, the rod snaps to one of "
                         rf"{len(after)} stable configurations", fontsize=8.5, x=0.01,
                         ha="left")
            drawn.append((axs[0], before))
            axs[0].set_title("at the fold", fontsize=8, color="0.2", pad=1)
            landed = next((j for j, (r, _) in enumerate(after, 1) if r.get("landed") == 1), None)
            for j in range(1, ncol):
                ax = axs[j]
                if j - 1 >= len(after):
                    ax.axis("off")
                    continue
                r, c = after[j - 1]
                if c is None:
                    ax.axis("off")
                    ax.text(0.5, 0.5, "not on a\ncomputed branch", ha="center", va="center",
                            transform=ax.transAxes, fontsize=7)
                else:
                    drawn.append((ax, c))
                ax.set_title(rf"$\mathbf{{m}}(0)\cdot\mathbf{{e}}_z={r['target_m0']:.2f}$"
                             + (" (lands)" if j == landed else ""), fontsize=8,
                             color=SNAP_COLOR, pad=1,
                             fontweight="bold" if j == landed else "normal")
                if j == landed:    # the rod's dynamics from the fold end here
                    ax.set_facecolor(LANDED_FACE)
            # the snap arrow points at the configuration the rod lands on (the first if unknown)
            sub.add_artist(ConnectionPatch(
                (1.0, 0.5), (0.0, 0.5), "axes fraction", "axes fraction", axesA=axs[0],
                axesB=axs[landed or 1], arrowstyle="-|>", color=SNAP_COLOR, lw=1.4,
                mutation_scale=11))
        draw_configurations(*zip(*drawn), margin=0.055)
        return save(fig, out_dir, "rotating_base_snaps")


# ------------------------------------------------------------------ beyond the paper: maps
def _map(data_dir, out_dir, run: str, stem: str, title: str) -> list:
    """The stability maps the fold-curve run ``run`` stored, as ``stem``.png and .pdf."""
    fig = map_figure(_open(data_dir, run), title)
    with matplotlib.rc_context(RC):
        return save(fig, out_dir, stem)


@figure("map-arm", "",
        "stability map in `(psi, eps)` at `P = pi^2/4` and `9 pi^2/4`: fold curves, cusps, "
        "and the number of stable equilibria in each region",
        ["fold_curves_arm"])
def fig_map_arm(data_dir, out_dir):
    return _map(data_dir, out_dir, "fold_curves_arm", "map_arm",
                r"rotating arm: stable equilibria in the $(\psi, \epsilon)$ plane "
                r"($\alpha=\theta_0=0$)")


@figure("map-load", "",
        "stability map in `(alpha, P)` at `eps = 0.5`, `psi = pi/2`: fold curves, cusps, and "
        "the number of stable equilibria in each region",
        ["fold_curves_load"])
def fig_map_load(data_dir, out_dir):
    return _map(data_dir, out_dir, "fold_curves_load", "map_load",
                r"rotating load: stable equilibria in the $(\alpha, P)$ plane ($\theta_0=0$)")


# ------------------------------------------------------------ beyond the paper: higher loads
P3 = 25 * PI ** 2 / 4


@figure("higher-loads", "",
        "rotating arm at `P = 25 pi^2/4`, between the third and fourth critical loads (the "
        "straight rod has index 3): `m(1).e_z` against `psi` over one period of folds of each "
        "direction, (a) `eps = 0.25`, (b) `eps = 0.5`, where the rod winds up to five turns",
        ["higher_loads"])
def fig_higher_loads(data_dir, out_dir):
    bf = _open(data_dir, "higher_loads")
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(10.0, 8.6), layout="constrained")
        subs = fig.subfigures(2, 1, hspace=0.02)
        for sub, eps, window, tag in zip(subs, (0.25, 0.5), (3 * PI, 12 * PI), "ab"):
            panel = _family_panel(bf, dict(eps=eps, P=P3), "psi", "m1", (-window, window),
                                  rf"({tag}) $\epsilon={eps:g}$, $P=25\pi^2/4$")
            ax = draw_panel(sub, panel)
            if window > 6 * PI:   # a tick at every pi would crowd the labels
                ax.xaxis.set_major_locator(MultipleLocator(2 * PI))
                ax.xaxis.set_minor_locator(MultipleLocator(PI))
        return save(fig, out_dir, "higher_loads")


# ------------------------------------------------------------- beyond the paper: pinned end
@figure("pinned-end", "",
        "pinned end: the lever arm's end pinned at `(0, 0.4)`, `m(1).e_z` against `psi` "
        "(constrained index), (a) `eps = 0.25`, (b) `eps = 0.5`, configurations with the pin "
        "and the reaction",
        ["pinned_arm"])
def fig_pinned_end(data_dir, out_dir):
    bf = _open(data_dir, "pinned_arm")
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(10.0, 8.6), layout="constrained")
        eps_values = sorted({float(b.columns["eps"][0]) for b in bf.branches})
        subs = np.atleast_1d(fig.subfigures(len(eps_values), 1, hspace=0.02))
        for sub, eps, tag in zip(subs, eps_values, "abcd"):
            items = [(bf, b) for b in branches_where(bf, eps=eps)]
            insets, numbering = [], 1
            for _, br in items:
                window = (float(np.min(br.columns["psi"])), float(np.max(br.columns["psi"])))
                insets += family_insets(bf, br, "psi", "m1", window, 3, numbering=numbering)
                numbering = len(insets) + 1
            panel = Panel(items, "psi", "m1", TEX["psi"], TEX["m1"],
                          rf"({tag}) pinned end at $(X, Y) = (0, 0.4)$, $\epsilon={eps:g}$",
                          xpi=True, insets=insets, legend_loc="lower right")
            draw_panel(sub, panel)
        return save(fig, out_dir, "pinned_end")


# ------------------------------------------------------- beyond the paper: snaps under damping
@figure("snap-damping", "",
        "where figure 12's snaps land under the damped model `u_tt + c u_t = -grad E`: the "
        "`m(0).e_z` of the equilibrium reached against the damping `c`, among the stable "
        "targets at the fold, with the overdamped flow's landing",
        ["snap_damping"])
def fig_snap_damping(data_dir, out_dir):
    bf = _open(data_dir, "snap_damping")
    folds: dict = {}
    for r in bf.landings:
        folds.setdefault(r["lp"], []).append(r)
    # named as in figure 12: by theta0 modulo 2 pi, largest first
    order = sorted(folds, key=lambda lp: -np.mod(folds[lp][0]["value"], TWO_PI))
    ncol = min(2, len(order))
    nrow = -(-len(order) // ncol)
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(4.6 * ncol, 2.9 * nrow + 0.3), layout="constrained")
        axs = np.atleast_1d(fig.subplots(nrow, ncol, squeeze=False)).ravel()
        for ax in axs[len(order):]:
            ax.axis("off")
        for k, (ax, lp) in enumerate(zip(axs, order)):
            rows = sorted(folds[lp], key=lambda r: r["damping"])
            targets = [r for r in bf.snaps if r["lp"] == lp]
            c = np.array([r["damping"] for r in rows])
            x_over = c.max() * 2.5     # the overdamped flow, drawn right of every c
            values = sorted(t["target_m0"] for t in targets)
            close = 0.05 * (np.ptp(values) or 1.0)   # two labels this close: apart
            for i, v in enumerate(values):           # every stable equilibrium at the fold
                ax.axhline(v, color="0.75", lw=0.8, ls=":", zorder=1)
                va = ("top" if i + 1 < len(values) and values[i + 1] - v < close else
                      "bottom" if i > 0 and v - values[i - 1] < close else "center")
                ax.annotate(f"{v:.2f}", (1.0, v), xycoords=("axes fraction", "data"),
                            xytext=(3, 0), textcoords="offset points", va=va, fontsize=7,
                            color="0.4")
            got = [r for r in rows if r["landed"] == 1]
            ax.step([r["damping"] for r in got], [r["target_m0"] for r in got],
                    where="mid", color=SNAP_COLOR, lw=1.0, alpha=0.5, zorder=2)
            ax.plot([r["damping"] for r in got], [r["target_m0"] for r in got], "o",
                    color=SNAP_COLOR, ms=4.5, zorder=3, label="damped model")
            missed = [r["damping"] for r in rows if r["landed"] != 1]
            if missed:
                ax.plot(missed, np.full(len(missed), ax.get_ylim()[0]), "x", color="black",
                        zorder=3, label="no stable equilibrium reached")
            over = next((t for t in targets if t.get("landed") == 1), None)
            if over is not None:
                ax.plot([x_over], [over["target_m0"]], "*", color=SNAP_COLOR, ms=9,
                        mec="black", mew=0.5, zorder=3, label="overdamped flow")
            ax.set_xscale("log")
            ax.set_xlim(c.min() / 1.5, x_over * 1.6)
            ticks = [v for v in (0.01, 0.1, 1, 10, 100) if c.min() / 1.5 <= v <= c.max()]
            ax.set_xticks(ticks + [x_over], [f"{v:g}" for v in ticks] + [r"$\infty$"])
            ax.minorticks_off()
            pad = 0.08 * (np.ptp([t["target_m0"] for t in targets]) or 1.0)
            ax.set_ylim(min(t["target_m0"] for t in targets) - pad,
                        max(t["target_m0"] for t in targets) + pad)
            ax.set_xlabel(r"damping $c$")
            ax.set_ylabel(r"landing: " + TEX["m0"])
            ax.set_title(rf"S{k + 1}: {lp} at $\theta_0={rows[0]['value']:.3f}$ "
                         rf"($\equiv{np.mod(rows[0]['value'], TWO_PI):.3f}$)", fontsize=9)
            if k == 0:
                ax.legend(loc="best", fontsize=7)
        fig.suptitle(r"rotating base, $\epsilon=0.5$, $\psi=\pi/2$, $P=9\pi^2/4$: where "
                     r"each snap of figure 12 lands under $u_{tt} + c\,u_t = -\nabla E$ "
                     "(dotted: every stable equilibrium at the fold)", fontsize=9)
        return save(fig, out_dir, "snap_damping")


# ------------------------------------------------------------- beyond the paper: the rod in 3D
@figure("rotating-arm-3d", "",
        "rotating arm of the spatial rod (`kirchhoff_lever_arm`), `b2` = 1 (left) and 2 "
        "(right): `m(1).e_z` against `psi` folded into `[0, 2 pi)`, styled by the 3D index "
        "(the direct count, in-plane plus out-of-plane), one panel per `(eps, P, b2)`",
        ["rotating_arm_3d"])
def fig_rotating_arm_3d(data_dir, out_dir):
    from .diagram import diagram_figure
    fig = diagram_figure(_open(data_dir, "rotating_arm_3d"), "psi", "m1", period=TWO_PI,
                         index_column="index_direct")
    with matplotlib.rc_context(RC):
        return save(fig, out_dir, "rotating_arm_3d")


@figure("configurations-3d", "",
        "the spatial rod at `eps = 0.5`, `psi = pi/2`, `P = 9 pi^2/4`: the equilibria of "
        "the 3D rotating arm there, drawn in space by the module's `draw` hook on 3D axes, "
        "with their in-plane and out-of-plane indices for `b2` = 1 and 2",
        ["rotating_arm_3d"])
def fig_configurations_3d(data_dir, out_dir):
    from .layout import configuration_axes
    bf = _open(data_dir, "rotating_arm_3d")
    found: dict = {}        # m0 (rounded) -> {b2: point}
    for br in branches_where(bf, eps=0.5, P=P2):
        for i, name in enumerate(br.label_names()):
            p = Pt(bf, br, i)
            if kind_of(name) == UZ and same_value(p["psi"], PI / 2, TWO_PI):
                found.setdefault(round(p["m0"], 3), {})[p["b2"]] = p
    rows = sorted(found.items())
    with matplotlib.rc_context(RC):
        ncol = 3                  # one width whatever the number of equilibria
        nrow = -(-len(rows) // ncol) or 1
        fig = Figure(figsize=(2.6 * ncol + 0.3, 2.7 * nrow + 0.4), layout="constrained")
        gs = fig.add_gridspec(nrow, ncol)
        axes, configs = [], []
        for j, (m0, by_b2) in enumerate(rows):
            p = by_b2[min(by_b2)]
            c = p.configuration()
            ax = configuration_axes(fig, gs[j // ncol, j % ncol], c)
            if ax.name == "3d":         # plain axes where the module is not drawn
                ax.view_init(elev=22, azim=-60)
            split = ", ".join(f"$b_2={b:g}$: {int(q['index_in'])} + {int(q['index_out'])}"
                              for b, q in sorted(by_b2.items()))
            ax.set_title(rf"$\mathbf{{m}}(0)\cdot\mathbf{{e}}_z={m0:.2f}$" + "\n" + split,
                         fontsize=7.5, pad=0)
            axes.append(ax)
            configs.append(c)
        draw_configurations(axes, configs, margin=0.04)
        fig.suptitle(r"spatial rod, $\epsilon=0.5$, $\psi=\pi/2$, $P=9\pi^2/4$: the "
                     "equilibria of the rotating arm,\nindex in plane + out of plane",
                     fontsize=9)
        return save(fig, out_dir, "configurations_3d")


# ------------------------------------------------- beyond the paper: a concentric-tube robot
@figure("concentric-tubes", "",
        "concentric-tube robot (`concentric_tubes`, two tubes, defaults): (a) the actuator's "
        "torque and (b) the tip's relative rotation against the base rotation `beta`, styled by "
        "index, with the fold pair where the tip snaps and numbered configurations in space; (c) "
        "the fold curve in `(beta, lambda)` and the closed-form snap-free bound where it turns "
        "(the cusp)",
        ["concentric_tubes", "concentric_tubes_folds"])
def fig_concentric_tubes(data_dir, out_dir):
    from ..equations.concentric_tubes import snap_free_bound
    from .style import CP_COLOR
    turn, folds = _open(data_dir, "concentric_tubes"), _open(data_dir, "concentric_tubes_folds")
    items = [(turn, br) for br in turn.branches]
    with matplotlib.rc_context(RC):
        fig = Figure(figsize=(13.5, 4.4), layout="constrained")
        subs = fig.subfigures(1, 3, wspace=0.02)
        for sub, yname, ytex, tag in zip(subs, ("torque", "tip"),
                                         (r"torque $\partial E/\partial\beta$",
                                          r"tip rotation $\psi_2(1)-\psi_1(1)$"), "ab"):
            insets = [ins for br in turn.branches
                      for ins in family_insets(turn, br, "beta", yname, (0, TWO_PI), 4)]
            draw_panel(sub, Panel(items, "beta", yname, r"$\beta$", ytex,
                                  f"({tag}) one turn of tube 2's base", xpi=True,
                                  insets=insets, legend_loc="upper left"))
        ax = subs[2].add_subplot()
        for br in folds.branches:
            ax.plot(br.columns["beta"], br.columns["lam"], color="black", lw=1.2)
        params = {name: float(folds.branches[0].columns[name][0])
                  for name in ("kappa1", "kappa2", "EI1", "EI2", "GJ1", "GJ2", "Lt")}
        bound = snap_free_bound(params)
        ax.axhline(bound, color=CP_COLOR, lw=0.8, ls="--",
                   label=rf"$\lambda^*=\arctan(1/(\sqrt{{c}}\,L_t))={bound:.4f}$")
        for br in folds.branches:
            for i, name in enumerate(br.label_names()):
                if kind_of(name) in SWITCHES | {CP}:
                    ax.plot(br.columns["beta"][i], br.columns["lam"][i], "o", ms=5,
                            mfc="white", mec=CP_COLOR, zorder=5)
        ax.set_xlim(0, TWO_PI)
        _pi_axis(ax)
        ax.set_xlabel(r"$\beta$", labelpad=1)
        ax.set_ylabel(r"$\lambda = L\sqrt{c}$")
        ax.set_title(r"(c) the fold curve, $L$ from 0.3 to 2", fontsize=9)
        ax.legend(loc="upper center", fontsize=8, frameon=False)
        return save(fig, out_dir, "concentric_tubes")


def _pi_axis(ax):
    """Ticks at multiples of pi/2 on the x axis, labelled in pi."""
    ax.xaxis.set_major_locator(MultipleLocator(PI / 2))
    ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(
        lambda v, _: {0: "0", 1: r"$\pi/2$", 2: r"$\pi$", 3: r"$3\pi/2$", 4: r"$2\pi$"}.get(
            round(v / (PI / 2)), "")))
