r"""The safety figure (SPEC §9/§10): equality and avoidance plans in the x–y plane, with every
vehicle's safety region :math:`x_{s,i}(t) \pm (L_i/2 + S_{x,i})` by
:math:`y_{s,i} \pm (W_i/2 + S_{y,i})` and its body drawn at several instants, to scale
(equal aspect), axes in metres.

At each instant the ego's position on each plan is marked (a filled marker when the point is
inside a safety region, hollow otherwise); the vehicles' boxes are drawn lighter for earlier
instants.  Colours follow the report's palette (:data:`iamp.comparison.figures.style.PALETTE`): the
equality PMP green, the avoidance QP blue dashed, safety regions red.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from iamp.core.plan import Plan

from .style import PALETTE, SAFETY_COLOR, VEHICLE_COLORS, PathLike, legend_below, save_figure

#: Dash of each vehicle's safety region (vehicle 1 red dashed as in the other figures, vehicle 2
#: in its body's colour dash-dotted, ...).
REGION_DASHES: tuple[str | tuple[int, tuple[int, ...]], ...] = ("--", "-.", ":", (0, (5, 1, 1, 1)))
#: Edge colour of each vehicle's safety region (darker than the body colours: the regions'
#: outlines must read against a white page).
REGION_COLORS: tuple[str, ...] = (SAFETY_COLOR, "olive", "purple", "0.3")


def _inside(plan: Plan, t: float) -> bool:
    X = plan.require_trajectory().states(np.array([t]))[0]
    for v in plan.problem.vehicles:
        dx, dy = X[0] - float(v.position(t)), X[2] - v.y
        if abs(dx) < v.length / 2 + v.safety_x - 1e-3 and abs(dy) < v.width / 2 + v.safety_y - 1e-3:
            return True
    return False


def plot_safety_xy(plans: dict[str, Plan], stem: PathLike, *, times: np.ndarray | None = None,
                   title: str | None = None) -> list[Path]:
    """Draw ``plans`` (label -> plan of the same problem; failed plans are skipped and named in
    the legend) with the vehicles' safety regions and bodies at ``times`` (default: 6 instants).

    Returns the written paths (PNG and PDF).
    """
    ok = {k: p for k, p in plans.items() if p.ok and p.trajectory is not None}
    failed = [k for k, p in plans.items() if k not in ok]
    problem = next(iter(plans.values())).problem
    tf = problem.tf
    times = np.linspace(0.0, tf, 6) if times is None else np.asarray(times, dtype=float)
    tt = np.linspace(0.0, tf, 501)
    fig = Figure(figsize=(7.5, 4.0), layout="constrained")  # at text width its 9 pt legend stays ~8 pt
    ax = fig.add_subplot(1, 1, 1)
    xs_all: list[float] = []
    for i, v in enumerate(problem.vehicles):
        col = VEHICLE_COLORS[i % len(VEHICLE_COLORS)]
        ax_, ay_ = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
        for k, t in enumerate(times):
            alpha = 0.25 + 0.6 * k / max(1, len(times) - 1)
            xc = float(v.position(t))
            xs_all += [xc - ax_, xc + ax_]
            # each vehicle's region in its own colour and dash (both in red read as one vehicle's)
            ax.add_patch(Rectangle((xc - ax_, v.y - ay_), 2 * ax_, 2 * ay_, fill=False,
                                   ec=REGION_COLORS[i % len(REGION_COLORS)], lw=1.2, alpha=alpha,
                                   ls=REGION_DASHES[i % len(REGION_DASHES)],
                                   label=f"safety region of {v.name}" if k == 0 else None))
            ax.add_patch(Rectangle((xc - v.length / 2, v.y - v.width / 2), v.length, v.width, color=col,
                                   alpha=alpha * 0.8, label=f"{v.name} body" if k == 0 else None))
            ax.annotate(f"{t:.1f} s", (xc, v.y + ay_), textcoords="offset points", xytext=(0, 2),
                        ha="center", fontsize=7, color=col)
    styles = {"equality": (PALETTE["pmp"], "-", "o"), "avoid": (PALETTE["clarabel"], "--", "s")}
    for label, plan in ok.items():
        color, ls, marker = styles["avoid" if "avoid" in label else "equality"]
        X = plan.require_trajectory().states(tt)
        xs_all += [float(X[:, 0].min()), float(X[:, 0].max())]
        cost = f", J = {plan.cost:.3g}" if plan.cost is not None else ""
        ax.plot(X[:, 0], X[:, 2], color=color, ls=ls, lw=1.8, label=f"{label}{cost}")
        Xk = plan.require_trajectory().states(times)
        for t, row in zip(times, Xk):
            filled = _inside(plan, float(t))
            ax.plot([row[0]], [row[2]], marker=marker, ms=6, color=color, mfc=color if filled else "none", zorder=5)
    for label in failed:
        ax.plot([], [], color="0.5", ls=":", label=f"{label}: {plans[label].status} (no plan)")
    # to scale, with the axes' height set by the lanes used (the data limits, not the figure's
    # shape, decide: the former 'datalim' aspect padded y to +-20 m of empty road)
    ys = [v.y + sgn * (v.width / 2 + v.safety_y) for v in problem.vehicles for sgn in (-1, 1)]
    ys += [float(problem.ego.y0), float(problem.ego.yf)]
    ax.set_ylim(min(ys) - 2.0, max(ys) + 2.0)
    if xs_all:
        ax.set_xlim(min(xs_all) - 3.0, max(xs_all) + 3.0)
        xr, yr = np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim())
        fig.set_size_inches(7.5, 0.9 * 7.5 * yr / xr + 2.6)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("longitudinal position $x$ [m]")
    ax.set_ylabel("lateral position $y$ [m]")
    ax.set_title(title or f"{problem.name}: equality vs avoidance; regions and bodies at t = "
                 + ", ".join(f"{t:g}" for t in times) + " s\n(filled marker: the ego inside a region)", fontsize=9)
    legend_below(ax, ncol=2, fontsize=9)
    return save_figure(fig, stem)
