"""`iamp compare`: verdicts that agree when they should and fail when they should, the
exact ZOH reference, the timing statistics, the LaTeX writer and the JSON schema.

No timing assertions (speed is measured by ``iamp bench``, never by tests).
"""

import json
import os
from dataclasses import replace

import numpy as np
import pytest

from iamp.comparison import timing
from iamp.comparison.agreement.fingerprints import problem_fingerprint, x_poly_fingerprint
from iamp.comparison.agreement.judge import QPConfig, Run, compare_pmp_qp, compare_problem, default_configs, run_qp
from iamp.comparison.agreement.references import grid_cost_table, zoh_reference
from iamp.comparison.report.latex import Raw, booktabs_table, escape, sci, write_atomic
from iamp.core.tolerances import tol
from iamp.planners.examples import paper_problem, random_problem, two_minima_problem
from iamp.planners.pmp.planner import PMPPlanner, ValueFunction
from iamp.planners.qp.core import DiscretisedQP as build_native

LOOSE_OSQP = {"eps_abs": 1e-2, "eps_rel": 1e-2, "polishing": False, "max_iter": 200}


def _verdicts(comp):
    return {(a["a"], a["b"]): a for a in comp.agreement}


def _assert_all_agree(comp):
    bad = [(a["a"], a["b"], a["reasons"]) for a in comp.agreement if a["verdict"] != "agree"]
    assert not bad, bad


# --------------------------------------------------------------------------------------
# verdicts that must agree
# --------------------------------------------------------------------------------------

ONE = [paper_problem(1), paper_problem(2), paper_problem(3), random_problem(31, m=1, side=1),
       random_problem(32, m=1, side=-1)]


@pytest.mark.parametrize("problem", ONE, ids=[p.name for p in ONE])
def test_verdicts_agree_one_vehicle(problem):
    comp = compare_problem(problem, default_configs(steps=(24,)), repeats=1, warmup=0, pmp_repeats=2)
    assert not comp.any_failed
    _assert_all_agree(comp)
    v = _verdicts(comp)
    foh = v[("pmp", "qp-clarabel-foh-24")]
    same = foh["at_same_contact_times"]
    assert abs(same["cost_rel_gap"]) < 1e-9 and same["contact_time_gap_to_grid_optimum"] == 0.0
    # run against run (SPEC §5b): the grid run can only be at or above the continuous optimum,
    # and its contact times are the QP's own, not the PMP's
    assert foh["cost_rel_gap"] >= -1e-12
    assert foh["contact_time_gap"] == pytest.approx(np.max(np.abs(np.asarray(same["contact_times"])
                                                                  - comp.run("pmp").result.contact_times)), abs=1e-12)
    zoh = v[("pmp", "qp-clarabel-zoh-24")]
    assert zoh["at_same_contact_times"]["cost_rel_gap"] > 0  # ZOH only restricts the input
    assert zoh["cost_rel_gap"] >= foh["cost_rel_gap"] - 1e-12
    assert 1.0 <= zoh["zoh_gap"]["ratio_to_leading"] <= 1.0 / (1.0 - zoh["zoh_gap"]["rho"]) + 1e-6
    # same polynomial reached every planner
    assert len({r.x_poly_fingerprint for r in comp.runs}) == 1


def test_verdicts_agree_two_vehicles_and_native_path():
    p = random_problem(21, m=2, side=1)
    cfgs = [QPConfig("clarabel", "foh", 10), QPConfig("clarabel", "zoh", 10),
            QPConfig("clarabel", "foh", 10, path="native"), QPConfig("osqp", "foh", 10, path="native")]
    comp = compare_problem(p, cfgs, repeats=1, warmup=0, pmp_repeats=2)
    _assert_all_agree(comp)
    v = _verdicts(comp)
    assert ("qp-clarabel-foh-10", "qp-clarabel-foh-10-native") in v


def test_refine_configuration_agrees_with_the_continuous_optimum():
    p = paper_problem(1)
    comp = compare_problem(p, [QPConfig("clarabel", "foh", 30, contact="refine")], repeats=1, warmup=0,
                           pmp_repeats=2)
    _assert_all_agree(comp)


# --------------------------------------------------------------------------------------
# verdicts that must fail
# --------------------------------------------------------------------------------------


