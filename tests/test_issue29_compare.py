"""Issue 29 items 1, 9, 10 and 16 (part): the comparison of bounded problems, the refusal of a
backend that cannot impose ``[limits]``, fast certified infeasibility of the bounded QP, and
the ``plan`` help and text output."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import iamp
from iamp.core.physical import PhysicalLimits
from iamp.core.problem import Problem
from iamp.planners.examples import random_problem
from iamp.planners.pmp import PMPPlanner
from iamp.prediction.resolve import load_problem

#: The template's [limits] (iamp template): a passenger car without the jerk bound.
TEMPLATE_LIMITS = PhysicalLimits(ax=(-6.0, 3.0), ay=(-2.0, 2.0), a_total=8.0, vx=(0.0, 40.0))


def _template(tmp_path: Path, cli) -> Path:  # type: ignore[no-untyped-def]
    r = cli("template")
    assert r.returncode == 0, r.stderr
    path = tmp_path / "t.toml"
    path.write_text(r.stdout)
    return path


# --- item 9: a backend that cannot take inequalities is refused, not a numerical error ----------


def test_cli_refuses_kkt_with_limits_naming_the_backends(tmp_path: Path, cli) -> None:  # type: ignore[no-untyped-def]
    t = _template(tmp_path, cli)
    for extra in ((), ("--constraint", "active"), ("--json",)):
        r = cli("plan", t, "--planner", "qp", "--solver", "kkt", "--steps", "10", *extra)
        assert r.returncode == 2, (extra, r.stdout, r.stderr)
        assert r.stdout == ""
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in r.stderr
        assert "--solver" in lines[0] and "kkt" in lines[0]
        for ok in ("osqp", "clarabel", "piqp"):
            assert ok in lines[0]


def test_api_refuses_kkt_with_limits() -> None:
    _, p, _ = load_problem("paper-1-poly")
    bounded = p.with_limits(TEMPLATE_LIMITS)
    with pytest.raises(iamp.OptionError) as err:
        iamp.plan(bounded, "qp", solver="kkt", steps=10)
    assert err.value.field == "solver" and "clarabel" in str(err.value)
    from iamp.planners.qp import QPPlanner

    with pytest.raises(iamp.OptionError):  # the planner object itself refuses, before any solve
        QPPlanner(steps=10, solver="kkt").plan(bounded)
    assert iamp.plan(p, "qp", solver="kkt", steps=10).status == "optimal"  # without limits kkt is fine


# --- item 16 (part): help without issue numbers; the active set's text has its limits line ------


def test_plan_help_cites_no_issue(cli) -> None:  # type: ignore[no-untyped-def]
    r = cli("plan", "--help")
    assert r.returncode == 0
    assert "issue" not in r.stdout.lower()


def test_active_text_output_has_a_limits_line(cli) -> None:  # type: ignore[no-untyped-def]
    outs = {}
    for planner in ("pmp", "qp"):
        r = cli("plan", "paper-1-poly", "--planner", planner, "--constraint", "active", "--steps", "10")
        assert r.returncode == 0, r.stderr
        outs[planner] = r.stdout
        limits = [line for line in r.stdout.splitlines() if line.startswith("limits ")]
        assert len(limits) == 1 and "vx" in limits[0]
    plain = cli("plan", "paper-1-poly", "--steps", "10").stdout
    assert any(line.startswith("limits ") for line in plain.splitlines())


# --- item 1: every scenario `iamp template` writes compares; the bounded rules B0-B6 --------------

FAST = ("--steps", "20", "--repeats", "1", "--budget", "0.01", "--no-breakdown", "-q")


def test_template_compares(tmp_path: Path, cli) -> None:  # type: ignore[no-untyped-def]
    """`iamp template > t.toml && iamp compare t.toml` (and with --bounded, and beside a built-in)."""
    t = _template(tmp_path, cli)
    r = cli("compare", t, *FAST, "--json")
    assert r.returncode == 0, r.stderr
    sc = json.loads(r.stdout)["scenarios"][0]
    assert sc["limits"]["ax"] == [-6.0, 3.0]
    assert {run["status"] for run in sc["runs"]} == {"optimal"}
    pmp_pairs = [a for a in sc["agreement"] if a["a"] == "pmp"]
    assert len(pmp_pairs) == 4 and all(a["verdict"] == "agree" for a in sc["agreement"])
    for a in pmp_pairs:  # judged against the bounded PMP, not the paper's unbounded rules
        assert "rules B1-B6" in a["verdict_basis"] and a["checks"]["bounded_lower_bound_rel"]["ok"]
        assert a["checks"]["kkt_complementarity_rel"]["ok"]


def test_template_compares_bounded(tmp_path: Path, cli) -> None:  # type: ignore[no-untyped-def]
    t = _template(tmp_path, cli)
    r = cli("compare", t, "--bounded", *FAST)
    assert r.returncode == 0 and "internal error" not in r.stderr, r.stderr
    assert "bounded problem (my-scenario" in r.stdout and "limits ax" in r.stdout


def test_template_compares_beside_a_builtin(tmp_path: Path, cli) -> None:  # type: ignore[no-untyped-def]
    """The README's `iamp compare paper-1-poly my.toml` with a [limits] table."""
    t = _template(tmp_path, cli)
    r = cli("compare", "paper-1-poly", t, *FAST, "--json")
    assert r.returncode == 0, r.stderr
    both = json.loads(r.stdout)["scenarios"]
    assert "limits" not in both[0] and both[1]["limits"]["vx"] == [0.0, 40.0]


