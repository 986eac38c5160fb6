"""Figures of an episode and of a campaign (matplotlib, Agg; written atomically)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from iamp.core.atomic import atomic_path
from iamp.simulation.episode import EpisodeResult


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def episode_figure(result: EpisodeResult, path: str | Path) -> None:
    """:func:`episode_figure_object`, written atomically to ``path`` (PNG, PDF or SVG)."""
    plt = _plt()
    fig = episode_figure_object(result)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=Path(path).suffix.lstrip(".") or "png", dpi=110)
    plt.close(fig)


def episode_figure_object(result: EpisodeResult) -> Any:
    """The lane change laterally against distance, speeds, accelerations, plan time per step.

    The top panel shows the first manoeuvre in the road frame: the ego's lateral position
    against the distance it travelled (``x - x_0``, from one second before the manoeuvre), the
    neighbours' paths and bodies at the same instants in the same frame.  A lane change over
    ~100 m is a few metres wide, so the lateral scale is stretched (stated on the axis); the
    earlier panel in the frame moving with the ego drew the whole manoeuvre as a vertical bar
    (issue 22 item 14).
    """
    plt = _plt()
    from matplotlib.patches import Rectangle

    log = result.log
    t = np.asarray(log.t)
    E = np.asarray(log.ego).reshape(-1, 6)
    s = result.summary
    fig = plt.figure(figsize=(11, 9), constrained_layout=True)
    gs = fig.add_gridspec(4, 1, height_ratios=[1.5, 1, 1, 1])
    ax = fig.add_subplot(gs[0])
    active = np.array([m == "active" or m == "abort" for m in log.mode])
    idx = np.flatnonzero(active)
    k0 = int(idx[0]) if idx.size else 0
    k1 = min(k0 + int(7.0 / s["period_s"]), len(t) - 1)
    ks = list(range(max(k0 - int(1.0 / s["period_s"]), 0), k1 + 1))
    x0 = float(E[ks[0], 0])
    span = float(E[ks[-1], 0] - x0)
    lo_x, hi_x = -20.0, span + 40.0
    tracks: dict[str, list[tuple[float, float]]] = {}
    for k in ks:
        for vid, row in zip(log.ids[k], log.nb[k]):
            if lo_x <= row[0] - x0 <= hi_x:
                tracks.setdefault(vid, []).append((row[0] - x0, row[1]))
    for n, pts in enumerate(tracks.values()):
        a = np.asarray(pts)
        ax.plot(a[:, 0], a[:, 1], color="tab:blue", lw=0.8, alpha=0.6, label="neighbours" if n == 0 else None)
    ax.plot(E[ks, 0] - x0, E[ks, 2], color="tab:red", lw=2, label="ego (centre)")
    for k in ks[:: max(len(ks) // 6, 1)]:
        for row in log.nb[k]:
            if lo_x <= row[0] - x0 <= hi_x:
                ax.add_patch(Rectangle((row[0] - x0 - row[5] / 2, row[1] - row[6] / 2), row[5], row[6],
                                       fc="tab:blue", alpha=0.12, ec="none"))
        ax.add_patch(Rectangle((E[k, 0] - x0 - 2.4, E[k, 2] - 0.9), 4.8, 1.8, fc="tab:red", alpha=0.25, ec="none"))
        ax.annotate(f"{t[k]:.1f} s", (E[k, 0] - x0, E[k, 2] + 1.1), fontsize=7, ha="center", color="tab:red")
    for lane_edge in (0.0, -3.75, -7.5, -11.25):
        ax.axhline(lane_edge, color="k", lw=0.5, ls="--")
    ax.set_xlim(lo_x, hi_x)
    ax.set_ylim(-12, 1.5)
    ax.set_xlabel("distance along the road from the ego's position 1 s before the manoeuvre, x - x_0 [m]")
    ax.set_ylabel("y [m] (lateral scale stretched)")
    ax.set_title(f"{s['planner']}, {s['traffic']} traffic, seed {s['seed']}: {s['lane_changes']} lane changes, "
                 f"{s['collisions']} collisions; first manoeuvre t = {t[ks[0]]:.1f}..{t[ks[-1]]:.1f} s "
                 "(bodies every ~1 s)", fontsize=9)
    ax.legend(loc="lower right", fontsize=9)
    ax = fig.add_subplot(gs[1])
    ax.plot(t, E[:, 1], color="tab:red", label="ego $v_x$")
    ax.plot(t, E[:, 3], color="tab:orange", label="ego $v_y$")
    ax.set_ylabel("speed [m/s]")
    ax.legend(fontsize=8)
    ax = fig.add_subplot(gs[2])
    dt = s["period_s"]
    ax.plot(t[1:-1], np.diff(E[:, 0], 2) / dt**2, color="tab:red", lw=1, label="ego $a_x$ (executed)")
    ax.plot(t[1:-1], np.diff(E[:, 2], 2) / dt**2, color="tab:orange", lw=1, label="ego $a_y$ (executed)")
    ax.set_ylabel("acceleration [m/s²]")
    ax.legend(fontsize=8)
    ax = fig.add_subplot(gs[3])
    pt = np.asarray(log.plan_time) * 1e3
    ax.semilogy(t, pt, ".", ms=3, color="tab:green", label="plan time")
    ax.axhline(dt * 1e3, color="k", lw=0.8, ls=":", label="period")
    ax.set_ylabel("plan time [ms]")
    ax.set_xlabel("episode time t [s]")
    ax.legend(fontsize=8)
    return fig


def campaign_figures(cells: list[dict[str, Any]], rows: list[dict[str, str]], folder: str | Path) -> list[Path]:
    """Per mission: success, contact and hard-brake rates with Wilson intervals (``rates.png``);
    distributions of the new follower's deceleration, the executed peak acceleration and the
    plan time (``distributions.png``)."""
    plt = _plt()
    folder = Path(folder)
    planners = list(dict.fromkeys(c["planner"] for c in cells))
    missions = list(dict.fromkeys(c["mission"] for c in cells)) or ["merge"]
    written = []
    keys = (("success", "success"), ("contact", "contact"), ("hard_brake", "new follower brakes > 4.5 m/s²"))
    fig, axes = plt.subplots(len(missions), 3, figsize=(15, 3.2 * len(missions)), constrained_layout=True,
                             squeeze=False)
    width = 0.8 / max(len(planners), 1)
    for r, m in enumerate(missions):
        traffics = list(dict.fromkeys(c["traffic"] for c in cells if c["mission"] == m))
        for ax, (key, label) in zip(axes[r], keys):
            for j, p in enumerate(planners):
                xs, ys, lo, hi = [], [], [], []
                for i, tr in enumerate(traffics):
                    c = next((c for c in cells if c["mission"] == m and c["planner"] == p and c["traffic"] == tr), None)
                    if c is None:
                        continue
                    xs.append(i + (j - (len(planners) - 1) / 2) * width)
                    ys.append(100 * c[f"{key}_rate"])
                    lo.append(max(0.0, 100 * (c[f"{key}_rate"] - c[f"{key}_ci"][0])))  # Wilson ends round past 0 and 1
                    hi.append(max(0.0, 100 * (c[f"{key}_ci"][1] - c[f"{key}_rate"])))
                ax.bar(xs, ys, width, yerr=[lo, hi], capsize=2, label=p)
            ax.set_xticks(range(len(traffics)), traffics)
            ax.set_ylim(0, 105)  # a 100 % bar's interval cap stays visible
            ax.set_ylabel("episodes [%]")
            ax.set_title(f"{m}: {label} (Wilson 95 %)", fontsize=9)
    axes[0][0].legend(fontsize=7)
    written.append(_save(plt, fig, folder / "rates.png"))
    fig, axes = plt.subplots(len(missions), 3, figsize=(15, 3.2 * len(missions)), constrained_layout=True,
                             squeeze=False)
    for r, m in enumerate(missions):
        for ax, (col, label, scale) in zip(axes[r], (("follower_max_decel", "new follower's max decel. [m/s²]", 1),
                                                     ("ego_peak_accel", "executed peak |a| [m/s²]", 1),
                                                     ("plan_time_p50_s", "plan time p50 per episode [ms]", 1e3))):
            data = []
            for p in planners:
                vals = [scale * float(x[col]) for x in rows if x.get("mission") == m and x["planner"] == p
                        and x.get(col, "") not in ("", "None")]
                data.append(vals if vals else [np.nan])
            ax.boxplot(data, tick_labels=planners)
            if col == "plan_time_p50_s":
                ax.set_yscale("log")
            ax.set_title(f"{m}: {label}", fontsize=9)
            ax.tick_params(axis="x", labelsize=7)
    written.append(_save(plt, fig, folder / "distributions.png"))
    return written


def _save(plt: Any, fig: Any, path: Path) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return path