def test_loose_osqp_is_caught():
    p = paper_problem(1)
    cfgs = [QPConfig("osqp", "foh", 20, settings=LOOSE_OSQP, tag="loose"), QPConfig("clarabel", "foh", 20)]
    comp = compare_problem(p, cfgs, repeats=1, warmup=0, pmp_repeats=2)
    v = _verdicts(comp)
    loose = v[("pmp", "qp-osqp-foh-20-loose")]
    assert loose["verdict"] == "disagree"
    assert v[("pmp", "qp-clarabel-foh-20")]["verdict"] == "agree"
    assert v[("qp-osqp-foh-20-loose", "qp-clarabel-foh-20")]["verdict"] == "disagree"
    # the plan verified itself: its recomputed KKT residuals miss the OSQP tolerance, so it
    # reports INACCURATE, names the check and reports no cost
    res = comp.run("qp-osqp-foh-20-loose").result
    assert res.status == "inaccurate" and res.cost is None
    assert res.info["failed_check"] in ("kkt_primal_rel", "kkt_dual_rel", "kkt_gap_rel")
    check = res.info["checks"][res.info["failed_check"]]
    assert check["value"] > check["tol"] == tol("cmp_kkt_rel_osqp")


def test_corrupted_polynomial_is_caught_by_the_identical_problem_check():
    p = paper_problem(1)
    v0 = p.vehicles[0]
    corrupted = p.with_vehicles([replace(v0, x_poly=(v0.x_poly[0] + 1e-9,) + tuple(v0.x_poly[1:]))])
    assert x_poly_fingerprint(corrupted) != x_poly_fingerprint(p)
    assert problem_fingerprint(corrupted) != problem_fingerprint(p)
    comp = compare_problem(p, [QPConfig("clarabel", "foh", 16)], repeats=1, warmup=0, pmp_repeats=2,
                           problems={"qp-clarabel-foh-16": corrupted})
    a = _verdicts(comp)[("pmp", "qp-clarabel-foh-16")]
    assert a["verdict"] == "disagree"
    assert any("x_poly" in r for r in a["reasons"]), a["reasons"]


def test_a_pmp_stuck_in_a_local_minimum_is_caught():
    p = two_minima_problem()
    pmp = PMPPlanner()
    t_glob = pmp.contact_times(p)
    vf = ValueFunction(p)
    # the other local minimum: the best grid point at least 1 s away from t*
    ts = np.linspace(0.05, p.tf - 0.05, 2000)
    far = np.abs(ts - t_glob[0]) > 1.0
    t_loc = ts[far][np.argmin(vf(ts[far][:, None]))]
    from iamp.planners.pmp.planner import _newton_on_jump_conditions  # polish to the local minimum

    t_loc, _ = _newton_on_jump_conditions(p, vf, np.array([t_loc]))
    local = pmp.plan(p, t_loc)
    assert local.cost > vf(t_glob[None, :])[0]
    pmp_run = Run("pmp", "pmp", local, None, fingerprint=problem_fingerprint(p),
                  x_poly_fingerprint=x_poly_fingerprint(p))
    qp_run = run_qp(p, QPConfig("clarabel", "foh", 60), repeats=1, warmup=0)
    a = compare_pmp_qp(p, pmp_run, qp_run)
    assert a["verdict"] == "disagree"
    assert any("pmp_global_lower_bound" in r for r in a["reasons"]), a["reasons"]


# --------------------------------------------------------------------------------------
# the exact ZOH reference
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("problem", [paper_problem(3), random_problem(21, m=2, side=1)],
                         ids=["paper-3", "random-21-m2"])
def test_zoh_closed_form_equals_the_zoh_qp_and_brackets_the_gap(problem):
    n = 20
    nodes = [11, 6][: problem.m]
    t_nodes = np.linspace(0, problem.tf, n + 1)
    z = zoh_reference(problem, t_nodes, nodes)
    r = build_native(problem, n, "zoh", "clarabel").solve_nodes(nodes)
    assert r.trajectory is not None and r.multipliers is not None
    assert r.cost == pytest.approx(z["cost"], rel=1e-10)
    assert np.max(np.abs(r.trajectory.X - z["X"])) <= 1e-8 * np.max(np.abs(z["X"]))
    assert np.max(np.abs(r.multipliers - z["nu"])) <= 1e-7 * max(1, np.max(np.abs(z["nu"])))
    pmp_cost = PMPPlanner().plan(problem, t_nodes[nodes]).cost
    assert z["J_continuous"] == pytest.approx(pmp_cost, rel=1e-10)
    gap = z["cost"] - pmp_cost
    assert z["gap_leading"] <= gap * (1 + 1e-9) and gap <= z["gap_leading"] / (1 - z["rho"]) * (1 + 1e-9)