@pytest.mark.slow
def test_template_compares_with_the_default_options(tmp_path: Path, cli) -> None:  # type: ignore[no-untyped-def]
    t = _template(tmp_path, cli)
    for extra in ((), ("--bounded",)):
        r = cli("compare", t, "-q", *extra)
        assert r.returncode == 0, r.stderr
        assert "verdicts: 6 of 6 pairs agree" in r.stdout


def test_template_with_a_jerk_bound_skips_zoh(tmp_path: Path, cli) -> None:  # type: ignore[no-untyped-def]
    t = _template(tmp_path, cli)
    text = t.read_text()
    assert "# jerk = 5.0" in text
    t.write_text(text.replace("# jerk = 5.0", "jerk = 7.0"))
    r = cli("compare", t, *FAST, "--json")
    assert r.returncode == 0, r.stderr
    sc = json.loads(r.stdout)["scenarios"][0]
    assert [run["hold"] for run in sc["runs"][1:]] == ["foh", "foh"]
    assert len(sc["skipped"]) == 2 and all("jerk" in s for s in sc["skipped"])
    assert all(a["verdict"] == "agree" for a in sc["agreement"])
    r = cli("compare", t, *FAST, "--holds", "zoh")  # nothing left to compare: the refusal
    assert r.returncode == 2 and "limits.jerk" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def _compare(problem, steps: int = 20, holds=("foh", "zoh"), solvers=("osqp", "clarabel")):  # type: ignore[no-untyped-def]
    from iamp.comparison.agreement.judge import compare_problem, default_configs

    return compare_problem(problem, default_configs(steps=(steps,), solvers=solvers, holds=holds), repeats=1,
                           pmp_repeats=1, warmup=0, budget_s=0.0)


BUILTINS = ("paper-1", "paper-1-poly", "paper-2", "paper-2-poly", "paper-3", "paper-3-poly", "two-vehicle")


@pytest.mark.parametrize("name", BUILTINS)
def test_every_builtin_compares_under_the_template_limits(name: str) -> None:
    """The template's [limits] on every built-in: paper-1 is feasible (both verified), the others are
    certified infeasible by both the PMP and every QP — and both ways the pairs agree."""
    _, p, _ = load_problem(name)
    comp = _compare(p.with_limits(TEMPLATE_LIMITS), steps=10 if p.m > 1 else 20)
    statuses = {r.result.status for r in comp.runs}
    assert statuses == ({"optimal"} if name.startswith("paper-1") else {"infeasible"}), statuses
    assert comp.all_agree, [a["reasons"] for a in comp.agreement]
    assert comp.to_json()["limits"]["a_total"] == 8.0


