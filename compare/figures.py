r"""Figures of the reproduction report (the paper's Figs. 4–9 and the comparison beyond it).

Every function draws on a fresh :class:`matplotlib.figure.Figure` (no ``pyplot``, no global
state, no display: the Agg canvas is used for PNG and the PDF backend for PDF) and writes
``<stem>.png`` and ``<stem>.pdf`` atomically (saved to a temporary name in the same folder,
then :func:`os.replace`).  Each returns the list of the two paths written.

Conventions every figure follows (a reviewer's checklist): every axis is labelled with its
unit (the cost ``J`` in m²/s³, co-states ``p1, p3`` and jumps in m/s³, ``p2, p4`` in m/s²);
x–y plots are drawn **to scale** (equal aspect, :func:`draw_xy`), so a lane change is not
exaggerated into a cliff; one colour per planner everywhere (:data:`PALETTE`,
:func:`planner_style`: PMP green, Clarabel blue, OSQP orange; red marks safety regions,
contacts and jumps only); legends sit where they hide no data.

* :func:`draw_xy` — a plan in the x–y plane on a given axis (used by ``iamp plot`` too).
* :func:`plot_xy_snapshots` — the paper's Figs. 4–6: the ego and the surrounding vehicles
  every 0.5 s in the x–y plane, with each vehicle's body and safety box
  ``x_s(t) ± (L/2 + S_x)`` by ``y_s ± (W/2 + S_y)``, lane lines and the contact corner.
* :func:`plot_positions` — Figs. 7–9: ``s_x(t)`` and ``s_y(t)`` with the safety-critical
  lines at ``t*`` dashed in red (vertical at ``t*``, horizontal at the corner coordinate).
* :func:`plot_value_function` — ``J(t)`` of the fixed-contact-time problem (closed form),
  the PMP's ``t*`` and the QP's sweep points.
* :func:`plot_costates` — co-states ``p1..p4`` with their jumps at ``t_i`` beside the QP
  multipliers ``ν`` (``ν_x`` against the ``p1`` jump, ``ν_y`` against the ``p3`` jump).
* :func:`plot_zoh_convergence` — ``J_ZOH − J_PMP`` against ``h`` on log–log axes with a
  slope-2 guide.
* :func:`plot_timing` — whole-plan medians and single-solve distributions per planner
  configuration.
* :func:`plot_predictions` — observed history, predicted samples and the fitted cubic.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle
from numpy.typing import ArrayLike

from iamp.core.atomic import atomic_path

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from iamp.core.plan import Plan
    from iamp.core.problem import Problem

PathLike = str | os.PathLike[str]

__all__ = [
    "PALETTE",
    "draw_xy",
    "is_avoidance",
    "lane_lines",
    "legend_below",
    "planner_style",
    "plot_costates",
    "plot_positions",
    "plot_predictions",
    "plot_timing",
    "plot_value_function",
    "plot_xy_snapshots",
    "plot_zoh_convergence",
    "save_figure",
    "save_one",
    "scenario_color",
    "tidy_axis",
    "xy_figsize",
    "xy_limits",
]

FORMATS = ("png", "pdf")
DPI = 150

# --- one palette for every figure ------------------------------------------------------
#: Colour of each planner family, the same in every figure of the report and of ``iamp plot``
#: (a label is matched by :func:`planner_style`). Red is reserved for safety regions, contact
#: points and jumps; grey shades and olive/pink for the surrounding vehicles.
PALETTE: dict[str, str] = {
    "pmp": "tab:green",
    "clarabel": "tab:blue",
    "osqp": "tab:orange",
    "piqp": "tab:purple",
    "kkt": "tab:brown",
    "safety": "tab:red",
    "other": "tab:gray",
}
#: Marker of each QP solver (ZOH runs use the second marker of the pair).
SOLVER_MARKERS: dict[str, tuple[str, str]] = {"clarabel": ("o", "s"), "osqp": ("x", "+"), "piqp": ("^", "v"),
                                              "kkt": ("D", "d")}
EGO_COLOR = PALETTE["pmp"]  # the ego drawn from a PMP plan
SAFETY_COLOR = PALETTE["safety"]
VEHICLE_COLORS = ("0.45", "tab:olive", "tab:pink", "0.7")
#: Colour of each scenario where scenarios (not planners) are compared.
SCENARIO_COLORS: dict[str, str] = {"paper-1": "0.15", "paper-2": "tab:pink", "paper-3": "tab:olive",
                                   "two-vehicle": "tab:cyan"}
_SCENARIO_CYCLE = ("0.15", "tab:pink", "tab:olive", "tab:cyan", "0.55")


def planner_style(label: str) -> dict[str, str]:
    """Colour, marker, fill and line style of a run label (``pmp``, ``qp-osqp-zoh-100``,
    ``QP clarabel solve, native, ...``): the colour follows the planner or QP solver
    (:data:`PALETTE`), the marker the solver and hold, a filled marker the native path, a
    dashed line the avoidance QP."""
    low = label.lower()
    if "pmp" in low:
        return {"color": PALETTE["pmp"], "marker": "*", "mfc": PALETTE["pmp"], "ls": "-"}
    for key in ("clarabel", "osqp", "piqp", "kkt"):
        if key in low:
            color = PALETTE[key]
            marker = SOLVER_MARKERS[key][1 if "zoh" in low else 0]
            filled = "native" in low and marker not in "x+"
            if "refine" in low:
                marker = "D"
            return {"color": color, "marker": marker, "mfc": color if filled else "none",
                    "ls": "--" if "avoid" in low else "-"}
    return {"color": PALETTE["other"], "marker": "^", "mfc": "none", "ls": ":"}


def is_avoidance(result: Plan) -> bool:
    """Whether ``result`` comes from the avoidance QP (SPEC §10), whose times are crossings."""
    return "avoid" in str((result.info or {}).get("constraint", ""))


def tidy_axis(ax: Axes, values: ArrayLike, *, min_span: float = 0.1) -> None:
    """No offset notation, and a y-range of at least ``min_span`` (relative to the values' size)
    around values that are constant up to rounding, so that 1e-13 noise is not drawn as a signal."""
    ax.ticklabel_format(axis="y", useOffset=False)
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return
    lo, hi = float(np.min(v)), float(np.max(v))
    span = max(min_span * max(abs(lo), abs(hi)), min_span)
    if hi - lo < 1e-6 * span:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - span, mid + span)


def scenario_color(name: str, k: int = 0) -> str:
    """The colour of a scenario (:data:`SCENARIO_COLORS`, else a fixed cycle by position)."""
    return SCENARIO_COLORS.get(name, _SCENARIO_CYCLE[k % len(_SCENARIO_CYCLE)])


def _qp_style(label: str, k: int = 0) -> tuple[str, str]:
    """``(marker, colour)`` of a QP run label (see :func:`planner_style`)."""
    st = planner_style(label)
    return st["marker"], st["color"]


def save_figure(fig: Figure, stem: PathLike, formats: Sequence[str] = FORMATS) -> list[Path]:
    """Write ``fig`` as ``stem.<fmt>`` for every format, atomically; return the paths."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    written = []
    for fmt in formats:
        path = stem.with_name(f"{stem.name}.{fmt}")
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=DPI, bbox_inches="tight",
                        metadata={"CreationDate": None} if fmt == "pdf" else None)
        written.append(path)
    return written