def test_grid_cost_tables_match_the_solvers():
    p = paper_problem(2)
    n = 16
    for hold in ("foh", "zoh"):
        _cands, J = grid_cost_table(p, n, hold)
        q = build_native(p, n, hold, "clarabel")
        for k in (1, 5, 9, 15):
            assert q.solve_nodes([k]).cost == pytest.approx(J[k - 1], rel=1e-9)


# --------------------------------------------------------------------------------------
# timing statistics (known samples; nothing is timed)
# --------------------------------------------------------------------------------------


def test_summary_statistics_on_known_samples():
    s = timing.summarize([10, 9, 8, 7, 6, 5, 4, 3, 2, 1])
    assert s.n == 10 and s.median == 5.5
    assert s.q1 == pytest.approx(3.25) and s.q3 == pytest.approx(7.75) and s.iqr == pytest.approx(4.5)
    assert s.p95 == pytest.approx(9.55)
    assert s.mean == 5.5 and s.min == 1 and s.max == 10
    one = timing.summarize([0.25])
    assert one.median == one.p95 == 0.25 and one.iqr == 0
    with pytest.raises(ValueError):
        timing.summarize([])


def test_shifted_geometric_mean():
    assert timing.shifted_geomean([0.01, 0.03], shift=0.01) == pytest.approx(np.sqrt(0.02 * 0.04) - 0.01)
    assert timing.shifted_geomean([0.2, 0.2, 0.2]) == pytest.approx(0.2)
    # shift 0 is the plain geometric mean
    assert timing.shifted_geomean([1.0, 4.0], shift=0.0) == pytest.approx(2.0)
    assert timing.DEFAULT_SHIFT_S == 0.01
    with pytest.raises(ValueError):
        timing.shifted_geomean([-0.02], shift=0.01)
    table = timing.geomean_table({"a": {"pmp": 0.01, "qp": 0.03}, "b": {"pmp": 0.03}}, shift=0.01)
    assert table["shift_s"] == 0.01
    assert table["means"]["pmp"]["n"] == 2 and table["means"]["qp"]["n"] == 1
    assert table["means"]["pmp"]["shifted_geomean_s"] == pytest.approx(np.sqrt(0.02 * 0.04) - 0.01)


def test_measure_counts_warmup_and_repeats_and_respects_the_budget():
    calls = []
    stats, last = timing.measure(lambda: calls.append(1) or len(calls), repeats=5, warmup=2)
    assert len(calls) == 7 and stats.n == 5 and stats.warmup == 2 and last == 7
    calls.clear()
    stats, _ = timing.measure(lambda: calls.append(1), repeats=100, warmup=0, budget_s=0.0)
    assert stats.n == 1 and len(calls) == 1  # the budget stops after the first sample


def test_versions_and_settings_are_recorded():
    v = timing.versions()
    for k in ("python", "numpy", "scipy", "cvxpy", "osqp", "clarabel"):
        assert v[k]
    s = timing.solver_settings()
    assert s["osqp"]["eps_rel"] == 0.0 and "tol_gap_abs" in s["clarabel"]


def test_qp_breakdown_reports_every_part():
    b = timing.qp_breakdown(paper_problem(1), steps=10, hold="foh", solver="clarabel", repeats=3)
    for k in ("cvxpy_resolve_s", "cvxpy_solver_s", "cvxpy_overhead_s", "native_solve_s", "native_solve_call_s",
              "native_solver_s"):
        assert (b[k]["n"] == 3 and b[k]["median"] >= 0) or k == "cvxpy_overhead_s"
    assert b["cvxpy_compile_s"] > 0 and b["native_setup_s"] > 0


# --------------------------------------------------------------------------------------
# LaTeX
# --------------------------------------------------------------------------------------


def test_latex_escaping_and_booktabs():
    assert escape("a_b & 50% $x$ #1 {y} ~^\\") == (
        r"a\_b \& 50\% \$x\$ \#1 \{y\} \textasciitilde{}\textasciicircum{}\textbackslash{}")
    assert escape(Raw(r"$\nu$")) == r"$\nu$"
    assert sci(1.234e-9) == r"$1.23\times10^{-9}$" and sci(None) == "--" and sci(0.0) == "$0$"
    tex = booktabs_table(["run", Raw("$J$")], [["qp_1", sci(22.865, 3)], None, ["pmp", "1"]],
                         caption="x", label="tab:x")
    assert r"\toprule" in tex and r"\midrule" in tex and r"\bottomrule" in tex
    assert r"qp\_1" in tex and r"\label{tab:x}" in tex
    with pytest.raises(ValueError):
        booktabs_table(["a", "b"], [["only one"]])


