r"""``report.tex``, the reproduction report's document: it ``\input``\ s the tables
(:mod:`iamp.comparison.report.tables`) and ``\includegraphics``\ es the figures, with the text
that reads them: what the co-state jumps mean, the safety over the whole horizon, the
qualitative comparison of the scenarios.

:func:`build_report_tex` is a pure function of the numbers
:func:`iamp.comparison.report.reproduce` computed (it compiles with ``pdflatex`` and the
packages of ``texlive-latex-recommended``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, cast

from iamp.comparison.metrics import ManoeuvreMetrics, QualitativeEntry

from .paper import PAPER_FIG, PAPER_TABLE_I, SCENARIOS
from .records import ResultsJSON, ScenarioEntry
from .tables import agreement_notes
from .tex import intervals_tex, tex_escape, tex_sci

if TYPE_CHECKING:  # pragma: no cover
    from iamp.core.problem import Problem, SurroundingVehicle


__all__ = ["build_report_tex"]



def vehicle1_words(name: str, problem: Problem) -> str:
    """What vehicle 1 does, in a caption: the paper's history (before ``t = 0``) and the
    prediction the plan used over ``[0, t_f]`` (issue 22 item 14: the prediction of scenarios 2
    and 3 is nearly constant speed, so "vehicle 1 decelerates" misdescribes the figure).

    The prediction's speed change is ``x_s'(t_f) - x_s'(0)`` and its mean acceleration that over
    ``t_f``, from the cubic ``x_s(t) = Σ c_k t^k``.
    """
    info = PAPER_TABLE_I[name]
    c = [float(x) for x in problem.vehicles[0].x_poly] + [0.0] * 4
    tf = float(problem.ego.tf)
    v0 = c[1]
    vf = c[1] + 2 * c[2] * tf + 3 * c[3] * tf**2
    mean_a = (vf - v0) / tf
    motion = ("at nearly constant speed" if abs(mean_a) < 0.1
              else "decelerating" if mean_a < 0 else "accelerating")
    before = "at constant speed" if info["before"] == "constant speed" else info["before"]
    return (f"Vehicle 1 was {before} before $t=0$ (scenario {info['scenario']}, its history); the cubic "
            f"predicted from that history keeps it {motion} over $[0, {tf:g}]$\\,s "
            f"({v0:.1f} to {vf:.1f}\\,m/s, mean acceleration {mean_a:+.2f}\\,m/s$^2$), in the adjacent lane.")

def _figure(path: str, caption: str, label: str, width: str = "\\linewidth") -> str:
    return ("\\begin{figure}[H]\n\\centering\n"
            f"\\includegraphics[width={width}]{{{path}}}\n\\caption{{{caption}}}\n\\label{{{label}}}\n"
            "\\end{figure}\n")


def _qualitative_tex(qual: Mapping[str, QualitativeEntry],
                     metrics: Mapping[str, ManoeuvreMetrics] | None = None) -> str:
    if not qual:
        return "The qualitative comparison needs scenarios 1--3.\n"
    out = ["The paper reports that the ego plans a \\emph{more aggressive} manoeuvre in scenario~2 and a "
           "\\emph{more conservative} one in scenario~3 than in scenario~1, without defining the terms. We measure "
           "aggressiveness by seven quantities of the PMP plan (Table~\\ref{tab:metrics}): an earlier contact time "
           "$t^*_1$, an earlier crossing of the lane divider, a larger peak lateral acceleration, a larger peak "
           "lateral jerk, a larger peak longitudinal acceleration, a higher cost $J$ and a smaller final clearance "
           "ahead of vehicle 1's safety region each count as more aggressive. (The paper chose $s_{xf}$ per "
           "scenario \\emph{to ensure a safety distance at the final time}, so the last measure is set largely by "
           "Table~I itself.)\n\\begin{itemize}"]
    for other, q in qual.items():
        k = PAPER_TABLE_I[other]["scenario"]
        detail = "; ".join(f"{r['label']}: {r['other_is']} ({r['scenario_1']:.3g} vs {r['other']:.3g})"
                           for r in q["measures"])
        verdict = ("consistent with the paper" if q["consistent_with_paper"] else
                   "\\textbf{not} what the paper reports")
        out.append(f"\\item Scenario {k} vs scenario 1 (paper: {q['paper_claim']}): more aggressive on "
                   f"{q['n_more_aggressive']} and more conservative on {q['n_more_conservative']} of "
                   f"{q['n_measures']} measures, so by majority \\emph{{{q['observed_majority']}}} --- {verdict}. "
                   f"Details (scenario 1 vs {k}): {detail}."
                   + (_speeds_tex(metrics, other, k) if metrics else ""))
    out.append("\\end{itemize}\n")
    return "\n".join(out)


def _speeds_tex(metrics: Mapping[str, ManoeuvreMetrics], other: str, k: int) -> str:
    a, b = metrics.get("paper-1"), metrics.get(other)
    if not a or not b:
        return ""
    return (f" Speeds: vehicle 1 is predicted from {b['vehicle_speed_0'][0]:.1f} to "
            f"{b['vehicle_speed_tf'][0]:.1f}\\,m/s "
            f"(scenario 1: {a['vehicle_speed_0'][0]:.1f} to {a['vehicle_speed_tf'][0]:.1f}\\,m/s) and the ego's "
            f"$v_x$ spans {b['min_vx']:.1f}--{b['max_vx']:.1f}\\,m/s (scenario 1: {a['min_vx']:.1f}--{a['max_vx']:.1f}"
            "\\,m/s).")


def _safety_tex(metrics: Mapping[str, ManoeuvreMetrics]) -> str:
    """One paragraph: does the single-instant equality keep the ego out of the box?"""
    items = []
    for name in SCENARIOS:
        m = metrics.get(name)
        if m is None:
            continue
        for i, (box, depth, body) in enumerate(zip(m["inside_safety_box"], m["max_depth_inside_safety_box"],
                                                  m["body_overlap"])):
            if box or body:
                items.append(f"\\item {tex_escape(name)}, vehicle {i + 1}: the ego's point is inside the safety box "
                             f"during {intervals_tex(box)}\\,s (up to {depth:.2g}\\,m deep)"
                             + (f", and the bodies overlap during {intervals_tex(body)}\\,s --- a collision"
                                if body else "") + ".")
    head = ("\\paragraph{Safety over the whole horizon.} The paper's constraint is an equality at one free instant "
            "$t_i$: the ego touches the corner of the safety region then, and nothing is required before or after. ")
    if not items:
        return head + "In this run the ego stays outside every safety box over the whole horizon.\n"
    return (head + "In this run it does not keep the ego out of the safety region everywhere:\n\\begin{itemize}\n"
            + "\n".join(items) + "\n\\end{itemize}\n")


def _meaning_tex(vehicle: SurroundingVehicle, phi_x: float, i: int) -> str:
    from iamp.comparison.agreement.signs import constraint_role

    if phi_x == 0:
        return f"$\\Phi_{{{i},x}}=0$: the corner lies on the unconstrained path."
    side = "ahead of" if phi_x > 0 else "behind"
    role = constraint_role(vehicle, phi_x)
    return (f"$\\Phi_{{{i},x}}={phi_x:.4g}{'>' if phi_x > 0 else '<'}0$: without the equality the ego would be "
            f"{side} the {vehicle.corner.split('-')[0]} corner of vehicle {i}; the equality is {role}.")


def build_report_tex(res: ResultsJSON, out: Path, figs: Mapping[str, str], tables: Mapping[str, str],
                     entries: Mapping[str, ScenarioEntry], extra: str = "") -> str:
    """``report.tex``: the sections in order, ``extra`` (whole sections) before the conclusions."""
    cfg = res["config"]
    metrics_by_name = {s["name"]: m for s in res["scenarios"] if (m := s["metrics"])}
    L = ["% generated by iamp.comparison.report.reproduce -- do not edit",
         "\\documentclass[10pt,a4paper]{article}",
         "\\ifdefined\\pdftrailerid\\pdftrailerid{}\\fi  % no random file ID: the same PDF from the same input",
         "\\usepackage[margin=2cm]{geometry}",
         "\\usepackage{lmodern}",
         "\\usepackage[T1]{fontenc}",
         "\\usepackage{textcomp}",
         "\\usepackage{amsmath}",
         "\\usepackage{booktabs}",
         "\\usepackage{graphicx}",
         "\\usepackage{float}",
         "\\usepackage{caption}",
         "\\captionsetup{font=small}",
         "% tables written by other modules may ask for [t]; keep them where they are input",
         "\\makeatletter",
         "\\newcommand{\\inputhere}[1]{\\begingroup\\renewenvironment{table}[1][]"
         "{\\@float{table}[H]}{\\end@float}\\input{#1}\\endgroup}",
         "\\makeatother",
         "\\title{Interaction-aware lane-change planning: reproduction report}",
         f"\\author{{generated by \\texttt{{iamp reproduce}}{' (quick mode)' if cfg['quick'] else ''}}}",
         "\\date{}",
         "\\begin{document}",
         "\\maketitle",
         "This report reproduces the simulations of \\emph{Interaction-Aware Vehicle Motion Planning with "
         "Collision Avoidance Constraints in Highway Traffic} (Kim, Kim and Han): the PMP planner with "
         "interior-point collision constraints at free contact times, fed by the MTD Markov-chain predictor, on "
         "the paper's three scenarios (Table~I, Figs.~4--9), and goes beyond them: a two-vehicle scenario, the "
         "discretised QP (the MPC baseline) on Clarabel and OSQP, the cost as a function of the contact time, "
         "co-state jumps against QP multipliers, the ZOH discretisation error and solve times. All numbers are "
         "in \\texttt{results.json}.",
         ""]
    if res["notes"]:
        L.append("\\paragraph{Notes on this run.}")
        L.append("\\begin{itemize}\\raggedright\\sloppy")
        L += [f"\\item {tex_escape(n)}" for n in res["notes"]]
        L.append("\\end{itemize}")
    L += ["\\section{Scenarios}", f"\\input{{{tables['scenarios']}}}"]
    if "predictions" in figs:
        L.append(_figure(figs["predictions"], "Vehicle 1 in the paper's scenarios: observed 3\\,s history, the "
                         "predictor's expected trajectory and the least-squares cubic handed to both planners.",
                         "fig:predictions", "0.75\\linewidth"))
    L += ["\\section{Results}", f"\\input{{{tables['results']}}}", "\\paragraph{What the jumps mean.}",
          "\\begin{itemize}"]
    for s in res["scenarios"]:
        pmp = next((r for r in s["runs"] if r["label"] == "pmp"), None)
        if pmp is None or pmp["status"] != "optimal":
            continue
        prob = entries[s["name"]].problem
        for i, (v, j) in enumerate(zip(prob.vehicles, pmp["jumps"])):
            L.append(f"\\item {tex_escape(s['name'])}: {_meaning_tex(v, j[0], i + 1)}")
    L.append("\\end{itemize}")
    L += [f"\\input{{{tables['metrics']}}}", _safety_tex(metrics_by_name),
          "\\subsection{Scenario 2 more aggressive, scenario 3 more conservative?}",
          _qualitative_tex(res["qualitative"], metrics_by_name)]
    L.append("\\section{The paper's figures}")
    for name in SCENARIOS[:3]:
        if f"xy-{name}" not in figs:
            continue
        k = PAPER_TABLE_I[name]["scenario"]
        f4, _ = PAPER_FIG[name]
        L.append(_figure(figs[f"xy-{name}"], f"(Paper Fig.~{f4}.) Ego (green, its body turned along its "
                         f"heading) and vehicle 1 (grey) every 0.5\\,s in the $(x,y)$ plane, to scale (equal aspect). "
                         f"{vehicle1_words(name, entries[name].problem)} "
                         "Thin red boxes: the safety regions $x_{s,1}(t)\\pm(L/2+S_x)$ by $y_{s,1}\\pm(W/2+S_y)$; "
                         "dashed: the safety region and body at $t^*_1$; star: the contact corner. Lane lines "
                         "half-way between the lane centres $s_{y0}$ and $y_{s,1}$.", f"fig:xy-{name}"))
    for name in SCENARIOS[:3]:
        if f"pos-{name}" not in figs:
            continue
        k = PAPER_TABLE_I[name]["scenario"]
        _, f7 = PAPER_FIG[name]
        L.append(_figure(figs[f"pos-{name}"], f"(Paper Fig.~{f7}.) Optimal longitudinal and lateral position "
                         f"(scenario {k}); the safety-critical lines at $t^*_1$ are dashed in red (vertical at "
                         "$t^*_1$, horizontal at the corner coordinate).", f"fig:pos-{name}", "0.7\\linewidth"))
    if "xy-two-vehicle" in figs:
        L.append("\\section{Two vehicles}")
        L.append(_figure(figs["xy-two-vehicle"], "Two-vehicle scenario: ego, vehicle 1 (behind, target lane) and "
                         "vehicle 2 (ahead, current lane) every 0.5\\,s with their safety regions.",
                         "fig:xy-two-vehicle"))
        L.append(_figure(figs["pos-two-vehicle"], "Two-vehicle scenario: positions with the safety-critical lines "
                         "at both contact times.", "fig:pos-two-vehicle", "0.7\\linewidth"))
    L.append("\\section{PMP against the discretised QP}")
    L.append(f"\\input{{{tables['agreement']}}}")
    an = agreement_notes(res["scenarios"])
    if an:
        L.append("\\paragraph{Reasons and notes of the agreement checks.}")
        L.append("\\begin{itemize}\\raggedright")
        for name, pair, kind, text in an[:40]:
            L.append(f"\\item {tex_escape(name)}, {tex_escape(pair)} ({kind}): {tex_escape(text)}")
        if len(an) > 40:
            L.append(f"\\item \\dots\\ and {len(an) - 40} more in \\texttt{{results.json}}.")
        L.append("\\end{itemize}")
    for name in SCENARIOS[:3]:
        if f"J-{name}" in figs:
            L.append(_figure(figs[f"J-{name}"], f"{tex_escape(name)}: the fixed-contact-time optimal cost $J(t)$ "
                             "(closed form of the PMP conditions), the PMP's global $t^*$ and the QP's FOH sweep "
                             f"points ($N={cfg['steps_one']}$; Clarabel and OSQP). Every FOH sweep point lies on "
                             "$J(t)$; the sweep's best is the best grid node, within $h/2$ of $t^*$.",
                             f"fig:J-{name}"))
    for name in SCENARIOS:
        if f"costates-{name}" in figs:
            # the grey curve Phi(t) is drawn for one vehicle only (plot_costates)
            grey = (" The grey curve is $\\Phi(t)$ of the PMP solved at a fixed contact time $t$: the QP's $\\nu$ "
                    "lies on it." if name in entries and entries[name].problem.m == 1 else "")
            L.append(_figure(figs[f"costates-{name}"], f"{tex_escape(name)}: co-states $p_1..p_4$ of the PMP "
                             "with their jumps at $t_i$ (red), and the jumps $\\Phi_i$ against the QP multipliers "
                             "$\\nu_i$ of the collision constraint, each at its planner's own contact time "
                             "($\\nu_x$ vs the $p_1$ jump, $\\nu_y$ vs the $p_3$ jump)." + grey,
                             f"fig:costates-{name}", "0.85\\linewidth"))
    L += ["\\subsection{ZOH discretisation error}", f"\\input{{{tables['convergence']}}}"]
    if "zoh" in figs:
        L.append(_figure(figs["zoh"], "ZOH gap $J_\\mathrm{ZOH}-J_\\mathrm{PMP}$ at the same contact node against "
                         "$h$; dashed: slope 2.", "fig:zoh", "0.6\\linewidth"))
    L += ["\\subsection{Solve times}",
          "The wall times below are the report's only machine-dependent numbers: they are written to "
          "\\texttt{timing/} beside the other files (with \\texttt{timing/timing.json}), and every other table, "
          "figure and \\texttt{results.json} is the same on every run of the same code.",
          f"\\input{{{tables['timing']}}}"]
    if "timing" in figs:
        L.append(_figure(figs["timing"], "Wall times, log scale, the numbers of Table~\\ref{tab:timing}. Top: "
                         "whole plans (median, bar from $q_1$ to $q_3$). Bottom: one QP solve at a changed candidate "
                         "node (box: quartiles, whiskers: 5--95\\,\\%, dots: every sample). Colours: PMP green, "
                         "Clarabel blue, OSQP orange, as in every figure.",
                         "fig:timing"))
    L.append("\\section{The predictor}")
    if tables.get("predictor_rmse"):
        L += ["The predictor's own evaluation (\\texttt{predictor\\_eval.json}), written by "
              "\\texttt{iamp.prediction.evaluate}:", "",  # restructure: keep (the report's text)
              f"\\inputhere{{{tables['predictor_rmse']}}}"]
        predictor = res.get("predictor")
        if tables.get("predictor_selection") and predictor is not None and predictor.get("selection_run"):
            L += [f"\\inputhere{{{tables['predictor_selection']}}}"]
        else:  # its table would only say so (issue 29 item 17: an empty table)
            L += ["", "The model-selection grid was not run for this report (\\texttt{iamp evaluate-predictor "
                  "-{}-out DIR} runs it; it takes many minutes): the shipped configuration was evaluated as it is."]
            if tables.get("predictor_selection"):
                L.append(f"% {tables['predictor_selection']} is not input: it says only that the selection was not run")
    else:
        L.append("The predictor evaluation was not available for this run (see the notes above).")
    L += [extra, conclusions_tex(res),
          "\\section{Reproducibility}",
          "\\input{timing/environment.tex}",
          "One-vehicle QP sweeps on $N=" + str(cfg["steps_one"]) + "$, two-vehicle on $N=" + str(cfg["steps_two"])
          + "$; ZOH study on $N\\in\\{" + ", ".join(map(str, cfg["zoh_steps"])) + "\\}$. "
          "The run time, the versions above and the solve times are machine-dependent (\\texttt{timing/}, with "
          "\\texttt{report.pdf} and the small campaign's \\texttt{episodes.csv}); every other file is the same, "
          "byte for byte, on every run of the same code on the same machine.",
          "\\end{document}", ""]
    return "\n".join(L)


def conclusions_tex(res: ResultsJSON) -> str:
    """The report's last section: what the numbers above say, each from ``results.json``."""
    items: list[str] = []
    pairs = [(s["name"], a) for s in res["scenarios"] for a in s["agreement"] if a["a"] == "pmp"]
    foh = [(n, a) for n, a in pairs if "-foh-" in a["b"] and "refine" not in a["b"]]
    if foh:
        agree = sum(a.get("verdict") == "agree" for _, a in foh)
        gaps = [abs(float(g)) for _, a in foh if (same := a.get("at_same_contact_times"))
                and (g := same.get("cost_rel_gap")) is not None]
        worst = f"; the largest relative cost gap at the same contact times is {tex_sci(max(gaps), floor=1e-11)}" \
            if gaps else ""
        items.append(f"\\item \\textbf{{PMP and the first-order-hold QP agree}} in {agree} of {len(foh)} "
                     f"comparisons (Table~\\ref{{tab:agreement}}){worst}: at equal contact times the QP is the PMP's "
                     "problem, and its multipliers are the co-state jumps.")
    slopes = {n: c.get("loglog_slope") for n, c in (res.get("zoh_convergence") or {}).items()}
    if slopes:
        text = ", ".join(f"{tex_escape(n)} {v:.2f}" for n, v in slopes.items() if v is not None)
        items.append(f"\\item \\textbf{{Zero-order hold converges as $O(h^2)$}} to the PMP's cost (fitted log--log "
                     f"slopes {text}; Table~\\ref{{tab:convergence}}).")
    qual = res.get("qualitative") or {}
    if qual:
        parts = [f"scenario {PAPER_TABLE_I[n]['scenario']} is {q['observed_majority']} than scenario 1 "
                 f"(the paper: {q['paper_claim']}; "
                 + ("consistent" if q["consistent_with_paper"] else "\\textbf{not} consistent") + ")"
                 for n, q in qual.items()]
        items.append("\\item \\textbf{The paper's qualitative claims}, by the majority of seven measures: "
                     + "; ".join(parts) + ".")
    unsafe = []
    for s in res["scenarios"]:
        m = s.get("metrics")
        if m and (any(m["inside_safety_box"]) or any(m["body_overlap"])):
            unsafe.append(tex_escape(s["name"]) + (" (the bodies overlap)" if any(m["body_overlap"]) else ""))
    if unsafe:
        items.append("\\item \\textbf{The single-instant equality does not keep the ego out of the safety region} "
                     "over the whole horizon in " + ", ".join(unsafe) + "; the avoidance QP and the active-set PMP "
                     "impose it at every instant.")
    bounded = res.get("bounded") or []
    if bounded:
        by: dict[str, list[str]] = {}
        for r in bounded:
            pair = f"{tex_escape(r['scenario'])}/\\texttt{{{tex_escape(r['planner'])}}}"
            by.setdefault(str(r["status"]), []).append(pair)
        ok = by.get("optimal", [])
        inf = by.get("infeasible", [])
        items.append(f"\\item \\textbf{{Under a passenger car's limits}} (Table~\\ref{{tab:bounded}}) "
                     f"{len(ok)} of {len(bounded)} scenario--planner pairs find an optimal plan"
                     + (f" ({', '.join(ok)})" if ok else "")
                     + (f"; {len(inf)} {'is' if len(inf) == 1 else 'are'} certified infeasible" if inf else "")
                     + ".")
    camp = res.get("campaign")
    summary = cast("list[dict[str, object]]", camp.get("summary") or []) if camp else []
    if camp and camp.get("available") and summary:
        cells = ", ".join(f"{tex_escape(str(c['planner']))} {c['success_episodes']}/{c['episodes']}"
                          for c in summary)
        items.append(f"\\item \\textbf{{In closed loop}} (Table~\\ref{{tab:campaign-small}}; too few seeds to rank "
                     f"planners), successful merges: {cells}.")
    if not items:
        return ""
    return "\\section{Conclusions}\n\\begin{itemize}\n" + "\n".join(items) + "\n\\end{itemize}\n"
