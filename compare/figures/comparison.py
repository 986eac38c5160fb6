r"""Figures of the PMP against the discretised QP: the cost of the contact time, and the
co-state jumps against the QP's multipliers.

* :func:`plot_value_function` — ``J(t)`` of the fixed-contact-time problem (closed form,
  :class:`~iamp.planners.pmp.planner.ValueFunction`), the PMP's ``t*`` and the QP's sweep points.
* :func:`plot_costates` — co-states ``p1..p4`` with their jumps at ``t_i``,
  :math:`p^-(t_i) - p^+(t_i) = \Phi_i`, beside the QP multipliers ``ν`` (``ν_x`` against the
  ``p1`` jump, ``ν_y`` against the ``p3`` jump; at equal contact times ``ν_i = Φ_i``, SPEC §3.3).

Palette, conventions and the atomic writing: :mod:`iamp.comparison.figures.style`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from iamp.comparison.trajectories import pmp_solution

from .style import PALETTE, SAFETY_COLOR, PathLike, legend_below, planner_style, save_figure

if TYPE_CHECKING:  # pragma: no cover
    from iamp.core.plan import Plan
    from iamp.core.problem import Problem

__all__ = ["plot_costates", "plot_value_function"]


def plot_value_function(problem: Problem, pmp_result: Plan,
                        sweeps: Mapping[str, tuple[int | None, list[tuple[tuple[int, ...], float]]]], stem: PathLike, *,
                        title: str | None = None) -> list[Path]:
    """``J(t)`` (closed form, one vehicle), the PMP's ``t*`` and the QP sweep points.

    Parameters
    ----------
    sweeps : dict
        ``{label: (steps, [(nodes, cost), ...])}`` — the QP's ``info["sweep"]`` and its ``N``.
    """
    from iamp.planners.pmp.planner import ValueFunction

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
            assert steps is not None, f"{label}: a QP sweep has its N"
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


def plot_costates(pmp_result: Plan, qp_results: Mapping[str, Plan | None], stem: PathLike, *,
                  title: str | None = None) -> list[Path]:
    """Co-states ``p1..p4`` with their jumps, beside the QP multipliers ``ν``.

    Layout: the x axis in the left column, y in the right; rows ``p1 | p3`` (the jumping
    co-states, a vertical segment at each ``t_i`` spans the jump ``Φ_i``), ``p2 | p4``
    (continuous), and the jumps themselves: ``Φ_i,x`` against ``ν_i,x``, ``Φ_i,y`` against
    ``ν_i,y``, each marker at its planner's own contact time.
    """
    sol = pmp_solution(pmp_result)
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
            span = float(np.ptp(sol.costates(np.linspace(0.0, tf, 201))[:, col])) or 1.0
            for i, ti in enumerate(ct):
                ax.plot([ti, ti], [pr[i], pl[i]], color=SAFETY_COLOR, lw=2.0,
                        label="jump $p^- - p^+ = \\Phi_i$" if i == 0 else None)
                # beside the jump, on the side away from the axes' edge; a small jump's label goes
                # above or below both levels of p (centred on the segment it would sit on the line)
                left = ti > 0.7 * tf
                if abs(pl[i] - pr[i]) > 0.25 * span:
                    anchor, dy, va = 0.5 * (pl[i] + pr[i]), 0, "center"
                else:
                    up = max(pl[i], pr[i]) < float(np.mean(ax.get_ylim()))
                    anchor, dy, va = (max(pl[i], pr[i]), 8, "bottom") if up else (min(pl[i], pr[i]), -8, "top")
                ax.annotate(f"$\\Phi_{{{i + 1},{'x' if col == 0 else 'y'}}}$ = {pl[i] - pr[i]:.4g}",
                            (ti, anchor), textcoords="offset points", xytext=(-6 if left else 6, dy), fontsize=8,
                            color=SAFETY_COLOR, ha="right" if left else "left", va=va,
                            bbox={"fc": "white", "ec": "none", "alpha": 0.85, "pad": 1.0})
        for ti in ct:
            ax.axvline(ti, color=SAFETY_COLOR, ls=":", lw=0.8)
        ax.set_xlim(0, tf)
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=8, loc="best")
    # jumps against multipliers
    curve = None
    if problem.m == 1:  # Φ(t) of the fixed-time solution near t*: the QP's ν lies on it (SPEC §3.3)
        from iamp.planners.pmp.planner import solve_fixed_times

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
        legend_below(ax, ncol=2, fontsize=7)  # below the axes: the markers sit on top of one another
    fig.suptitle(title or f"{problem.name}: co-states and jumps (PMP) against QP multipliers", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, stem)