def test_two_vehicles_with_an_active_box_agree() -> None:
    _, p, _ = load_problem("two-vehicle")
    comp = _compare(p.with_limits(PhysicalLimits(ax=(-30.0, 30.0), ay=(-6.0, 6.0))), steps=10)
    pmp = comp.run("pmp").result  # two vehicles: verified at its contact times, not certified global
    assert pmp.status == "local" and pmp.diagnostics.bounded["box_active"]  # type: ignore[attr-defined]
    assert comp.all_agree, [a["reasons"] for a in comp.agreement]
    assert all("rule B5 is not applied" in a["notes"][0] for a in comp.agreement if a["a"] == "pmp")
    zoh = [a for a in comp.agreement if a["b"].endswith("zoh-10") and a["a"] == "pmp"]
    assert zoh and all(a["checks"]["bounded_zoh_excess_rel"]["ok"] for a in zoh)  # rule B6's bracket applied
    assert all(0 <= a["bounded"]["excess"] <= a["bounded"]["zoh_upper_excess"] for a in zoh)  # type: ignore[typeddict-item]


def test_the_bounded_rules_can_fail() -> None:
    """A QP that did not impose the limits (what the cvxpy path did before) fails B0 and B4."""
    from iamp.comparison.agreement.bounded_pair import compare_bounded_pmp_qp
    from iamp.comparison.agreement.runs import QPConfig, run_pmp, run_qp

    _, p, _ = load_problem("paper-1-poly")
    bounded = p.with_limits(TEMPLATE_LIMITS)
    pmp = run_pmp(bounded, repeats=1, warmup=0)
    free = run_qp(p, QPConfig(solver="clarabel", hold="foh", steps=20), repeats=1, warmup=0)
    pair = compare_bounded_pmp_qp(bounded, pmp, free)
    assert pair["verdict"] == "disagree"
    assert any("different problem data" in r for r in pair["reasons"])  # the fingerprint holds the limits
    assert pair["checks"]["bounded_lower_bound_rel"]["ok"] is False  # J_QP < J_b(t_Q)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st.integers(0, 10**6), st.floats(0.6, 1.2))
def test_generated_bounded_problems_agree_when_both_verify(seed: int, scale: float) -> None:
    """Property: whenever the bounded PMP is certified optimal and a QP is optimal, the pair agrees;
    a QP plan never coexists with a PMP certificate of infeasibility."""
    problem = random_problem(seed)
    U = PMPPlanner().plan(problem).inputs(np.linspace(0.0, problem.tf, 2001))
    lim = PhysicalLimits(ax=(scale * min(-0.5, float(U[:, 0].min())), scale * max(0.5, float(U[:, 0].max()))),
                         ay=(scale * min(-0.5, float(U[:, 1].min())), scale * max(0.5, float(U[:, 1].max()))))
    comp = _compare(problem.with_limits(lim), steps=24, solvers=("clarabel",))
    pmp = comp.run("pmp").result
    for a in comp.agreement:
        qp = comp.run(a["b"]).result
        if pmp.status == "optimal" and qp.status == "optimal":
            assert a["verdict"] == "agree", a["reasons"]
        assert not (pmp.status == "infeasible" and qp.status == "optimal") or a["verdict"] == "disagree"


def _problem_229() -> Problem:
    """``random_problem(229)`` with limits at 0.609375 of its unbounded inputs, exactly as
    :func:`test_generated_bounded_problems_agree_when_both_verify` makes them."""
    problem = random_problem(229)
    U = PMPPlanner().plan(problem).inputs(np.linspace(0.0, problem.tf, 2001))
    s = 0.609375
    return problem.with_limits(PhysicalLimits(
        ax=(s * min(-0.5, float(U[:, 0].min())), s * max(0.5, float(U[:, 0].max()))),
        ay=(s * min(-0.5, float(U[:, 1].min())), s * max(0.5, float(U[:, 1].max())))))


def test_bounded_pmp_and_zoh_qp_agree_on_random_problem_229() -> None:
    """The ZOH counterexample to the former rule B6 (issue 32): ``random_problem(229)`` at
    0.609375 of its inputs, ZOH N = 24.  The excess over the bounded PMP at the QP's contact
    time is 1.2535 x the unbounded leading term (the former bracket [0.8, 1.25] failed:
    strict xfail until 2026-11-29); it lies in the derived bracket [0, D] of a plan of the QP
    built from the PMP's input (bounded_pair.zoh_upper_plan), with D / excess = 1.009 (1.019
    before the saturated averages were pinned in the correction)."""
    comp = _compare(_problem_229(), steps=24, solvers=("clarabel",), holds=("zoh",))
    assert [a["verdict"] for a in comp.agreement] == ["agree"], [a["reasons"] for a in comp.agreement]
    a = comp.agreement[0]
    b = a["bounded"]  # type: ignore[typeddict-item]
    assert 1.25 < b["ratio_to_leading"] < 1.26  # the former bracket's upper end is exceeded
    assert b["zoh_upper_reason"] is None and a["checks"]["bounded_zoh_excess_rel"]["ok"]
    assert 0 < b["excess"] <= b["zoh_upper_excess"] < 1.03 * b["excess"]  # 0 <= excess <= D, D/excess = 1.009


