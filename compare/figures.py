r"""Figures of the reproduction report (the paper's Figs. 4–9 and the comparison beyond it).

Every function draws on a fresh :class:`matplotlib.figure.Figure` (no ``pyplot``, no global
state, no display: the Agg canvas is used for PNG and the PDF backend for PDF) and writes
``<stem>.png`` and ``<stem>.pdf`` atomically (saved to a temporary name in the same folder,
then :func:`os.replace`).  Each returns the list of the two paths written.

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
* :func:`plot_timing` — solve-time distributions per planner configuration.
* :func:`plot_predictions` — observed history, predicted samples and the fitted cubic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from iamp.core.atomic import atomic_path
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

__all__ = [
    "save_figure",
    "lane_lines",
    "plot_xy_snapshots",
    "plot_positions",
    "plot_value_function",
    "plot_costates",
    "plot_zoh_convergence",
    "plot_timing",
    "plot_predictions",
]

FORMATS = ("png", "pdf")
DPI = 150
EGO_COLOR = "tab:green"
VEHICLE_COLORS = ("tab:orange", "tab:blue", "tab:purple", "tab:brown")
SAFETY_COLOR = "tab:red"
QP_STYLES = {  # label prefix -> (marker, colour)
    "clarabel": ("o", "tab:blue"),
    "osqp": ("x", "tab:orange"),
}


def _qp_style(label: str, k: int):
    for key, style in QP_STYLES.items():
        if key in label:
            marker, color = style
            if "zoh" in label:
                marker = "s" if key == "clarabel" else "+"
            return marker, color
    return ("^v<>"[k % 4], f"C{(k + 2) % 10}")


def save_figure(fig: Figure, stem, formats=FORMATS) -> list[Path]:
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


def lane_lines(problem) -> tuple[list[float], list[float]]:
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


def plot_xy_snapshots(result, stem, *, dt: float = 0.5, title: str | None = None,
                      ego_size=None) -> list[Path]:
    """The paper's Figs. 4–6: ego and surrounding vehicles every ``dt`` s in the x–y plane.

    Parameters
    ----------
    result : Plan
        An optimal plan (its ``problem`` gives the vehicles).
    stem : path-like
        Output path without extension.
    dt : float
        Snapshot spacing [s].
    ego_size : (length, width), optional
        Body drawn for the ego (default: vehicle 1's ``L × W``; the ego is a point mass in
        the model).
    """
    problem = result.problem
    tf = problem.tf
    ts = _snapshot_times(tf, dt)
    X = result.trajectory.states(ts)
    tt = np.linspace(0.0, tf, 401)
    Xd = result.trajectory.states(tt)
    L_e, W_e = ego_size or (problem.vehicles[0].length, problem.vehicles[0].width)

    fig = Figure(figsize=(10.0, 4.2))
    ax = fig.add_subplot(1, 1, 1)
    alphas = np.linspace(0.25, 1.0, len(ts))

    # lanes
    xs_all = [Xd[:, 0]] + [v.position(tt) for v in problem.vehicles]
    xmin = min(np.min(x) for x in xs_all) - 12.0
    xmax = max(np.max(x) for x in xs_all) + 12.0
    edges, dividers = lane_lines(problem)
    for y in edges:
        ax.axhline(y, color="0.3", lw=1.5, zorder=0)
    for y in dividers:
        ax.axhline(y, color="0.5", lw=1.0, ls=(0, (8, 6)), zorder=0)

    # surrounding vehicles: body and safety box at every snapshot
    for i, v in enumerate(problem.vehicles):
        col = VEHICLE_COLORS[i % len(VEHICLE_COLORS)]
        hx = v.length / 2 + v.safety_x
        hy = v.width / 2 + v.safety_y
        for k, t in enumerate(ts):
            xc = float(v.position(t))
            ax.add_patch(Rectangle((xc - hx, v.y - hy), 2 * hx, 2 * hy, fill=False, ec=SAFETY_COLOR,
                                   lw=0.6, alpha=0.35 * alphas[k], zorder=1))
            ax.add_patch(Rectangle((xc - v.length / 2, v.y - v.width / 2), v.length, v.width, fc=col,
                                   ec="k", lw=0.4, alpha=0.8 * alphas[k], zorder=2))
        ax.plot([], [], color=col, lw=6, alpha=0.8, label=f"vehicle {i + 1} ({v.name}) every {dt:g} s")
    ax.plot([], [], color=SAFETY_COLOR, lw=1, alpha=0.5, label="safety boxes $\\pm(L/2+S_x)\\times\\pm(W/2+S_y)$")

    # ego
    ax.plot(Xd[:, 0], Xd[:, 2], color=EGO_COLOR, lw=1.2, zorder=3, label="ego path $(s_x, s_y)$")
    for k in range(len(ts)):
        # axis-aligned body: the axes are not to scale, a rotated box would look sheared
        rect = Rectangle((X[k, 0] - L_e / 2, X[k, 2] - W_e / 2), L_e, W_e, fc=EGO_COLOR, ec="k", lw=0.4,
                         alpha=0.85 * alphas[k], zorder=4)
        ax.add_patch(rect)
    ax.plot(X[:, 0], X[:, 2], "o", ms=2.5, color="k", zorder=5, label=f"ego every {dt:g} s")

    # the contact: safety box at t_i (solid red) and the corner
    for i, (v, ti) in enumerate(zip(problem.vehicles, result.contact_times)):
        if not np.isfinite(ti):
            continue
        hx = v.length / 2 + v.safety_x
        hy = v.width / 2 + v.safety_y
        xc = float(v.position(ti))
        ax.add_patch(Rectangle((xc - hx, v.y - hy), 2 * hx, 2 * hy, fill=False, ec=SAFETY_COLOR, lw=1.6,
                               ls="--", zorder=6))
        ax.add_patch(Rectangle((xc - v.length / 2, v.y - v.width / 2), v.length, v.width, fill=False,
                               ec="k", lw=1.0, ls="--", zorder=6))
        cx, cy = float(v.corner_x(ti)), v.corner_y
        se = result.trajectory.states(np.array([ti]))[0]
        ax.plot([cx], [cy], "*", ms=12, color=SAFETY_COLOR, mec="k", mew=0.5, zorder=7,
                label=f"contact with vehicle {i + 1}: {v.corner} corner at $t_{i + 1}$ = {ti:.2f} s")
        ax.plot([se[0]], [se[2]], "o", ms=5, mfc="none", mec="k", zorder=7)

    ax.set_xlim(xmin, xmax)
    ylo = min(edges[0], np.min(Xd[:, 2]) - 1.0) - 0.5
    yhi = max(edges[-1], np.max(Xd[:, 2]) + 1.0) + 0.5
    ax.set_ylim(ylo, yhi)
    ax.set_xlabel("$x$ [m]")
    ax.set_ylabel("$y$ [m]")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.set_title(title or f"{problem.name}: ego and surrounding vehicles every {dt:g} s "
                 "(lighter = earlier)", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3, fontsize=8, frameon=False)
    return save_figure(fig, stem)


def plot_positions(result, stem, *, title: str | None = None, show_vehicles: bool = True) -> list[Path]:
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


def plot_value_function(problem, pmp_result, sweeps: dict, stem, *, title: str | None = None) -> list[Path]:
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
        ax.plot(tt[sel], Jt[sel], color="k", lw=1.5, label="$J(t)$: PMP fixed-time optimum (closed form)")
        for k, (label, (steps, table)) in enumerate(sweeps.items()):
            h = tf / steps
            pts = np.array([(nodes[0] * h, c) for nodes, c in table if np.isfinite(c)])
            if pts.size == 0:
                continue
            if zoom:
                pts = pts[np.abs(pts[:, 0] - t_star) <= half]
            marker, color = _qp_style(label, k)
            ax.plot(pts[:, 0], pts[:, 1], marker, ms=5 if zoom else 3.5, mfc="none" if marker in "os" else None,
                    color=color, ls="none", label=f"QP sweep points, {label}")
            if len(pts):
                best = pts[np.argmin(pts[:, 1])]
                ax.plot([best[0]], [best[1]], marker, ms=12, mfc="none" if marker in "os" else None, mew=1.5,
                        color=color, label=f"QP sweep best, {label}: $t$ = {best[0]:.3f} s" if zoom else None)
        ax.axvline(t_star, color=SAFETY_COLOR, ls="--", lw=1.0)
        ax.plot([t_star], [pmp_result.cost], "*", ms=14, color=SAFETY_COLOR, mec="k", zorder=5,
                label=f"PMP $t^*$ = {t_star:.4f} s, $J^*$ = {pmp_result.cost:.4f}" if zoom else "PMP $t^*$")
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
        ax.set_xlabel("contact time $t_1$ [s]")
    ax_full.set_yscale("log")
    ax_full.set_xlim(0, tf)
    finite = Jt[np.isfinite(Jt)]
    ax_full.set_ylim(0.8 * float(np.min(finite)), min(float(np.max(finite)), 1e3 * float(np.min(finite))))
    ax_full.set_ylabel("$J = \\frac{1}{2}\\int_0^{t_f} (u_x^2 + u_y^2)\\,dt$")
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


def plot_costates(pmp_result, qp_results: dict, stem, *, title: str | None = None) -> list[Path]:
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
    fig = Figure(figsize=(9.0, 8.0))
    axes = [[fig.add_subplot(3, 2, 2 * r + c + 1) for c in range(2)] for r in range(3)]
    names = {(0, 0): (0, "$p_1$ (jumps by $\\Phi_{i,x}$)"), (0, 1): (2, "$p_3$ (jumps by $\\Phi_{i,y}$)"),
             (1, 0): (1, "$p_2 = -u_x$ (continuous)"), (1, 1): (3, "$p_4 = -u_y$ (continuous)")}
    for (r, c), (col, lab) in names.items():
        ax = axes[r][c]
        for j in range(len(bps) - 1):
            seg = np.linspace(bps[j], bps[j + 1], 100)
            eps = 1e-12 * tf
            seg_eval = np.clip(seg, bps[j] + eps, bps[j + 1] - eps)
            P_ = sol.costates(seg_eval)
            ax.plot(seg, P_[:, col], color="k", lw=1.5, label=lab if j == 0 else None)
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
            ax.plot([ti], [pmp_result.jumps[i, idx]], "*", ms=14, color=SAFETY_COLOR, mec="k",
                    label=f"PMP $\\Phi_{{i,{axis_name}}}$ at $t^*_i$" if i == 0 else None, zorder=5)
        for k, (label, res) in enumerate(qp_results.items()):
            if res is None or not res.is_optimal():
                continue
            marker, color = _qp_style(label, k)
            tq = np.asarray(res.contact_times, dtype=float)
            ax.plot(tq, res.jumps[:, idx], marker, ms=9, mew=1.5, mfc="none" if marker in "os" else None,
                    color=color, ls="none", label=f"QP $\\nu_{{i,{axis_name}}}$, {label}")
        ax.axhline(0.0, color="0.5", lw=0.6)
        if curve is not None:  # zoom on the contact times
            ax.set_xlim(curve[0][0], curve[0][-1])
        else:
            ax.set_xlim(0, tf)
        ax.set_xlabel("$t$ [s]" if curve is None else "$t$ [s] (zoomed on the contact times)")
        ax.set_ylabel(f"jump / multiplier, {axis_name} axis")
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or f"{problem.name}: co-states and jumps (PMP) against QP multipliers", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, stem)


def plot_zoh_convergence(series: dict, stem, *, title: str | None = None) -> list[Path]:
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
        ax.loglog(h[ok], gap[ok], "o-", color=f"C{k}", label=label)
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
    ax.set_ylabel("$J_\\mathrm{ZOH} - J_\\mathrm{PMP}$ (same contact time)")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=8)
    ax.set_title(title or "ZOH discretisation gap against step size", fontsize=10)
    return save_figure(fig, stem)


def plot_timing(samples: dict, stem, *, title: str | None = None) -> list[Path]:
    """Solve-time distributions (box plot with the samples jittered over it, log scale).

    Parameters
    ----------
    samples : dict
        ``{label: sequence of seconds}``; empty sequences are skipped.
    """
    items = [(k, np.asarray(v, dtype=float)) for k, v in samples.items() if len(v)]
    fig = Figure(figsize=(8.0, max(3.0, 0.45 * len(items) + 1.2)))
    ax = fig.add_subplot(1, 1, 1)
    if items:
        data = [v[v > 0] for _, v in items]
        pos = np.arange(len(items), 0, -1)  # first configuration on top
        import inspect

        horizontal = ({"orientation": "horizontal"}
                      if "orientation" in inspect.signature(ax.boxplot).parameters else {"vert": False})
        ax.boxplot(data, positions=pos, whis=(5, 95), showfliers=False, widths=0.5, **horizontal)
        rng = np.random.default_rng(0)
        for k, d in enumerate(data):
            ax.plot(d, pos[k] + rng.uniform(-0.15, 0.15, d.size), ".", ms=3, alpha=0.5, color=f"C{k % 10}")
        ax.set_yticks(pos)
        ax.set_yticklabels([f"{k} (n={len(v)})" for k, v in items], fontsize=8)
        ax.set_xscale("log")
    else:
        ax.text(0.5, 0.5, "no timing samples", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("wall time per plan or solve [s]")
    ax.grid(True, axis="x", which="both", lw=0.3, alpha=0.5)
    ax.set_title(title or "solve-time distributions (box: quartiles, whiskers: 5-95 %)", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, stem)


def plot_predictions(entries: dict, stem, *, tf: float, title: str | None = None) -> list[Path]:
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
        col = f"C{k}"
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
