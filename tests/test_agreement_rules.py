"""The verdict rules of `iamp compare`, each number recomputed independently from the runs.

These tests pin the arithmetic of every rule (scales, brackets, bounds), so that a verdict
cannot silently change meaning: each reported check value is recomputed here from the runs'
own results and the exact references.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from iamp.comparison.agreement.judge import QPConfig, compare_pmp_qp, compare_problem
from iamp.comparison.agreement.references import grid_cost_table
from iamp.core.tolerances import tol
from iamp.planners.examples import paper_problem

N = 12


@pytest.fixture(scope="module")
def comp():
    problem = paper_problem(1)
    configs = [QPConfig(s, h, N) for h in ("foh", "zoh") for s in ("clarabel", "osqp")]
    return compare_problem(problem, configs, repeats=1, warmup=0, pmp_repeats=1)


def test_pmp_own_checks_are_scaled_residuals(comp):
    pmp = comp.run("pmp").result
    scale = max(1.0, abs(pmp.cost), float(np.max(np.abs(pmp.problem.ego.final))))
    pair = comp.pair("pmp", f"qp-clarabel-foh-{N}")
    seen = 0
    for name, value in pmp.residuals.items():
        key = f"pmp_{name}_residual"
        if key in pair["checks"]:
            assert pair["checks"][key]["value"] == pytest.approx(value / scale, rel=1e-12, abs=1e-300)
            seen += 1
    assert seen >= 3


def test_bracket_bound_is_the_best_grid_node_around_t_star(comp):
    """Rule 6: the bracket is {floor(t*/h), ceil(t*/h)}, its cost the exact FOH sweep cost there."""
    problem = comp.problem
    pmp = comp.run("pmp").result
    h = problem.tf / N
    t_star = float(pmp.contact_times[0])
    cands, J = grid_cost_table(problem, N, "foh")
    lookup = {int(c[0]): float(j) for c, j in zip(cands, J, strict=True)}
    expect = min(lookup[int(np.floor(t_star / h))], lookup[int(np.ceil(t_star / h))])
    pair = comp.pair("pmp", f"qp-clarabel-foh-{N}")
    assert pair["continuous"]["bracket_cost"] == pytest.approx(expect, rel=1e-12)
    lo, hi = int(np.floor(t_star / h)), int(np.ceil(t_star / h))
    assert sorted(map(tuple, pair["continuous"]["bracket_nodes"])) == sorted({(lo,), (hi,)})
    qp = comp.run(f"qp-clarabel-foh-{N}").result
    assert pair["checks"]["bracket_upper_bound_rel"]["value"] == pytest.approx((qp.cost - expect) / expect, abs=1e-12)


def test_a_worse_grid_candidate_fails_the_search_rules(comp):
    """A QP run that reports a non-optimal node (the cost is right for that node) disagrees."""
    problem = comp.problem
    label = f"qp-clarabel-foh-{N}"
    run = comp.run(label)
    planner = run.config.planner()
    cands, J = grid_cost_table(problem, N, "foh")
    worst = int(cands[int(np.argmax(J))][0])
    bad = planner.plan_at_nodes(problem, [worst]) if hasattr(planner, "plan_at_nodes") else None
    if bad is None:
        pytest.skip("planner has no plan_at_nodes")
    fake = replace(run, result=bad)
    pair = compare_pmp_qp(problem, comp.run("pmp"), fake)
    assert pair["verdict"] == "disagree"
    assert not pair["checks"]["search_grid_optimum_rel"]["ok"]
    assert not pair["checks"]["bracket_upper_bound_rel"]["ok"]


def test_zoh_bracket_is_leading_term_over_one_minus_rho(comp):
    pair = comp.pair("pmp", f"qp-clarabel-zoh-{N}")
    z = pair["zoh_gap"]
    assert 0 < z["rho"] < 1
    assert z["upper_bound"] == pytest.approx(z["leading_h2_term"] / (1 - z["rho"]), rel=1e-12)
    assert z["leading_h2_term"] <= z["gap"] <= z["upper_bound"] * (1 + 1e-9)


def test_qp_pair_gaps_are_run_against_run(comp):
    """OSQP vs Clarabel on the same grid: same node, gaps recomputed from both trajectories."""
    a, b = comp.run(f"qp-clarabel-foh-{N}").result, comp.run(f"qp-osqp-foh-{N}").result
    pair = comp.pair(f"qp-clarabel-foh-{N}", f"qp-osqp-foh-{N}")
    assert pair["contact_time_gap"] == pytest.approx(float(np.max(np.abs(a.contact_times - b.contact_times))), abs=0)
    assert pair["contact_time_gap"] == 0.0
    tn = np.asarray(a.trajectory.t_nodes)
    Ua, Ub = a.trajectory.inputs(tn), b.trajectory.inputs(tn)
    du = float(np.max(np.abs(Ua - Ub)))
    assert pair["input_sup_gap"] == pytest.approx(du, rel=1e-12, abs=1e-300)
    assert pair["checks"]["input_rel"]["value"] == pytest.approx(du / max(1.0, float(np.max(np.abs(Ua)))),
                                                                 rel=1e-12, abs=1e-300)
    assert pair["cost_rel_gap"] == pytest.approx((b.cost - a.cost) / abs(a.cost), rel=1e-12, abs=1e-300)
    assert pair["verdict"] == "agree"
    assert pair["checks"]["cost_rel"]["limit"] == tol("cmp_cost_rel_osqp")


def test_compare_problem_default_repeats_time_every_run():
    problem = paper_problem(1)
    out = compare_problem(problem, [QPConfig("clarabel", "foh", 6)], warmup=0)
    qp = out.run("qp-clarabel-foh-6")
    assert qp.time is not None and qp.time.n >= 1
    assert out.run("pmp").time.n >= 20  # the PMP gets max(20, 10 * repeats)


def test_every_reference_check_value_is_recomputed(comp):
    """Rule 2 and 4 check values, recomputed from the QP's trajectory and the PMP at t_Q."""
    from iamp.planners.pmp.planner import solve_fixed_times

    problem = comp.problem
    pair = comp.pair("pmp", f"qp-clarabel-foh-{N}")
    qp = comp.run(f"qp-clarabel-foh-{N}").result
    pmp = comp.run("pmp").result
    tn = np.asarray(qp.trajectory.t_nodes)
    ref = solve_fixed_times(problem, qp.contact_times)
    X, U = qp.trajectory.states(tn), qp.trajectory.inputs(tn)
    Xr, Ur = ref.states(tn), ref.inputs(tn)
    c = pair["checks"]
    assert c["cost_vs_reference_rel"]["value"] == pytest.approx(abs(qp.cost - ref.cost()) / abs(ref.cost()),
                                                                rel=1e-9, abs=1e-15)
    assert c["state_vs_reference_rel"]["value"] == pytest.approx(
        np.max(np.abs(X - Xr)) / max(1.0, np.max(np.abs(Xr))), rel=1e-9, abs=1e-15)
    assert c["input_vs_reference_rel"]["value"] == pytest.approx(
        np.max(np.abs(U - Ur)) / max(1.0, np.max(np.abs(Ur))), rel=1e-9, abs=1e-15)
    assert c["jump_vs_reference_rel"]["value"] == pytest.approx(
        np.max(np.abs(qp.jumps - ref.jumps)) / max(1.0, np.max(np.abs(ref.jumps))), rel=1e-9, abs=1e-15)
    bscale = max(1.0, float(np.max(np.abs(np.r_[problem.ego.initial, problem.ego.final]))))
    assert c["boundary_residual_rel"]["value"] == pytest.approx(qp.boundary_residual() / bscale, rel=1e-12, abs=0)
    assert c["collision_residual_rel"]["value"] == pytest.approx(qp.corner_residual() / bscale, rel=1e-12, abs=0)
    hj = pmp.residuals["hamiltonian_jump"] / max(1.0, pmp.cost)
    assert c["pmp_hamiltonian_jump_at_t*"]["value"] == pytest.approx(hj, rel=1e-12, abs=1e-300)
    same = pair["at_same_contact_times"]
    assert same["input_sup_gap"] == pytest.approx(float(np.max(np.abs(U - Ur))), rel=1e-9, abs=1e-15)
    assert [s["phi_x"] for s in pair["signs"]] == [float(j[0]) for j in qp.jumps]


