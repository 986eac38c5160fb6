"""The bench table of issue 32 (planning with the car's limits; the 60 s closed-loop episode), written
from ``iamp bench --json``'s output; nothing in it is typed by hand.

Usage::

    iamp bench --json > reports/bench.json          # the measurement (minutes; needs iamp[sim] for the loop)
    python scripts/bench_table.py                    # write docs/bench.md and README.md's bench block
    python scripts/bench_table.py --check            # exit 1 if either differs from what the JSON says

Inputs: ``reports/bench.json`` (the run: ``planning_with_limits``, ``loop``, ``machine``,
``versions``) and, if present, ``reports/bench-before.json`` (the same keys measured on the code
before issue 32, with its ``commit`` and ``commands``): the *before* columns.  The README's block
between ``<!-- bench:begin -->`` and ``<!-- bench:end -->`` holds the targets table;
``docs/bench.md`` holds every table.  ``tests/test_bench_table.py`` fails when they and the JSON
disagree, and checks that every number of the tables is one of the JSON's.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"
AFTER, BEFORE = Path("reports/bench.json"), Path("reports/bench-before.json")
DOC = Path("docs/bench.md")
#: The case families in the order of the table, with a reader's name.
FAMILIES = {
    "bounded_pmp_one_vehicle_certified": "bounded PMP, one vehicle, certified global",
    "bounded_pmp_three_vehicles": "bounded PMP, three vehicles, a box no plan keeps (certified `infeasible`)",
    "bounded_pmp_three_vehicles_feasible": "bounded PMP, three vehicles, box at 85 % of the peaks (`local` allowed)",
    "avoid_limits_one_vehicle": "avoidance with limits, N = 50, one vehicle, certified",
    "avoid_limits_three_vehicles": "avoidance with limits, N = 50, three vehicles",
}


def fmt_s(x: float | None) -> str:
    """A time [s] with three significant digits and a unit (``n/a`` for ``None``)."""
    if x is None:
        return "n/a"
    for scale, unit in ((1.0, "s"), (1e-3, "ms"), (1e-6, "µs")):
        if abs(x) >= scale or unit == "µs":
            return f"{x / scale:.3g} {unit}"
    raise AssertionError("unreachable")  # pragma: no cover


def fmt_ratio(x: float | None) -> str:
    """A ratio with three significant digits (``n/a`` for ``None``)."""
    return "n/a" if x is None else f"{x:.3g}"


def _yes(ok: bool) -> str:
    return "**met**" if ok else "missed"


def targets_table(after: Mapping[str, Any], before: Mapping[str, Any] | None) -> list[str]:
    """Issue 32's targets: one row per case of ``planning_with_limits``."""
    wl = after["planning_with_limits"]
    prior = (before or {}).get("planning_with_limits") or {}
    lines = ["| case | backend | status | CPU | wall | target | met (CPU) | met (wall) | CPU / PMP plan | "
             "CPU / KKT solve | before: CPU (status) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, row in wl["rows"].items():
        tg = wl["targets"][key]
        ratio = wl["ratios"][key]
        old = (prior.get("rows") or {}).get(key)
        was = f"{fmt_s(old['cpu_s'])} ({old['status']})" if old and old.get("status") else "n/a"
        status = row["status"] or row.get("error", "n/a")
        lines.append(f"| {FAMILIES[row['family']]} | {row['solver'] or '—'} | {status}"
                     f" | {fmt_s(row['cpu_s'])} | {fmt_s(row['wall_s'])} | {fmt_s(tg['target_s'])} | "
                     f"{_yes(tg['met_cpu'])} | {_yes(tg['met_wall'])} | {fmt_ratio(ratio['cpu_to_pmp_plan'])} | "
                     f"{fmt_ratio(ratio['cpu_to_kkt_solve'])} | {was} |")
    return lines


def same_optimum_line(after: Mapping[str, Any]) -> str:
    """Whether OSQP, Clarabel and PIQP reach the same certified optimum, per vehicle count."""
    same = after["planning_with_limits"]["same_optimum"]
    parts = [f"{k.replace('avoid_limits_', '').replace('_', ' ')}: {'yes' if v else 'no'}" for k, v in same.items()]
    return "OSQP, Clarabel and PIQP at the same certified optimum (all `optimal`, costs within 1e-6): " + \
        "; ".join(parts) + "."


def references_table(after: Mapping[str, Any]) -> list[str]:
    """The two references of the ratios, measured in the same run."""
    refs = after["planning_with_limits"]["references"]
    return ["| reference (same run) | CPU | wall |", "|---|---|---|",
            f"| unbounded PMP plan, `paper-1` | {fmt_s(refs['pmp_plan']['cpu_s'])} | "
            f"{fmt_s(refs['pmp_plan']['wall_s'])} |",
            f"| one KKT solve, equality QP, `paper-1`, FOH, N = 100 | {fmt_s(refs['kkt_solve']['cpu_s'])} | "
            f"{fmt_s(refs['kkt_solve']['wall_s'])} |"]


def loop_table(after: Mapping[str, Any], before: Mapping[str, Any] | None) -> list[str]:
    """The 60 s closed-loop episode per iamp planner (wall and CPU time)."""
    loop = after.get("loop")
    if not loop:
        return ["The closed-loop episodes were not measured in this run (`--quick` or no SUMO)."]
    prior = ((before or {}).get("loop") or {}).get("planners") or {}
    warmup = int(loop.get("warmup", 0))
    lines = []
    if warmup:
        lines += [f"Each planner's episodes are timed after {warmup} untimed warm-up episode(s) of the same planner "
                  "in the same process (a campaign's workers run many episodes each); the warm-up's own wall time "
                  "is the column *first episode*: it also loads libsumo, the predictor's model and the planner's "
                  "modules.", ""]
    repeats = int(loop.get("repeats", 1))
    if repeats > 1:
        lines += [f"Each episode figure is the median of {repeats} timed episodes of this run (wall clock, and the "
                  "process's CPU time); *of which planning* is the median run's own.", ""]
    lines += ["| planner | episode (wall) | episode (CPU) | of which planning | first episode (wall) | planner calls | "
              "success | contacts | target | met | before: episode (planning) |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    target = loop["target_episode_s"]
    for name, row in loop["planners"].items():
        old = prior.get(name)
        was = f"{fmt_s(old['episode']['median'])} ({fmt_s(old['wall_s'].get('planning'))})" if old else "n/a"
        med = row["episode"]["median"]
        cpu = (row.get("cpu") or {}).get("median")
        lines.append(f"| {name} | {fmt_s(med)} | {fmt_s(cpu)} | {fmt_s(row['wall_s'].get('planning'))} | "
                     f"{fmt_s(row.get('first_episode_s'))} | {row['planner_calls']} | "
                     f"{'yes' if row['success'] else 'no'} | {row['contacts']} | {fmt_s(target)} | "
                     f"{_yes(med <= target)} | {was} |")
    return lines


def _machine(after: Mapping[str, Any]) -> str:
    m = after["machine"]
    cpu = f" ({m['cpu_model']})" if m.get("cpu_model") else ""
    return (f"Machine: {m['cpu_count']} CPUs{cpu}, {m['platform']}, Python {m['python']}; load average (1 min) "
            f"{m['load_average_1min_before']:.2f} before the run, {m['load_average_1min_after']:.2f} after.")


def speed_table(after: Mapping[str, Any]) -> list[str]:
    """The unbounded paths against issue 14's targets: the PMP plans, ``plan_batch``, one equality-QP
    candidate per backend, the FOH grid sweeps, the avoidance sweep and CasADi/IPOPT (paper-1, FOH,
    ``N = 100``); every figure a median of repeats in this one run."""
    tg, r = after["targets"], after["ratios"]
    pmp, solve = after["pmp_plan_s"], after["qp_native_solve_s"]
    sweep, avoid, cas = after["qp_grid_sweep_s"], after["avoid_grid_sweep_s"], after.get("casadi_ipopt") or {}

    def met(key: str) -> str:
        t = tg.get(key)
        if t is None:
            return ""
        bound = fmt_s(t["target"]) if t["op"] == "<=" else f"{t['target']:,.0f} / s"
        return f"{'≤' if t['op'] == '<=' else '≥'} {bound}, {_yes(t['met'])}"

    us = 1e6
    lines = ["| measure | median | target (issue 14) | ratio to the limit / peer |", "|---|---|---|---|",
             f"| PMP plan, one vehicle, global `t*` | {us * pmp['one_vehicle']:.1f} µs | "
             f"{met('pmp_plan_one_vehicle_s')} | {fmt_ratio(r['pmp_to_compiled_limit'])}× the numba-compiled kernel |",
             f"| PMP plan, two vehicles, certified global (one source, run as Python) | "
             f"{1e3 * pmp['two_vehicles']:.2f} ms | {met('pmp_plan_two_vehicles_s')} | |",
             f"| `plan_batch`, one-vehicle plans | {after['pmp_batch_plans_per_s']:,.0f} / s | "
             f"{met('pmp_batch_plans_per_s')} | the one kernel per problem, equal to `PMPPlanner.plan` bit for bit |",
             f"| equality QP, one candidate: `kkt` (direct banded KKT solve) | {us * solve['kkt']:.0f} µs | "
             f"{met('qp_native_solve_kkt_s')} | the limit |",
             f"| … best iterative, PIQP | {us * solve['piqp']:.0f} µs | {met('qp_native_solve_best_iterative_s')} | "
             f"{fmt_ratio(r['qp_piqp_to_kkt'])}× kkt |",
             f"| … Clarabel | {us * solve['clarabel']:.0f} µs | | {fmt_ratio(r['qp_clarabel_to_kkt'])}× kkt |",
             f"| … OSQP (polished to the exact solution) | {us * solve['osqp']:.0f} µs | "
             f"{met('qp_native_solve_osqp_s')} | {fmt_ratio(r['qp_osqp_to_kkt'])}× kkt |",
             f"| FOH grid sweep, one vehicle, native `kkt` | {fmt_s(sweep['native_kkt'])} | "
             f"{met('qp_grid_sweep_native_best_s')} | |",
             f"| … native PIQP / Clarabel / OSQP | {fmt_s(sweep['native_piqp'])} / {fmt_s(sweep['native_clarabel'])} / "
             f"{fmt_s(sweep['native_osqp'])} | | |",
             f"| … through cvxpy, Clarabel / OSQP (the cross-check) | {fmt_s(sweep['clarabel'])} / "
             f"{fmt_s(sweep['osqp'])} | | {fmt_ratio(r['cvxpy_clarabel_sweep_to_native'])}× / "
             f"{fmt_ratio(r['cvxpy_osqp_sweep_to_native'])}× native |",
             f"| avoidance QP sweep (SPEC §10), Clarabel / OSQP | {fmt_s(avoid['clarabel'])} / {fmt_s(avoid['osqp'])} "
             "| | |"]
    if cas:
        lines.append(f"| CasADi `Opti` + IPOPT, free contact time, ZOH N = 100 ({cas['variables']} variables) | "
                     f"build {fmt_s(cas['build_s'])}, cold solve {fmt_s(cas['cold_s'])}, warm re-solve "
                     f"{fmt_s(cas['warm_s'])} | | warm re-solve {fmt_ratio(r['casadi_ipopt_warm_to_pmp_plan'])}× the "
                     "PMP plan |")
    return lines


def readme_block(after: Mapping[str, Any], before: Mapping[str, Any] | None) -> str:
    """The README's block: the targets table and where the rest is."""
    out = ["<!-- generated by `python scripts/bench_table.py` from reports/bench.json: do not edit by hand -->", "",
           "Planning with the car's limits (`iamp bench --json > reports/bench.json`, issue 32; medians of "
           "repeats in one run, CPU and wall time; every table in [docs/bench.md](docs/bench.md))"
           + _compiled_note(after) + ":", ""]
    out += targets_table(after, before)
    return "\n".join(out)


def _compiled_note(after: Mapping[str, Any]) -> str:
    """Which path the planners ran: their numba-compiled kernels (as the closed loop runs them), and the
    one-vehicle certified bounded plan in plain Python where the JSON has it."""
    pure = (after.get("pmp_plan_s") or {}).get("one_vehicle_bounded_certified_pure")
    text = ". The planners run their numba-compiled kernels, as the closed loop does (`[sim]`, `[fast]`)"
    if isinstance(pure, (int, float)):
        text += f"; the certified one-vehicle bounded plan takes {fmt_s(float(pure))} in plain Python"
    text += (". Each avoidance plan starts with the half-planes' rows of earlier plans forgotten (the vehicles move "
             "between a loop's plans), the grid's factorisation kept")
    return text


def document(after: Mapping[str, Any], before: Mapping[str, Any] | None) -> str:
    """``docs/bench.md``: every table, the machine and the commands."""
    case = (after.get("loop") or {}).get("case")
    out = ["# Bench: planning with the car's limits", "",
           "<!-- generated by `python scripts/bench_table.py` from reports/bench.json: do not edit by hand -->", "",
           "Measured by `iamp bench --json > reports/bench.json` and written here by "
           "`python scripts/bench_table.py` (the README's bench block too). Every case is planned by the "
           "registry's planner as `iamp plan` does, several times in one process; the table gives the "
           "medians of the process's CPU time and of the wall time (the machines here are shared, so the "
           "wall time depends on their load), the status the planner returned, the target of issue 32 "
           "(met only with an allowed status: `optimal` where the case says certified) and the ratios to "
           "the unbounded one-vehicle PMP plan and to one KKT solve measured in the same run. The problems: "
           "`paper-1` and `random_problem(0, m=3)` with the passenger car's input box (bounded PMP), the "
           "overtake of `iamp.planners.examples.overtake_problem` and its three-vehicle version "
           "`overtake_three_problem` under the passenger car's limits (avoidance, FOH, "
           "`--safety continuous`).", ""]
    out += targets_table(after, before) + ["", same_optimum_line(after), ""] + references_table(after)
    out += ["", "## The closed loop", ""]
    if case:
        out += [f"One whole {case['duration_s']:g} s `{case['mission']}` episode in `{case['traffic']}` traffic, "
                f"seed {case['seed']}, per iamp planner, every planner with the car's limits imposed (the same as "
                f"`iamp simulate --mission {case['mission']} --traffic {case['traffic']} --seed {case['seed']} "
                f"--planner P --duration {case['duration_s']:g} --json`):", ""]
    out += loop_table(after, before)
    if all(k in after for k in ("targets", "ratios", "pmp_plan_s", "qp_native_solve_s", "qp_grid_sweep_s")):
        out += ["", "## The unbounded paths", "", "The paths without limits against the targets of issue 14 "
                "(paper-1, FOH, N = 100), from the same run:", ""] + speed_table(after)
    if before:
        out += ["", "## Before", "",
                f"The *before* columns: {before.get('description', 'the code before issue 32')} "
                f"(`reports/bench-before.json`)."]
        out += [f"- `{c}`" for c in before.get("commands", [])]
    out += ["", _machine(after)]
    return "\n".join(out) + "\n"


def render_readme(readme: str, after: Mapping[str, Any], before: Mapping[str, Any] | None) -> str:
    """``readme`` with its bench block replaced by :func:`readme_block`."""
    head, sep, rest = readme.partition(BEGIN)
    if not sep or END not in rest:
        raise SystemExit(f"README.md has no {BEGIN} ... {END} block")
    _, _, tail = rest.partition(END)
    return f"{head}{BEGIN}\n{readme_block(after, before)}\n{END}{tail}"


def load(root: Path = ROOT) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """The run and, if present, the *before* run."""
    after = json.loads((root / AFTER).read_text(encoding="utf-8"))
    if not after.get("planning_with_limits"):
        raise SystemExit(f"{AFTER}: no planning_with_limits (made by an iamp bench before issue 32?)")
    before_path = root / BEFORE
    before = json.loads(before_path.read_text(encoding="utf-8")) if before_path.is_file() else None
    return after, before


def main(argv: list[str] | None = None, root: Path = ROOT) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if docs/bench.md or README.md is stale")
    args = parser.parse_args(argv)
    after, before = load(root)
    readme = root / "README.md"
    old_readme = readme.read_text(encoding="utf-8")
    new_readme = render_readme(old_readme, after, before)
    doc = root / DOC
    old_doc = doc.read_text(encoding="utf-8") if doc.is_file() else ""
    new_doc = document(after, before)
    if args.check:
        if new_readme != old_readme or new_doc != old_doc:
            print("docs/bench.md or README.md's bench block differs from reports/bench.json: "
                  "run python scripts/bench_table.py", file=sys.stderr)
            return 1
        return 0
    from iamp.core.atomic import write_text

    write_text(doc, new_doc)
    write_text(readme, new_readme)
    return 0


if __name__ == "__main__":
    sys.exit(main())