def save_one(fig: Figure, path: PathLike) -> Path:
    """Write ``fig`` to ``path`` atomically, in the format its suffix names (``.png``, ``.pdf``,
    ``.svg``, …); returns the path."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=DPI, bbox_inches="tight",
                    metadata={"CreationDate": None} if fmt == "pdf" else None)
    return path


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
    X = result.trajectory.states(tt)
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
        The ego's body (default: the problem's ego size if it has one, else vehicle 1's
        ``L × W``; the planning model is a point mass).
    time_labels : bool
        Write ``t = …`` above each ego snapshot.
    """
    problem = result.problem
    # the avoidance QP (SPEC §10) reports crossing times τ_i (the ego leaves one half-plane of the
    # corner for the other), not touches of the corner
    crossing = is_avoidance(result)
    ts = np.asarray(times, dtype=float)
    X = result.trajectory.states(ts)
    tt = np.linspace(0.0, problem.tf, 401)
    Xd = result.trajectory.states(tt)
    ego = problem.ego
    L_e, W_e = ego_size or (float(getattr(ego, "length", 0) or problem.vehicles[0].length),
                            float(getattr(ego, "width", 0) or problem.vehicles[0].width))
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


def legend_below(ax: Axes, *, ncol: int = 3, fontsize: float = 7, below_points: float = 36.0) -> Any:
    """A legend under ``ax``, ``below_points`` below its lower edge (clear of the tick labels and
    the x label however short the axes are: equal-aspect road strips are)."""
    return ax.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=ncol, fontsize=fontsize, frameon=False,
                     borderaxespad=below_points / fontsize)