def test_qp_pair_state_check_is_scaled(comp):
    a, b = comp.run(f"qp-clarabel-zoh-{N}").result, comp.run(f"qp-osqp-zoh-{N}").result
    pair = comp.pair(f"qp-clarabel-zoh-{N}", f"qp-osqp-zoh-{N}")
    tn = np.asarray(a.trajectory.t_nodes)
    Xa, Xb = a.trajectory.states(tn), b.trajectory.states(tn)
    assert pair["checks"]["state_rel"]["value"] == pytest.approx(
        np.max(np.abs(Xa - Xb)) / max(1.0, np.max(np.abs(Xa))), rel=1e-12, abs=1e-300)


def test_refine_cost_check_is_relative_to_the_continuous_optimum():
    problem = paper_problem(1)
    comp = compare_problem(problem, [QPConfig("clarabel", "foh", 10, contact="refine")], repeats=1, warmup=0,
                           pmp_repeats=1)
    pair = comp.agreement[0]
    qp, pmp = comp.runs[1].result, comp.run("pmp").result
    assert pair["checks"]["refine_cost_vs_continuous_rel"]["value"] == pytest.approx(
        abs(qp.cost - pmp.cost) / pmp.cost, rel=1e-9, abs=1e-15)


def test_progress_counts_every_run_once():
    calls = []
    compare_problem(paper_problem(1), [QPConfig("clarabel", "foh", 6), QPConfig("osqp", "foh", 6)], repeats=1,
                    warmup=0, pmp_repeats=1, progress=lambda d, n: calls.append((d, n)))
    assert calls == [(1, 3), (2, 3), (3, 3)]