def test_write_atomic_replaces_whole_files_and_leaves_no_temporaries(tmp_path):
    path = tmp_path / "t.tex"
    write_atomic(path, "first\n")
    write_atomic(path, "second\n")
    assert path.read_text() == "second\n"
    with pytest.raises(TypeError):
        write_atomic(path, None)  # fails while writing: the old file stays
    assert path.read_text() == "second\n"
    assert sorted(os.listdir(tmp_path)) == ["t.tex"]


# --------------------------------------------------------------------------------------
# the command line
# --------------------------------------------------------------------------------------


def test_compare_json_schema_and_latex(cli, tmp_path):
    tex = tmp_path / "cmp.tex"
    r = cli("compare", "paper-1-poly", "--steps", "12", "--repeats", "1", "--no-breakdown", "--solvers",
            "clarabel", "--json", "--latex", tex)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)  # exactly one JSON object
    sc = out["scenarios"][0]
    assert sc["name"] == "paper-1-poly"
    labels = [run["label"] for run in sc["runs"]]
    assert labels == ["pmp", "qp-clarabel-foh-12", "qp-clarabel-zoh-12"]
    for run in sc["runs"]:
        for k in ("label", "planner", "solver", "hold", "steps", "status", "cost", "contact_times", "jumps",
                  "time_s"):
            assert k in run
        assert "median" in run["time_s"]
        assert run["status"] == "optimal"
    assert sc["runs"][0]["solver"] is None and sc["runs"][1]["solver"] == "clarabel"
    for a in sc["agreement"]:
        for k in ("a", "b", "cost_rel_gap", "contact_time_gap", "state_sup_gap", "jump_gap", "verdict"):
            assert k in a
        assert a["verdict"] == "agree", a["reasons"]
    assert out["timing_summary"]["shift_s"] == 0.01
    for k in ("python", "numpy", "scipy", "cvxpy", "osqp", "clarabel"):
        assert out["versions"][k]
    assert "osqp" in out["solver_settings"]
    assert tex.exists() and r"\toprule" in tex.read_text()


def test_compare_text_output_and_bad_options(cli, tmp_path):
    r = cli("compare", "paper-2-poly", "--steps", "10", "--repeats", "1", "--holds", "foh", "--solvers", "clarabel")
    assert r.returncode == 0, r.stderr
    assert "agree" in r.stdout and "verdicts: 2 of 2" not in r.stdout  # one pair only
    assert "verdicts: 1 of 1 pairs agree" in r.stdout
    r = cli("compare", "two-vehicle", "--steps", "2")
    assert r.returncode == 2 and "--steps" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = cli("compare", "two-vehicle", "--steps", "1000")
    assert r.returncode == 2 and "--steps" in r.stderr
    r = cli("compare", str(tmp_path / "missing.toml"))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    r = cli("compare", "paper-1-poly", "--repeats", "0")
    assert r.returncode == 2


def test_headline_gaps_are_run_against_run():
    """SPEC §5b: a coarse grid run that misses t* reads its real gap, not the identity at t_Q."""
    problem = paper_problem(1)
    comp = compare_problem(problem, [QPConfig("clarabel", "foh", 7)], repeats=1, warmup=0, pmp_repeats=1)
    a = comp.agreement[0]
    pmp, qp = comp.run("pmp").result, comp.run("qp-clarabel-foh-7").result
    assert a["cost_rel_gap"] == pytest.approx((qp.cost - pmp.cost) / pmp.cost, rel=1e-12)
    assert a["cost_rel_gap"] > 1e-4  # a 7-interval grid cannot hit t*
    assert a["contact_time_gap"] == pytest.approx(float(np.max(np.abs(qp.contact_times - pmp.contact_times))))
    assert a["contact_time_gap"] > 1e-3
    tn = np.asarray(qp.trajectory.t_nodes)
    assert a["state_sup_gap"] == pytest.approx(float(np.max(np.abs(qp.trajectory.states(tn)
                                                                   - pmp.trajectory.states(tn)))))
    assert a["jump_gap"] == pytest.approx(float(np.max(np.abs(qp.jumps - pmp.jumps))))
    # the exact identity lives under its own key
    assert abs(a["at_same_contact_times"]["cost_rel_gap"]) < 1e-9
    assert a["verdict"] == "agree" and "at_same_contact_times" in a["verdict_basis"]