def test_bounded_pmp_and_foh_qp_agree_on_random_problem_229() -> None:
    """The counterexample the random property found (2026-11-28): ``random_problem(229)`` with
    limits at 0.609 of its inputs.  The bounded PMP was right (certified optimal; the FOH QP at
    its contact time converges to its cost from above as N grows); rule B6 measured the FOH
    excess against 0.25 of the ZOH leading term, which is not a bound: the excess at N = 24 is
    0.35 of it (seven switching times, slope jumps up to ~20 m/s³).  B6 then estimated it by
    2 x the switching kinks' leading term K_h (bounded_pair.foh_kink_term); since 2026-11-29 it
    is the derived bracket 0 <= excess <= D of a plan of the FOH QP built from the PMP's input
    (bounded_pair.upper_plan, D / excess = 1.014).  It failed before."""
    from iamp.comparison.agreement.bounded_pair import foh_kink_term, input_slope_energy
    from iamp.planners.qp.bounded import BoundedQP

    bounded = _problem_229()
    comp = _compare(bounded, steps=24, solvers=("clarabel",), holds=("foh",))
    best = comp.run("pmp").result
    assert [a["verdict"] for a in comp.agreement] == ["agree"], [a["reasons"] for a in comp.agreement]
    # (failed before: bounded_foh_excess_rel 0.00163 against 1e-9)
    b = comp.agreement[0]["bounded"]  # type: ignore[typeddict-item]
    assert b["foh_upper_reason"] is None and comp.agreement[0]["checks"]["bounded_foh_excess_rel"]["ok"]
    assert 0 < b["excess"] <= b["foh_upper_excess"] < 1.02 * b["excess"]
    problem = random_problem(229)
    assert best.status == "optimal" and best.diagnostics.certified_global
    t_star = float(best.contact_times[0])
    excess = []
    for N in (24, 96, 384):  # the FOH QP at t* (a grid through it): above J_b(t*), converging to it
        r = BoundedQP(bounded, N, "foh", "clarabel").solve_times([t_star])
        assert r.status == "optimal" and r.cost is not None
        excess.append(r.cost - float(best.cost))
    assert 0 <= excess[2] < 2e-4 < excess[1] < excess[0] / 20 and excess[0] > 0.1  # 0.52, 1.0e-2, 8.9e-5
    # the QP's own contact time at N = 24: the excess is far above 0.25 of the ZOH term, within K_h
    N = 24
    qp = BoundedQP(bounded, N, "foh", "clarabel")
    t_q = float(np.linspace(0.0, problem.tf, N + 1)[7])
    r = qp.solve_times([t_q])
    at = PMPPlanner().plan(bounded, contact_times=[t_q])
    assert r.cost is not None and at.cost is not None
    ex = r.cost - at.cost
    h = problem.tf / N
    assert ex > 0.25 * h * h / 24 * input_slope_energy(at)  # the old rule's bound is exceeded
    assert 0 < ex <= 2.0 * foh_kink_term(at, np.linspace(0.0, problem.tf, N + 1))  # the former rule's estimate


# --- item 10: certified infeasible before the sweep, counted in solves ---------------------------