def xy_figsize(result: Plan, width: float = 10.0, extra_height: float = 1.6) -> tuple[float, float]:
    """A figure size whose x–y axes fill the width at equal aspect (plus room for the title and
    a legend below)."""
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
    fig = Figure(figsize=xy_figsize(result, extra_height=2.0), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    draw_xy(ax, result, _snapshot_times(problem.tf, dt), ego_size=ego_size)
    ax.set_title(title or f"{problem.name}: ego and surrounding vehicles every {dt:g} s (lighter = earlier), "
                 "to scale", fontsize=10)
    legend_below(ax, ncol=2, fontsize=8)
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
    X = result.trajectory.states(tt)
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
        ax1.annotate(f"$t^*_{i + 1}$ = {ti:.3f} s\n$x$ = {cx:.2f} m", (ti, cx), textcoords="offset points",
                     xytext=(8, -28), fontsize=8, color=SAFETY_COLOR)
        ax2.annotate(f"$y$ = {cy:.2f} m", (ti, cy), textcoords="offset points", xytext=(8, -14 if i == 0 else 6),
                     fontsize=8, color=SAFETY_COLOR)
    ax1.set_ylabel("$s_x$ [m]")
    ax2.set_ylabel("$s_y$ [m]")
    ax2.set_xlabel("$t$ [s]")
    ax2.set_xlim(0, tf)
    for ax in (ax1, ax2):
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=8, loc="best")
    ax1.set_title(title or f"{problem.name}: optimal longitudinal and lateral position", fontsize=10)
    return save_figure(fig, stem)


def plot_value_function(problem: Problem, pmp_result: Plan, sweeps: dict[str, Any], stem: PathLike, *,
                        title: str | None = None) -> list[Path]:
    """``J(t)`` (closed form, one vehicle), the PMP's ``t*`` and the QP sweep points.

    Parameters
    ----------
    sweeps : dict
        ``{label: (steps, [(nodes, cost), ...])}`` — the QP's ``info["sweep"]`` and its ``N``.
    """
    from iamp.planners.pmp import ValueFunction

    if problem.m != 1:
        raise ValueError("plot_value_function draws J(t) for one vehicle")
    J = ValueFunction(problem)
    tf = problem.tf
    tt = np.linspace(tf * 1e-3, tf * (1 - 1e-3), 4000)
    Jt = J(tt[:, None])
    t_star = float(pmp_result.contact_times[0])
    fig = Figure(figsize=(11.0, 4.4))
    ax_full = fig.add_subplot(1, 2, 1)
    ax_zoom = fig.add_subplot(1, 2, 2)
    half = 0.35 * tf / 5.0
    for ax, zoom in ((ax_full, False), (ax_zoom, True)):
        sel = (np.abs(tt - t_star) <= half) if zoom else np.ones_like(tt, dtype=bool)
        ax.plot(tt[sel], Jt[sel], color=PALETTE["pmp"], lw=1.5, label="$J(t)$: PMP fixed-time optimum (closed form)")
        for label, (steps, table) in sweeps.items():
            h = tf / steps
            pts = np.array([(nodes[0] * h, c) for nodes, c in table if np.isfinite(c)])
            if pts.size == 0:
                continue
            if zoom:
                pts = pts[np.abs(pts[:, 0] - t_star) <= half]
            st = planner_style(label)
            marker, color = st["marker"], st["color"]
            ax.plot(pts[:, 0], pts[:, 1], marker, ms=5 if zoom else 3.5, mfc=st["mfc"],
                    color=color, ls="none", label=f"QP sweep points, {label}")
            if len(pts):
                best = pts[np.argmin(pts[:, 1])]
                ax.plot([best[0]], [best[1]], marker, ms=12, mfc="none", mew=1.5,
                        color=color, label=f"QP sweep best, {label}: $t$ = {best[0]:.3f} s" if zoom else None)
        ax.axvline(t_star, color=SAFETY_COLOR, ls="--", lw=1.0)
        ax.plot([t_star], [float(pmp_result.cost or np.nan)], "*", ms=14, color=PALETTE["pmp"], mec="k", zorder=5,
                label=f"PMP $t^*$ = {t_star:.4f} s, $J^*$ = {pmp_result.cost:.4f}" if zoom else "PMP $t^*$")
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
        ax.set_xlabel("contact time $t_1$ [s]")
    ax_full.set_yscale("log")
    ax_full.set_xlim(0, tf)
    finite = Jt[np.isfinite(Jt)]
    ax_full.set_ylim(0.8 * float(np.min(finite)), min(float(np.max(finite)), 1e3 * float(np.min(finite))))
    ax_full.set_ylabel("$J = \\frac{1}{2}\\int_0^{t_f} (u_x^2 + u_y^2)\\,dt$ [m$^2$/s$^3$]")
    ax_zoom.set_ylabel("$J$ [m$^2$/s$^3$]")
    ax_full.set_title("whole horizon (log scale)", fontsize=9)
    ax_zoom.set_xlim(t_star - half, t_star + half)
    zsel = np.abs(tt - t_star) <= half
    zj = Jt[zsel & np.isfinite(Jt)]
    ax_zoom.set_ylim(float(np.min(zj)) - 0.05 * float(np.ptp(zj)), float(np.max(zj)))
    ax_zoom.set_title(f"around $t^*$ (±{half:.2f} s)", fontsize=9)
    ax_full.legend(fontsize=7, loc="upper center")
    ax_zoom.legend(fontsize=7, loc="upper center")
    fig.suptitle(title or f"{problem.name}: cost against contact time", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, stem)


