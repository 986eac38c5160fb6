r"""Figures of the report's studies beyond the paper: the ZOH discretisation error, the solve
times and the predictions.

* :func:`plot_zoh_convergence` — ``J_ZOH − J_PMP`` against ``h`` on log–log axes with a
  slope-2 guide (``O(h²)``).
* :func:`plot_timing` — whole-plan medians and single-solve distributions per planner
  configuration.
* :func:`plot_predictions` — observed history, predicted samples and the fitted cubic.

Palette, conventions and the atomic writing: :mod:`iamp.comparison.figures.style`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TypedDict

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from iamp.comparison.timing import StatsJSON

from .style import PathLike, planner_style, save_figure, scenario_color

#: Fewest samples whose quartiles a timing figure draws (fewer: the samples' range instead).
MIN_QUARTILE_SAMPLES = 5

__all__ = ["PredictionCurves", "plot_predictions", "plot_timing", "plot_zoh_convergence"]


class PredictionCurves(TypedDict):
    """What :func:`plot_predictions` draws of one scenario (``None``: not available)."""

    history_t: NDArray[np.float64] | None
    history_x: NDArray[np.float64] | None
    pred_t: NDArray[np.float64] | None
    pred_x: NDArray[np.float64] | None
    x_poly: Sequence[float]


def plot_zoh_convergence(series: Mapping[str, tuple[Sequence[float], Sequence[float]]], stem: PathLike, *,
                         title: str | None = None) -> list[Path]:
    """``J_ZOH − J_PMP`` (same contact node) against ``h`` on log–log axes.

    Parameters
    ----------
    series : dict
        ``{label: (h_values, gaps)}``; a slope-2 guide is drawn through the first series.
    """
    fig = Figure(figsize=(6.0, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    first = None
    for k, (label, (h_values, gaps)) in enumerate(series.items()):
        h = np.asarray(h_values, dtype=float)
        gap = np.asarray(gaps, dtype=float)
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


def plot_timing(samples: Mapping[str, Sequence[float]], stem: PathLike, *,
                whole_plans: Mapping[str, StatsJSON] | None = None,
                title: str | None = None) -> list[Path]:
    """Wall times, log scale, coloured by planner (:func:`planner_style`).

    Top (if ``whole_plans``): whole plans, contact-time search included — the median with
    its quartiles as a bar, one row per run, from the statistics of the planning step (the
    same numbers as the timing table). Bottom: single QP solves at a changed candidate node —
    box (quartiles, whiskers 5–95 %) with every sample jittered over it.  6 in wide, so
    that at the report's text width its labels print at about their size.

    Parameters
    ----------
    samples : dict
        ``{label: sequence of seconds}``; empty sequences are skipped.
    whole_plans : dict, optional
        ``{label: {"median", "q1", "q3", "n"}}``.
    """
    items = [(k, np.asarray(v, dtype=float)) for k, v in samples.items() if len(v)]
    plans = [(k, st) for k, st in (whole_plans or {}).items() if st and st.get("median")]
    # one panel above the other, 6 in wide: printed at the text width, the labels keep their size
    heights = [max(1.2, 0.26 * len(plans) + 0.6)] if plans else []
    heights.append(max(1.2, 0.26 * max(len(items), 1) + 0.6))
    fig = Figure(figsize=(6.0, sum(heights) + 1.2 * len(heights)), layout="constrained")
    grid = fig.add_gridspec(len(heights), 1, height_ratios=heights)
    axes = [fig.add_subplot(grid[r, 0]) for r in range(len(heights))]
    if plans:
        ax = axes[0]
        pos = np.arange(len(plans), 0, -1)
        for y, (label, st) in zip(pos, plans):
            sty = planner_style(label)
            if int(st.get("n", 0)) >= MIN_QUARTILE_SAMPLES:
                ax.errorbar([st["median"]], [y], xerr=[[st["median"] - st["q1"]], [st["q3"] - st["median"]]],
                            fmt=sty["marker"], ms=7, mfc=sty["mfc"], color=sty["color"], capsize=3)
                continue
            # quartiles of 1-4 samples say nothing: the median and the extreme samples instead
            # (for n <= 3 these are the samples themselves)
            ax.plot([st["median"]], [y], sty["marker"], ms=7, mfc=sty["mfc"], color=sty["color"])
            ends = [st[k] for k in ("min", "max") if st.get(k) is not None]
            ax.plot(ends, [y] * len(ends), "|", ms=9, mew=1.5, color=sty["color"])
        ax.set_yticks(pos)
        ax.set_yticklabels([f"{k} (n={st['n']})" for k, st in plans], fontsize=8)
        ax.set_xscale("log")
        ax.set_xlabel(f"wall time of a whole plan [s]: median; bar: quartiles (n >= {MIN_QUARTILE_SAMPLES}), "
                      "else ticks: fastest, slowest", fontsize=8)
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
    ax.set_xlabel("wall time of one QP solve [s]", fontsize=8)
    ax.grid(True, axis="x", which="both", lw=0.3, alpha=0.5)
    ax.set_title("one QP solve at a changed candidate node (box: quartiles, whiskers: 5-95 %)", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, stem)


def plot_predictions(entries: Mapping[str, PredictionCurves], stem: PathLike, *, tf: float,
                     title: str | None = None) -> list[Path]:
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
        ht, hx, pt, px = e["history_t"], e["history_x"], e["pred_t"], e["pred_x"]
        if ht is not None and hx is not None:
            ax.plot(ht, hx, ".", ms=3, color=col, label=f"{label}: observed history")
        if pt is not None and px is not None:
            ax.plot(pt, px, "o", ms=3, mfc="none", color=col, alpha=0.6,
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
