"""Markdown tables of ``evaluate-predictor``'s results with the ``interaction`` section (README, reports)."""

from __future__ import annotations

from .records import UserEvaluation

__all__ = ["interaction_markdown"]

_SUBSETS = (("all", "all windows"), ("free", "free flow"), ("congested", "congested"),
            ("leader_known", "leader known"), ("leader_unknown", "no leader known"))


def _ci(c: list[float], fmt: str = "{:.2f}") -> str:
    return f"[{fmt.format(c[0])}, {fmt.format(c[1])}]"


def interaction_markdown(res: UserEvaluation, title: str) -> str:
    """The §13 table (RMSE per horizon, ADE/FDE with CIs) and the per-subset RMSE at 5 s against CV."""
    tabs = res["interaction"]["tables"]
    allm = tabs["all"]["methods"]
    lines = [f"**{title}** — {res['tracks']} tracks, {res['windows']} windows (3 s history, 5 s future); "
             f"model: {res['model']}; leader model: {res['interaction']['leader_model']['note']}.", "",
             "| method | RMSE 1 s | 2 s | 3 s | 4 s | 5 s [95 % CI] | ADE [CI] | FDE [CI] | 5 s vs CV [CI] |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for name, r in allm.items():
        d = r.get("diff_to_cv")
        rel = f"{100 * d['rmse_5s_rel']:+.1f} % {_ci([100 * x for x in d['rmse_5s_rel_ci95']], '{:+.1f}')}" if d \
            else "—"
        rm = r["rmse_m"]
        lines.append(f"| {name} | {rm[0]:.2f} | {rm[1]:.2f} | {rm[2]:.2f} | {rm[3]:.2f} | {rm[4]:.2f} "
                     f"{_ci(r['rmse_ci95'][-1])} | {r['ade_m']:.2f} {_ci(r['ade_ci95'])} | "
                     f"{r['fde_m']:.2f} {_ci(r['fde_ci95'])} | {rel} |")
    names = list(allm)
    lines += ["", "RMSE at 5 s [m] and change against CV, per subset:", "",
              "| subset | windows | " + " | ".join(names) + " |",
              "| --- | ---: | " + " | ".join("---:" for _ in names) + " |"]
    for key, label in _SUBSETS:
        tb = tabs.get(key, {})
        if "methods" not in tb:
            lines.append(f"| {label} | 0 | " + " | ".join("—" for _ in names) + " |")
            continue
        cells = []
        for n in names:
            r = tb["methods"][n]
            d = r.get("diff_to_cv")
            cells.append(f"{r['rmse_m'][-1]:.2f}" + (f" ({100 * d['rmse_5s_rel']:+.0f} %)" if d else ""))
        lines.append(f"| {label} | {tb['windows']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