TWO_TIGHT = PhysicalLimits(ax=(-6.0, 3.0), ay=(-2.0, 2.0), a_total=8.0, vx=(0.0, 40.0), jerk=5.0)


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_two_vehicles_with_tight_limits_are_infeasible_without_a_sweep(solver: str) -> None:
    from iamp.planners.qp import QPPlanner
    from iamp.planners.qp.bounded import PMP_CERTIFICATE_SOLVES

    _, p, _ = load_problem("two-vehicle")
    plan = QPPlanner(steps=100, solver=solver).plan(p.with_limits(TWO_TIGHT))
    d = plan.diagnostics
    assert plan.status == "infeasible" and plan.cost is None
    assert d.n_solves is not None and d.n_solves <= 1  # was 9702 QP solves (one per candidate)
    cert = d.candidates["certified_before_sweep"]  # type: ignore[index]
    assert cert["qp_solves"] == 1 and 0 < cert["pmp_boxes"] <= PMP_CERTIFICATE_SOLVES
    assert d.candidates["total"] == 99 * 98 and d.candidates["solved"] == 0  # type: ignore[index]
    assert "no choice of the 2 contact times" in (d.reason or "")


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**6), st.floats(0.3, 1.1), st.integers(1, 2))
def test_the_early_certificate_is_sound(seed: int, scale: float, m: int) -> None:
    """Whenever the pre-sweep certificate says infeasible, the full sweep finds no candidate."""
    from iamp.planners.qp.bounded import BoundedQP, infeasible_before_sweep
    from iamp.planners.qp.sweep import run_sweep

    problem = random_problem(seed, m=m)
    U = PMPPlanner().plan(problem).inputs(np.linspace(0.0, problem.tf, 2001))
    peak = np.abs(U).max(axis=0)
    bounded = problem.with_limits(PhysicalLimits(ax=(-scale * peak[0] - 0.1, scale * peak[0] + 0.1),
                                                 ay=(-scale * peak[1] - 0.1, scale * peak[1] + 0.1)))
    N = 12 if m == 1 else 8
    early = infeasible_before_sweep(bounded, N, "foh", "clarabel")
    if early is not None:
        sw = run_sweep(BoundedQP(bounded, N, "foh", "clarabel"))
        assert sw.best is None and all(r.status == "infeasible" for r in sw.results)


def test_a_vehicle_alone_out_of_reach_is_infeasible_in_few_solves() -> None:
    """Tight jerk: the box admits plans (the PMP's certificate does not apply), but the vehicle
    ahead alone cannot be cleared at any node: 2 (N - 1) solves instead of the joint sweep."""
    from iamp.planners.qp import QPPlanner

    _, p, _ = load_problem("two-vehicle")
    N = 50
    plan = QPPlanner(steps=N).plan(p.with_limits(PhysicalLimits(ax=(-30.0, 30.0), ay=(-6.0, 6.0), jerk=5.0)))
    d = plan.diagnostics
    assert plan.status == "infeasible"
    assert d.n_solves == 2 * (N - 1)  # was 383 solves of the joint sweep (after the box screen)
    assert "sv2 alone" in (d.reason or "") and f"{(N - 1) * (N - 2)} of {(N - 1) * (N - 2)}" in (d.reason or "")


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**6), st.floats(0.4, 1.2), st.sampled_from([None, 6.0, 30.0]))
def test_the_pruned_sweep_equals_the_full_sweep(seed: int, scale: float, jerk: float | None) -> None:
    """The screens (box, each vehicle alone) drop only certified-infeasible candidates: the plan
    is the full sweep's best."""
    from iamp.planners.qp import QPPlanner
    from iamp.planners.qp.bounded import BoundedQP
    from iamp.planners.qp.sweep import run_sweep

    problem = random_problem(seed, m=2)
    U = PMPPlanner().plan(problem).inputs(np.linspace(0.0, problem.tf, 2001))
    peak = np.abs(U).max(axis=0)
    bounded = problem.with_limits(PhysicalLimits(ax=(-scale * peak[0] - 0.1, scale * peak[0] + 0.1),
                                                 ay=(-scale * peak[1] - 0.1, scale * peak[1] + 0.1), jerk=jerk))
    N = 8
    plan = QPPlanner(steps=N).plan(bounded)
    full = run_sweep(BoundedQP(bounded, N, "foh", "clarabel"))
    if full.best is None:
        assert plan.status != "optimal"
    else:
        assert plan.status == "optimal" and plan.cost == pytest.approx(full.best.cost, rel=1e-9)
        assert np.allclose(plan.contact_times, full.best.contact_times)


def test_the_api_compares_a_bounded_problem() -> None:
    _, p, _ = load_problem("paper-1-poly")
    comp = iamp.compare(p.with_limits(TEMPLATE_LIMITS), steps=(20,), solvers=("clarabel",), holds=("foh", "zoh"),
                        repeats=1)
    assert comp.all_agree and not comp.any_failed
    js = comp.to_json()["scenarios"][0]
    assert js["limits"]["ax"] == [-6.0, 3.0] and "pmp" in js and len(js["pmp"]["hamiltonian_jump_residuals"]) == 1
