"""Configurations of the elastica with its lever arm, drawn from stored profiles.

Conventions (docs/design.md, "Sign conventions"): the centreline (x(s), y(s)) starts at the
clamp, which is turned by theta0 from the vertical; the lever arm starts at the tip and points
at angle theta(1) - psi from the vertical, measured like theta (so its direction is
eps (sin(psi - theta(1)), cos(psi - theta(1)))); the load F = P (sin alpha, -cos alpha) acts at
the arm's end. Everything here is geometry for drawing; nothing is solved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .style import ARM_COLOR, LOAD_COLOR, TRACE_COLOR

#: Length of the drawn load arrow, in rod lengths.
ARROW = 0.42


@dataclass
class Geometry:
    """One configuration: centreline, clamp angle, tip, arm end, unit load direction."""

    x: np.ndarray
    y: np.ndarray
    theta0: float
    tip: np.ndarray
    arm_end: np.ndarray
    load: np.ndarray            # unit vector along F (zero when P = 0)
    trace: np.ndarray | None = None   # (2, n): path of the arm end (tip trace), or None

    def points(self, arrow=ARROW, trace=True) -> np.ndarray:
        """Every point the drawing covers, (2, n), for common inset limits."""
        pts = [np.vstack((self.x, self.y)), self.arm_end[:, None],
               (self.arm_end - arrow * self.load)[:, None], np.zeros((2, 1))]
        if trace and self.trace is not None:
            pts.append(self.trace)
        return np.hstack(pts)


def arm_end(theta1, x1, y1, params):
    """Position of the arm's end (the load point) for tip angle and position arrays."""
    eps, psi = params["eps"], params["psi"]
    return np.array((x1 + eps * np.sin(psi - theta1), y1 + eps * np.cos(psi - theta1)))


def geometry(profile: np.ndarray, params: dict, trace: np.ndarray | None = None) -> Geometry:
    """The configuration of a stored profile ``(states, grid)`` with states [theta, kappa, x, y]."""
    theta, _, x, y = profile[:4]
    tip = np.array((x[-1], y[-1]))
    end = arm_end(theta[-1], x[-1], y[-1], params)
    a, P = params["alpha"], params["P"]
    load = np.sign(P) * np.array((np.sin(a), -np.cos(a))) if P != 0 else np.zeros(2)
    return Geometry(np.asarray(x), np.asarray(y), float(params["theta0"]), tip, end, load, trace)


def extent(geoms, arrow=ARROW, margin=0.12, trace=True) -> tuple[float, float]:
    """Width and height that fit every one of ``geoms`` (each centred in its own box)."""
    w = h = 0.0
    for g in geoms:
        p = g.points(arrow, trace)
        w = max(w, np.ptp(p[0]))
        h = max(h, np.ptp(p[1]))
    return w + 2 * margin, h + 2 * margin


def draw(ax, g: Geometry, *, arrow=ARROW, lw=1.6, color="black", clamp=0.16, alpha=1.0,
         show_trace=True, zorder=3):
    """Draw clamp, rod, lever arm, load arrow and (if any) the tip trace on ``ax``."""
    t0 = g.theta0
    tangent = np.array((-np.sin(t0), np.cos(t0)))
    normal = np.array((np.cos(t0), np.sin(t0)))
    # clamp: a wall across the rod at s = 0, hatched on the side away from the rod
    wall = np.outer(normal, (-clamp, clamp))
    ax.plot(wall[0], wall[1], color="0.2", lw=lw * 0.9, solid_capstyle="butt", zorder=zorder,
            alpha=alpha)
    for u in np.linspace(-clamp, clamp, 5):
        p = u * normal
        q = p - 0.09 * tangent - 0.07 * normal
        ax.plot((p[0], q[0]), (p[1], q[1]), color="0.35", lw=0.6, zorder=zorder, alpha=alpha)
    if show_trace and g.trace is not None and g.trace.shape[1] > 1:
        ax.plot(g.trace[0], g.trace[1], color=TRACE_COLOR, lw=1.3, zorder=zorder - 1,
                alpha=alpha, solid_capstyle="round")
    ax.plot(g.x, g.y, color=color, lw=lw, zorder=zorder + 1, alpha=alpha,
            solid_capstyle="round")
    ax.plot((g.tip[0], g.arm_end[0]), (g.tip[1], g.arm_end[1]), color=ARM_COLOR, lw=lw * 0.7,
            zorder=zorder + 1, alpha=alpha, solid_capstyle="round")
    ax.plot(*g.tip, "o", ms=lw * 1.3, color=color, zorder=zorder + 2, alpha=alpha)
    ax.plot(*g.arm_end, "o", ms=lw * 1.8, color=ARM_COLOR, zorder=zorder + 2, alpha=alpha)
    if np.any(g.load):
        tail = g.arm_end - arrow * g.load
        ax.annotate("", xy=g.arm_end, xytext=tail, zorder=zorder + 3,
                    arrowprops=dict(arrowstyle="-|>", color=LOAD_COLOR, lw=lw * 0.75,
                                    mutation_scale=6 + 2 * lw, shrinkA=0, shrinkB=lw * 1.2,
                                    alpha=alpha))


def frame(ax, g: Geometry, size: tuple[float, float], arrow=ARROW):
    """Limits of ``ax``: the common ``size`` centred on ``g``'s drawing; equal aspect, no axes."""
    p = g.points(arrow)
    cx, cy = (p[0].min() + p[0].max()) / 2, (p[1].min() + p[1].max()) / 2
    ax.set_xlim(cx - size[0] / 2, cx + size[0] / 2)
    ax.set_ylim(cy - size[1] / 2, cy + size[1] / 2)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xticks([])
    ax.set_yticks([])
    for sp in ax.spines.values():
        sp.set_visible(False)