def plot_costates(pmp_result: Plan, qp_results: dict[str, Plan | None], stem: PathLike, *,
                  title: str | None = None) -> list[Path]:
    """Co-states ``p1..p4`` with their jumps, beside the QP multipliers ``ν``.

    Layout: the x axis in the left column, y in the right; rows ``p1 | p3`` (the jumping
    co-states, a vertical segment at each ``t_i`` spans the jump ``Φ_i``), ``p2 | p4``
    (continuous), and the jumps themselves: ``Φ_i,x`` against ``ν_i,x``, ``Φ_i,y`` against
    ``ν_i,y``, each marker at its planner's own contact time.
    """
    sol = pmp_result.trajectory
    problem = pmp_result.problem
    tf = problem.tf
    ct = np.asarray(pmp_result.contact_times, dtype=float)
    # evaluate piecewise, with the one-sided limits at the breakpoints
    bps = np.unique(np.r_[0.0, ct, tf])
    fig = Figure(figsize=(10.0, 9.5))
    axes = [[fig.add_subplot(3, 2, 2 * r + c + 1) for c in range(2)] for r in range(3)]
    # units: H = ½|u|² + p·f has units m²/s⁴, so p1, p3 = ∂H/∂v [m/s³] and p2, p4 = ∂H/∂u [m/s²]
    names = {(0, 0): (0, "$p_1$ (jumps by $\\Phi_{i,x}$)", "$p_1$ [m/s$^3$]"),
             (0, 1): (2, "$p_3$ (jumps by $\\Phi_{i,y}$)", "$p_3$ [m/s$^3$]"),
             (1, 0): (1, "$p_2 = -u_x$ (continuous)", "$p_2$ [m/s$^2$]"),
             (1, 1): (3, "$p_4 = -u_y$ (continuous)", "$p_4$ [m/s$^2$]")}
    for (r, c), (col, lab, ylab) in names.items():
        ax = axes[r][c]
        ax.set_ylabel(ylab)
        ax.set_xlabel("$t$ [s]")
        for j in range(len(bps) - 1):
            seg = np.linspace(bps[j], bps[j + 1], 100)
            eps = 1e-12 * tf
            seg_eval = np.clip(seg, bps[j] + eps, bps[j + 1] - eps)
            P_ = sol.costates(seg_eval)
            ax.plot(seg, P_[:, col], color=PALETTE["pmp"], lw=1.5, label=lab if j == 0 else None)
        if col in (0, 2):
            pl = sol.costates(ct, "left")[:, col]
            pr = sol.costates(ct, "right")[:, col]
            for i, ti in enumerate(ct):
                ax.plot([ti, ti], [pr[i], pl[i]], color=SAFETY_COLOR, lw=2.0,
                        label="jump $p^- - p^+ = \\Phi_i$" if i == 0 else None)
                ax.annotate(f"$\\Phi_{{{i + 1},{'x' if col == 0 else 'y'}}}$ = {pl[i] - pr[i]:.4g}",
                            (ti, 0.5 * (pl[i] + pr[i])), textcoords="offset points", xytext=(6, 0), fontsize=8,
                            color=SAFETY_COLOR)
        for ti in ct:
            ax.axvline(ti, color=SAFETY_COLOR, ls=":", lw=0.8)
        ax.set_xlim(0, tf)
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=8, loc="best")
    # jumps against multipliers
    curve = None
    if problem.m == 1:  # Φ(t) of the fixed-time solution near t*: the QP's ν lies on it (SPEC §3.3)
        from iamp.planners.pmp import solve_fixed_times

        tq_all = [float(t) for r in qp_results.values() if r is not None and r.is_optimal()
                  for t in np.asarray(r.contact_times, dtype=float)]
        lo = max(min([ct[0]] + tq_all) - 0.4, 0.02 * tf)
        hi = min(max([ct[0]] + tq_all) + 0.4, 0.98 * tf)
        tg = np.linspace(lo, hi, 161)
        curve = (tg, np.array([solve_fixed_times(problem, [t]).jumps[0] for t in tg]))
    for c, (axis_name, idx) in enumerate((("x", 0), ("y", 1))):
        ax = axes[2][c]
        if curve is not None:
            ax.plot(curve[0], curve[1][:, idx], color="0.4", lw=1.0,
                    label=f"PMP $\\Phi_{{1,{axis_name}}}(t)$ at a fixed contact time $t$")
        for i, ti in enumerate(ct):
            ax.plot([ti], [pmp_result.jumps[i, idx]], "*", ms=14, color=PALETTE["pmp"], mec="k",
                    label=f"PMP $\\Phi_{{i,{axis_name}}}$ at $t^*_i$" if i == 0 else None, zorder=5)
        for label, res in qp_results.items():
            if res is None or not res.is_optimal():
                continue
            st = planner_style(label)
            tq = np.asarray(res.contact_times, dtype=float)
            ax.plot(tq, res.jumps[:, idx], st["marker"], ms=9, mew=1.5, mfc=st["mfc"],
                    color=st["color"], ls="none", label=f"QP $\\nu_{{i,{axis_name}}}$, {label}")
        ax.axhline(0.0, color="0.5", lw=0.6)
        if curve is not None:  # zoom on the contact times
            ax.set_xlim(curve[0][0], curve[0][-1])
        else:
            ax.set_xlim(0, tf)
        ax.set_xlabel("$t$ [s]" if curve is None else "$t$ [s] (zoomed on the contact times)")
        ax.set_ylabel(f"$\\Phi_{{i,{axis_name}}}$, $\\nu_{{i,{axis_name}}}$ [m/s$^3$]")
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or f"{problem.name}: co-states and jumps (PMP) against QP multipliers", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, stem)


