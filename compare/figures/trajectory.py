r"""The paper's figures of a plan: Figs. 4–6 (the x–y plane) and Figs. 7–9 (positions).

* :func:`draw_xy` — a plan in the x–y plane on a given axis, **to scale** (used by
  ``iamp plot`` too), with :func:`lane_lines` and :func:`xy_limits`.
* :func:`plot_xy_snapshots` — the paper's Figs. 4–6: the ego and the surrounding vehicles
  every 0.5 s in the x–y plane, with each vehicle's body and safety box
  ``x_s(t) ± (L/2 + S_x)`` by ``y_s ± (W/2 + S_y)``, lane lines and the contact corner.
* :func:`plot_positions` — Figs. 7–9: ``s_x(t)`` and ``s_y(t)`` with the safety-critical
  lines at ``t*`` dashed in red (vertical at ``t*``, horizontal at the corner coordinate).

Palette, conventions and the atomic writing: :mod:`iamp.comparison.figures.style`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle
from numpy.typing import ArrayLike

from .style import (
    EGO_COLOR,
    SAFETY_COLOR,
    VEHICLE_COLORS,
    PathLike,
    is_avoidance,
    legend_below,
    save_figure,
)

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from iamp.core.plan import Plan
    from iamp.core.problem import Problem

__all__ = ["draw_xy", "lane_lines", "plot_positions", "plot_xy_snapshots", "xy_figsize", "xy_limits"]


def lane_lines(problem: Problem) -> tuple[list[float], list[float]]:
    """Lane geometry used by the x–y figure: ``(edges, dividers)``.

    The paper gives no lane width beyond ``s_yf``; the lanes drawn here are centred at the
    ego's initial lateral position and at each surrounding vehicle's (and the ego's final)
    lateral position, and each lane line lies half-way between neighbouring centres.
    """
    centres = sorted({round(float(c), 9) for c in
                      [problem.ego.y0, problem.ego.yf] + [v.y for v in problem.vehicles]})
    merged = [centres[0]]
    for c in centres[1:]:  # centres closer than a car width are one lane
        if c - merged[-1] > 2.0:
            merged.append(c)
    if len(merged) == 1:
        half = 3.75 / 2
        return [merged[0] - half, merged[0] + half], []
    dividers = [(a + b) / 2 for a, b in zip(merged[:-1], merged[1:])]
    edges = [merged[0] - (merged[1] - merged[0]) / 2, merged[-1] + (merged[-1] - merged[-2]) / 2]
    return edges, dividers


def _snapshot_times(tf: float, dt: float) -> np.ndarray:
    n = int(np.floor(tf / dt + 1e-9))
    return np.arange(n + 1) * dt


def xy_limits(result: Plan, margin_x: float = 12.0, margin_y: float = 1.0) -> tuple[float, float, float, float]:
    """``(xmin, xmax, ymin, ymax)`` of the x–y figure: every vehicle and the ego path over the
    horizon with a margin, and at least the lanes (:func:`lane_lines`)."""
    problem = result.problem
    tt = np.linspace(0.0, problem.tf, 401)
    X = result.require_trajectory().states(tt)
    xs = [X[:, 0]] + [v.position(tt) for v in problem.vehicles]
    edges, _ = lane_lines(problem)
    ys = [X[:, 2], np.array(edges)] + [np.array([v.y - v.width / 2 - v.safety_y, v.y + v.width / 2 + v.safety_y])
                                      for v in problem.vehicles]
    return (float(min(np.min(x) for x in xs)) - margin_x, float(max(np.max(x) for x in xs)) + margin_x,
            float(min(np.min(y) for y in ys)) - margin_y, float(max(np.max(y) for y in ys)) + margin_y)


def draw_xy(ax: Axes, result: Plan, times: ArrayLike, *, ego_size: tuple[float, float] | None = None,
            time_labels: bool = False, ego_color: str = EGO_COLOR) -> None:
    """Draw a plan in the x–y plane on ``ax`` **to scale** (equal aspect: one metre is as long
    across as along the road, so a lane change looks as gentle as it is).

    Lanes; every surrounding vehicle's body and safety box ``x_s,i(t) ± (L_i/2 + S_x,i)`` by
    ``y_s,i ± (W_i/2 + S_y,i)`` at each of ``times`` (lighter = earlier); the ego's path and its
    body at the same instants, turned along its heading ``atan2(v_y, v_x)``; the safety box at
    each contact time ``t_i`` (dashed) and the contact corner (star).

    Parameters
    ----------
    ax : matplotlib Axes
    result : Plan
        A plan with a trajectory (its ``problem`` gives the vehicles).
    times : sequence of float
        The snapshot instants [s].
    ego_size : (length, width), optional
        The ego's body (default: the scenario's ``[ego] length`` × ``width``, SPEC §9; the
        planning model is a point mass).
    time_labels : bool
        Write ``t = …`` above each ego snapshot.
    """
    problem = result.problem
    # the avoidance QP (SPEC §10) reports crossing times τ_i (the ego leaves one half-plane of the
    # corner for the other), not touches of the corner
    crossing = is_avoidance(result)
    ts = np.asarray(times, dtype=float)
    X = result.require_trajectory().states(ts)
    tt = np.linspace(0.0, problem.tf, 401)
    Xd = result.require_trajectory().states(tt)
    ego = problem.ego
    L_e, W_e = ego_size or (ego.ego_length, ego.ego_width)
    alphas = np.linspace(0.3, 1.0, len(ts)) if len(ts) > 1 else np.ones(1)
    edges, dividers = lane_lines(problem)
    for y in edges:
        ax.axhline(y, color="0.3", lw=1.2, zorder=0)
    for y in dividers:
        ax.axhline(y, color="0.5", lw=0.9, ls=(0, (8, 6)), zorder=0)
    for i, v in enumerate(problem.vehicles):
        col = VEHICLE_COLORS[i % len(VEHICLE_COLORS)]
        hx, hy = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
        for k, t in enumerate(ts):
            xc = float(v.position(t))
            ax.add_patch(Rectangle((xc - hx, v.y - hy), 2 * hx, 2 * hy, fill=False, ec=SAFETY_COLOR, lw=0.7,
                                   alpha=0.45 * alphas[k], zorder=1))
            ax.add_patch(Rectangle((xc - v.length / 2, v.y - v.width / 2), v.length, v.width, fc=col, ec="k",
                                   lw=0.4, alpha=0.8 * alphas[k], zorder=2))
        ax.plot([], [], color=col, lw=6, alpha=0.8, label=f"vehicle {i + 1} ({v.name}) body")
    ax.plot([], [], color=SAFETY_COLOR, lw=1, alpha=0.6,
            label="safety boxes $x_{s,i}(t) \\pm (L_i/2+S_{x,i})$ by $y_{s,i} \\pm (W_i/2+S_{y,i})$")
    ax.plot(Xd[:, 0], Xd[:, 2], color=ego_color, lw=1.3, zorder=3, label="ego path $(s_x, s_y)$")
    for k in range(len(ts)):
        heading = float(np.degrees(np.arctan2(X[k, 3], X[k, 1])))
        ax.add_patch(Rectangle((X[k, 0] - L_e / 2, X[k, 2] - W_e / 2), L_e, W_e, angle=heading,
                               rotation_point="center", fc=ego_color, ec="k", lw=0.4, alpha=0.85 * alphas[k],
                               zorder=4))
        if time_labels:
            ax.annotate(f"{ts[k]:g} s", (X[k, 0], X[k, 2] + W_e / 2), textcoords="offset points", xytext=(0, 3),
                        ha="center", va="bottom", fontsize=7, color="0.2", zorder=8)
    ax.plot(X[:, 0], X[:, 2], "o", ms=2.0, color="k", zorder=5,
            label="ego at " + ", ".join(f"{t:g}" for t in ts) + " s" if len(ts) <= 8 else "ego snapshots")
    for i, (v, ti) in enumerate(zip(problem.vehicles, result.contact_times)):
        if not np.isfinite(ti):
            continue
        hx, hy = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
        xc = float(v.position(ti))
        ax.add_patch(Rectangle((xc - hx, v.y - hy), 2 * hx, 2 * hy, fill=False, ec=SAFETY_COLOR, lw=1.4, ls="--",
                               zorder=6))
        ax.add_patch(Rectangle((xc - v.length / 2, v.y - v.width / 2), v.length, v.width, fill=False, ec="k",
                               lw=0.9, ls="--", zorder=6))
        cx, cy = float(v.corner_x(ti)), v.corner_y
        ax.plot([cx], [cy], "*", ms=11, color=SAFETY_COLOR, mec="k", mew=0.5, zorder=7,
                label=(f"vehicle {i + 1}: {v.corner} corner at its crossing time $\\tau_{i + 1}$ = {ti:.2f} s"
                       if crossing else
                       f"contact {i + 1}: {v.corner} corner of vehicle {i + 1} at $t_{i + 1}$ = {ti:.2f} s"))
    xmin, xmax, ymin, ymax = xy_limits(result)
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("$x$ [m]")
    ax.set_ylabel("$y$ [m]")
    ax.grid(True, lw=0.3, alpha=0.5)


def xy_figsize(result: Plan, width: float = 7.5, extra_height: float = 1.6) -> tuple[float, float]:
    """A figure size whose x–y axes fill the width at equal aspect (plus room for the title and
    a legend below).  7.5 in wide: set at a paper's text width (~6.5 in) its 9 pt legend stays
    ~8 pt (at the former 10 in the 8 pt legend shrank to 5 pt; issue 22 item 14)."""
    xmin, xmax, ymin, ymax = xy_limits(result)
    return width, 0.9 * width * (ymax - ymin) / (xmax - xmin) + extra_height


def plot_xy_snapshots(result: Plan, stem: PathLike, *, dt: float = 0.5, title: str | None = None,
                      ego_size: tuple[float, float] | None = None) -> list[Path]:
    """The paper's Figs. 4–6: ego and surrounding vehicles every ``dt`` s in the x–y plane,
    to scale (:func:`draw_xy`).

    Parameters
    ----------
    result : Plan
        An optimal plan (its ``problem`` gives the vehicles).
    stem : path-like
        Output path without extension.
    dt : float
        Snapshot spacing [s].
    ego_size : (length, width), optional
        Body drawn for the ego (default: vehicle 1's ``L × W``).
    """
    problem = result.problem
    fig = Figure(figsize=xy_figsize(result, extra_height=2.6), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    draw_xy(ax, result, _snapshot_times(problem.tf, dt), ego_size=ego_size)
    ax.set_title(title or f"{problem.name}: ego and surrounding vehicles every {dt:g} s (lighter = earlier), "
                 "to scale", fontsize=10)
    legend_below(ax, ncol=1, fontsize=9)
    return save_figure(fig, stem)


def plot_positions(result: Plan, stem: PathLike, *, title: str | None = None, show_vehicles: bool = True) -> list[Path]:
    """The paper's Figs. 7–9: ``s_x(t)`` and ``s_y(t)`` with the safety-critical lines.

    At each contact time ``t_i`` a vertical red dashed line, and a horizontal red dashed
    line at the corner coordinate (``x_s,i(t_i) ± (L/2+S_x)`` in the upper panel,
    ``y_s,i ± (W/2+S_y)`` in the lower one).  The corner's longitudinal trajectory
    ``x_s,i(t) ± (L/2+S_x)`` is drawn thin for reference.
    """
    problem = result.problem
    tf = problem.tf
    tt = np.linspace(0.0, tf, 501)
    X = result.require_trajectory().states(tt)
    fig = Figure(figsize=(7.0, 6.0))
    ax1 = fig.add_subplot(2, 1, 1)
    ax2 = fig.add_subplot(2, 1, 2, sharex=ax1)
    ax1.plot(tt, X[:, 0], color=EGO_COLOR, lw=2, label="ego $s_x(t)$")
    ax2.plot(tt, X[:, 2], color=EGO_COLOR, lw=2, label="ego $s_y(t)$")
    for i, (v, ti) in enumerate(zip(problem.vehicles, result.contact_times)):
        col = VEHICLE_COLORS[i % len(VEHICLE_COLORS)]
        if show_vehicles:
            ax1.plot(tt, v.corner_x(tt), color=col, lw=1.0, ls="-.",
                     label=f"vehicle {i + 1} corner $x_{{s,{i + 1}}}(t) {'+' if v.sign_x > 0 else '-'} "
                           f"(L/2+S_x)$")
        if not np.isfinite(ti):
            continue
        cx, cy = float(v.corner_x(ti)), v.corner_y
        lab = "safety-critical lines at $t^*$" if i == 0 else None
        for ax, c in ((ax1, cx), (ax2, cy)):
            ax.axvline(ti, color=SAFETY_COLOR, ls="--", lw=1.2, label=lab)
            ax.axhline(c, color=SAFETY_COLOR, ls="--", lw=1.2)
        ax1.plot([ti], [cx], "o", color=SAFETY_COLOR, ms=6, zorder=5)
        ax2.plot([ti], [cy], "o", color=SAFETY_COLOR, ms=6, zorder=5)
        # on a white box: another contact's dashed lines may run through the label (two vehicles)
        box = {"fc": "white", "ec": "none", "alpha": 0.85, "pad": 1.0}
        ax1.annotate(f"$t^*_{i + 1}$ = {ti:.3f} s\n$x$ = {cx:.2f} m", (ti, cx), textcoords="offset points",
                     xytext=(8, -28), fontsize=8, color=SAFETY_COLOR, bbox=box, zorder=6)
        ax2.annotate(f"$y$ = {cy:.2f} m", (ti, cy), textcoords="offset points", xytext=(8, -14 if i == 0 else 6),
                     fontsize=8, color=SAFETY_COLOR, bbox=box, zorder=6)
    ax1.set_ylabel("$s_x$ [m]")
    ax2.set_ylabel("$s_y$ [m]")
    ax2.set_xlabel("$t$ [s]")
    ax2.set_xlim(0, tf)
    for ax in (ax1, ax2):
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=8, loc="best")
    ax1.set_title(title or f"{problem.name}: optimal longitudinal and lateral position", fontsize=10)
    return save_figure(fig, stem)
