"""The human-readable report of ``iamp bench`` (:func:`format_bench`; the numbers come from
:func:`iamp.comparison.bench.run.run_bench`)."""

from __future__ import annotations

from iamp.comparison.durations import format_seconds

from .run import BenchJSON


def _fmt_s(x: float | None) -> str:
    return format_seconds(x, digits=3, width=8, missing="       n/a")


def _fmt_target(x: float) -> str:
    return f"{x * 1e6:g} µs" if x < 1e-3 else f"{x * 1e3:g} ms" if x < 1 else f"{x:g} s"


def format_bench(out: BenchJSON) -> str:
    """The human-readable report of :func:`~iamp.comparison.bench.run.run_bench`'s result."""
    lines = [f"iamp bench — medians, {out['problem']}, FOH, N = {out['steps']}" + (" (quick)" if out["quick"] else ""),
             ""]
    lines.append(f"  {'PMP plan, one vehicle (global t*)':44s} {_fmt_s(out['pmp_plan_s']['one_vehicle'])}")
    plan_s = out["pmp_plan_s"]
    two = "compiled search" if plan_s.get("two_vehicles_compiled") else "pure numpy"
    lines.append(f"  {'PMP plan, two vehicles (' + two + ')':44s} {_fmt_s(plan_s['two_vehicles'])}")
    if plan_s.get("two_vehicles_compiled"):
        lines.append(f"  {'PMP plan, two vehicles (pure numpy)':44s} {_fmt_s(plan_s['two_vehicles_pure'])}")
    if plan_s.get("one_vehicle_bounded") is not None:
        how = "compiled axis" if plan_s.get("one_vehicle_bounded_compiled") else "pure"
        lines.append(f"  {'PMP plan, one vehicle, input box (local t*, ' + how + ')':44s} "
                     f"{_fmt_s(plan_s['one_vehicle_bounded'])}")
    if plan_s.get("one_vehicle_bounded_certified") is not None:
        lines.append(f"  {'  the same, certified global (default)':44s} "
                     f"{_fmt_s(plan_s['one_vehicle_bounded_certified'])}")
    if plan_s.get("one_vehicle_bounded_compiled") and plan_s.get("one_vehicle_bounded_pure"):
        lines.append(f"  {'  the same two, pure Python axis solve':44s} {_fmt_s(plan_s['one_vehicle_bounded_pure'])}"
                     + (f"   {_fmt_s(plan_s['one_vehicle_bounded_certified_pure']).strip()}"
                        if plan_s.get("one_vehicle_bounded_certified_pure") else ""))
    lines.append(f"  {'PMP batch, one vehicle':44s} {out['pmp_batch_plans_per_s']:8.0f} /s")
    lines += ["", "  QP per candidate (update + solve; whole candidate incl. verification):"]
    for s, c in out["qp_candidate"].items():
        lines.append(f"    {s:10s} {_fmt_s(c['backend_s']['median'])}   {_fmt_s(c['wall_s']['median'])}"
                     + (f"   ({c['failed']} unverified)" if c["failed"] else ""))
    lines += ["", "  QP grid sweep (whole plan, build included):"]
    for k, v in out["qp_grid_sweep_s"].items():
        label = k.replace("native_", "native ") if k.startswith("native_") else f"cvxpy {k}"
        lines.append(f"    {label:18s} {_fmt_s(v)}")
    if out["avoid_grid_sweep_s"]:
        for k, av in out["avoid_grid_sweep_s"].items():
            lines.append(f"    {'avoid ' + k:18s} {_fmt_s(av)}")
    ab = out.get("avoid_bounded")
    if ab and "backends" in ab and ab["backends"]:
        lines += ["", f"  Bounded avoidance, {ab['problem']}, FOH, N = {ab['steps']}, safety {ab['safety']}:",
                  f"    {'backend':10s} {'whole plan':>10s}  {'QPs':>5s}  {'one QP':>10s}  status"]
        for k, r in ab["backends"].items():
            if r.get("plan_s") is None:
                lines.append(f"    {k:10s} {r.get('error', 'n/a')}")
                continue
            lines.append(f"    {k:10s} {_fmt_s(r['plan_s'])}  {r.get('n_solves', 0):5d}  {_fmt_s(r.get('qp_s'))}  "
                         f"{r['status']} (J = {r['cost']:.9g})" if r.get("cost") is not None else
                         f"    {k:10s} {_fmt_s(r['plan_s'])}  {r['status']}")
        c = ab.get("casadi_ipopt")
        if c and "solve_s" in c:
            lines.append(f"    CasADi + IPOPT, the same QP at the crossing time: solve {_fmt_s(c['solve_s'])} "
                         f"({c['iterations']} it, J = {c['cost']:.9g}), build {_fmt_s(c['build_s']).strip()}")
    cas = out.get("casadi_ipopt")
    if cas:
        pmp_t = out["pmp_plan_s"]["one_vehicle"]
        lines += ["", f"  CasADi Opti + IPOPT, free contact time, ZOH N = {cas['steps']} "
                  f"({cas['variables']} variables):",
                  f"    build {_fmt_s(cas['build_s'])}   cold solve {_fmt_s(cas['cold_s'])} "
                  f"({cas['iterations_cold']} it)   warm solve {_fmt_s(cas['warm_s'])} ({cas['iterations_warm']} it)",
                  f"    t1 = {cas['contact_time']:.6f} s, J = {cas['cost']:.6f} (discretised; PMP plan "
                  f"{_fmt_s(pmp_t).strip()})"]
    casb = out.get("casadi_ipopt_bounded")
    if casb:
        lines += ["  the same with the input box ax [-6, 3], ay [-2, 2] on every u_k:",
                  f"    build {_fmt_s(casb['build_s'])}   cold solve {_fmt_s(casb['cold_s'])} "
                  f"({casb['iterations_cold']} it)   warm solve {_fmt_s(casb['warm_s'])} "
                  f"({casb['iterations_warm']} it)",
                  f"    t1 = {casb['contact_time']:.6f} s, J = {casb['cost']:.6f} (discretised; bounded PMP plan "
                  f"{_fmt_s(out['pmp_plan_s'].get('one_vehicle_bounded')).strip()})"]
    wl = out.get("planning_with_limits")
    if wl:
        lines += ["", "  Planning with the limits imposed (issue 32; medians, CPU and wall):",
                  f"    {'case':42s} {'CPU':>10s} {'wall':>10s}  {'target':>8s}  status"]
        for k, case in wl["rows"].items():
            tg = wl["targets"][k]
            verdict = "met" if tg["met_cpu"] else "MISSED"
            lines.append(f"    {k:42s} {_fmt_s(case['cpu_s'])} {_fmt_s(case['wall_s'])}  "
                         f"{_fmt_target(tg['target_s']):>8s}  {case['status'] or case.get('error', 'n/a')} "
                         f"({verdict} on CPU)")
    loop = out.get("loop")
    if loop:
        ep = loop["case"]
        lines += ["", f"  Closed loop, whole {ep['duration_s']:g} s {ep['mission']} episodes ({ep['traffic']}, "
                  f"seed {ep['seed']}, with the car's limits):"]
        for k, row in loop["planners"].items():
            cpu = (row.get("cpu") or {}).get("median")
            lines.append(f"    {k:18s} {_fmt_s(row['episode']['median'])} ({_fmt_s(cpu).strip()} CPU)   planning "
                         f"{_fmt_s(row['wall_s'].get('planning')).strip()}, {row['planner_calls']} planner calls, "
                         f"{'success' if row['success'] else 'no success'}, {row['contacts']} contacts")
    lines += ["", "targets:"]
    for k, t in out["targets"].items():
        val = f"{t['value']:8.0f} /s" if k.endswith("per_s") and t["value"] is not None else _fmt_s(t["value"])
        tgt = f"{t['target']:.0f} /s" if k.endswith("per_s") else _fmt_target(t["target"])
        lines.append(f"  {k:38s} {val}   {t['op']} {tgt:8s} {'met' if t['met'] else 'MISSED'}")
    lines += ["", "ratios (same run):"]
    for k, ratio in out["ratios"].items():
        lines.append(f"  {k:42s} " + ("n/a" if ratio is None else f"{ratio:10.3g}"))
    if out["osqp_tuning"]:
        lines += ["", "OSQP settings on the equality QP (one sweep each; KKT recomputed):"]
        for r in out["osqp_tuning"]:
            s = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in r["settings"].items())
            s = s or "iamp's equality-QP default"
            lines.append(f"  {s:36s} verified {r['verified']:3d}/{r['candidates']}  polished {r['polished']:3d}  "
                         f"iter {r['iterations_median']:5.0f} (max {r['iterations_max']})  "
                         f"KKT max {r['kkt_rel_max']:.1e}  {_fmt_s(r['backend_s_median']).strip()}/candidate")
    m, ver = out["machine"], out["versions"]
    lines += ["", f"machine: {m['cpu_count']} CPU(s), {m['platform']}; load {m['load_average_1min_before']} -> "
              f"{m['load_average_1min_after']}",
              "versions: " + ", ".join(f"{k} {ver.get(k)}" for k in ("python", "numpy", "scipy", "cvxpy", "osqp",
                                                                  "clarabel", "piqp"))]
    lines += [f"warning: {w}" for w in out["warnings"]]
    lines += [f"note: {n}" for n in out["notes"]]
    return "\n".join(lines)