def plot_zoh_convergence(series: dict[str, Any], stem: PathLike, *, title: str | None = None) -> list[Path]:
    """``J_ZOH − J_PMP`` (same contact node) against ``h`` on log–log axes.

    Parameters
    ----------
    series : dict
        ``{label: (h_values, gaps)}``; a slope-2 guide is drawn through the first series.
    """
    fig = Figure(figsize=(6.0, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    first = None
    for k, (label, (h, gap)) in enumerate(series.items()):
        h = np.asarray(h, dtype=float)
        gap = np.asarray(gap, dtype=float)
        ok = gap > 0
        ax.loglog(h[ok], gap[ok], "o-", color=scenario_color(label, k), label=label)
        if first is None and ok.sum() >= 2:
            first = (h[ok], gap[ok])
    if first is not None:
        h, gap = first
        ref = gap[-1] * (h / h[-1]) ** 2
        ax.loglog(h, ref * 0.5, "k--", lw=1.0, label="slope 2 guide, $\\propto h^2$")
    if first is not None:  # label the measured step sizes only (minor log labels overlap)
        from matplotlib.ticker import FixedLocator, NullLocator

        ax.xaxis.set_major_locator(FixedLocator(sorted(first[0])))
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xticklabels([f"{h:.4g}" for h in sorted(first[0])])
    ax.set_xlabel("step $h = t_f/N$ [s]")
    ax.set_ylabel("$J_\\mathrm{ZOH} - J_\\mathrm{PMP}$ [m$^2$/s$^3$] (same contact time)")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=8)
    ax.set_title(title or "ZOH discretisation gap against step size", fontsize=10)
    return save_figure(fig, stem)


def plot_timing(samples: dict[str, Any], stem: PathLike, *, whole_plans: dict[str, Any] | None = None,
                title: str | None = None) -> list[Path]:
    """Wall times, log scale, coloured by planner (:func:`planner_style`).

    Left (if ``whole_plans``): whole plans, contact-time search included — the median with
    its quartiles as a bar, one row per run, from the statistics of the planning step (the
    same numbers as the timing table). Right: single QP solves at a changed candidate node —
    box (quartiles, whiskers 5–95 %) with every sample jittered over it.

    Parameters
    ----------
    samples : dict
        ``{label: sequence of seconds}``; empty sequences are skipped.
    whole_plans : dict, optional
        ``{label: {"median", "q1", "q3", "n"}}``.
    """
    items = [(k, np.asarray(v, dtype=float)) for k, v in samples.items() if len(v)]
    plans = [(k, st) for k, st in (whole_plans or {}).items() if st and st.get("median")]
    rows = max(len(items), len(plans), 1)
    ncols = 2 if plans else 1
    fig = Figure(figsize=(7.0 * ncols, max(3.0, 0.42 * rows + 1.4)), layout="constrained")
    axes = [fig.add_subplot(1, ncols, c + 1) for c in range(ncols)]
    if plans:
        ax = axes[0]
        pos = np.arange(len(plans), 0, -1)
        for y, (label, st) in zip(pos, plans):
            sty = planner_style(label)
            ax.errorbar([st["median"]], [y], xerr=[[st["median"] - st["q1"]], [st["q3"] - st["median"]]],
                        fmt=sty["marker"], ms=7, mfc=sty["mfc"], color=sty["color"], capsize=3)
        ax.set_yticks(pos)
        ax.set_yticklabels([f"{k} (n={st['n']})" for k, st in plans], fontsize=8)
        ax.set_xscale("log")
        ax.set_xlabel("wall time of a whole plan [s] (median, bar: quartiles)")
        ax.set_title("whole plans, contact-time search included", fontsize=9)
        ax.grid(True, axis="x", which="both", lw=0.3, alpha=0.5)
    ax = axes[-1]
    if items:
        data = [v[v > 0] for _, v in items]
        pos = np.arange(len(items), 0, -1)  # first configuration on top
        import inspect

        horizontal = ({"orientation": "horizontal"}
                      if "orientation" in inspect.signature(ax.boxplot).parameters else {"vert": False})
        ax.boxplot(data, positions=pos, whis=(5, 95), showfliers=False, widths=0.5,
                   medianprops={"color": "k"}, **horizontal)
        rng = np.random.default_rng(0)
        for k, d in enumerate(data):
            ax.plot(d, pos[k] + rng.uniform(-0.15, 0.15, d.size), ".", ms=3, alpha=0.6,
                    color=planner_style(items[k][0])["color"])
        ax.set_yticks(pos)
        ax.set_yticklabels([f"{k} (n={len(v)})" for k, v in items], fontsize=8)
        ax.set_xscale("log")
    else:
        ax.text(0.5, 0.5, "no timing samples", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("wall time of one QP solve [s]")
    ax.grid(True, axis="x", which="both", lw=0.3, alpha=0.5)
    ax.set_title("one QP solve at a changed candidate node (box: quartiles, whiskers: 5-95 %)", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, stem)


def plot_predictions(entries: dict[str, Any], stem: PathLike, *, tf: float, title: str | None = None) -> list[Path]:
    """Observed history, the predictor's samples and the fitted cubic handed to the planners.

    Parameters
    ----------
    entries : dict
        ``{label: {"history_t", "history_x", "pred_t", "pred_x", "x_poly"}}`` (any of the
        sample arrays may be ``None``).
    """
    fig = Figure(figsize=(7.0, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    tt = np.linspace(0.0, tf, 200)
    for k, (label, e) in enumerate(entries.items()):
        col = scenario_color(label, k)
        if e.get("history_t") is not None:
            ax.plot(e["history_t"], e["history_x"], ".", ms=3, color=col, label=f"{label}: observed history")
        if e.get("pred_t") is not None:
            ax.plot(e["pred_t"], e["pred_x"], "o", ms=3, mfc="none", color=col, alpha=0.6,
                    label=f"{label}: predicted samples")
        ax.plot(tt, np.polynomial.polynomial.polyval(tt, e["x_poly"]), "-", lw=1.5, color=col,
                label=f"{label}: cubic $x_{{s,1}}(t)$")
    ax.axvline(0.0, color="0.4", lw=0.8)
    ax.set_xlabel("$t$ [s]")
    ax.set_ylabel("$x_{s,1}$ [m]")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=7, ncol=3, loc="upper center", bbox_to_anchor=(0.5, -0.13), frameon=False)
    ax.set_title(title or "vehicle 1: history and prediction", fontsize=10)
    return save_figure(fig, stem)
