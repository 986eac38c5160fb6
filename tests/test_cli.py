"""SPEC §4–§6 through the CLI: the JSON contract, exit codes, and every bad input."""

import json

import numpy as np
import pytest
from conftest import run_cli
from scenario_texts import history_scenario

from iamp.core.scenario import builtin_text
from iamp.planners.examples import paper_problem
from iamp.planners.pmp.planner import PMPPlanner

GOOD = builtin_text("paper-1-poly")
HIST = history_scenario("-1.0, -0.5, 0.0", "-33.0, -24.0, -15.0", xf=85.0)

KEYS = {"scenario", "planner", "solver", "hold", "steps", "status", "cost", "contact_times", "jumps",
        "solve_time_s", "trajectory", "safety", "limits"}  # "safety": SPEC §9, "limits": SPEC §14


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_plan_json_contract_pmp(tmp_path):
    p = write(tmp_path, GOOD)
    r = run_cli("plan", p, "--json", "--steps", "50")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)  # exactly one JSON object and nothing else
    assert set(out) == KEYS
    assert out["planner"] == "pmp" and out["solver"] is None and out["hold"] is None and out["steps"] == 50
    assert out["status"] == "optimal"
    ref = PMPPlanner().plan(paper_problem(1))
    assert out["cost"] == pytest.approx(ref.cost, rel=1e-12)
    assert out["contact_times"] == pytest.approx(list(ref.contact_times), abs=1e-12)
    assert np.allclose(out["jumps"], ref.jumps, rtol=1e-12)
    tr = out["trajectory"]
    assert set(tr) == {"t", "x", "y", "vx", "vy", "ax", "ay"}
    assert tr["t"] == pytest.approx(list(np.linspace(0, 5, 51)))
    assert tr["x"][0] == 0.0 and tr["y"][-1] == pytest.approx(3.75)
    assert all(len(v) == 51 for v in tr.values())


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_plan_json_contract_qp_indexes_match_pmp(tmp_path, solver):
    p = write(tmp_path, GOOD)
    q = json.loads(run_cli("plan", p, "--json", "--planner", "qp", "--solver", solver, "--steps", "50",
                           "--contact", "refine").stdout)
    m = json.loads(run_cli("plan", p, "--json", "--steps", "50").stdout)
    assert q["solver"] == solver and q["hold"] == "foh" and q["planner"] == "qp"
    assert q["cost"] == pytest.approx(m["cost"], rel=1e-6)
    assert np.allclose(q["jumps"], m["jumps"], rtol=1e-3)
    assert np.allclose(q["trajectory"]["t"], m["trajectory"]["t"])
    assert np.max(np.abs(np.array(q["trajectory"]["x"]) - m["trajectory"]["x"])) < 1e-2


def test_plan_builtin_from_any_directory(tmp_path):
    r = run_cli("plan", "paper-2-poly", cwd=tmp_path)
    assert r.returncode == 0 and "optimal" in r.stdout
    r = run_cli("scenarios", cwd=tmp_path)
    assert "paper-1-poly" in r.stdout and "two-vehicle" in r.stdout


def _replace(text, old, new):
    assert old in text, old
    return text.replace(old, new, 1)


BAD = [
    ("syntax", lambda t: t + "\n[ego\n", "line"),
    ("missing-ego-key", lambda t: _replace(t, "tf = 5.0\n", ""), "ego.tf"),
    ("unknown-top-key", lambda t: "colour = 1\n" + t, "colour"),
    ("unknown-ego-key", lambda t: _replace(t, "tf = 5.0\n", "tf = 5.0\nmass = 3\n"), "ego.mass"),
    ("unknown-vehicle-key", lambda t: _replace(t, "length = 4.8", "length = 4.8\nheight = 1"), "vehicles[0].height"),
    ("non-numeric", lambda t: _replace(t, "x0 = 0.0", 'x0 = "zero"'), "ego.x0"),
    ("nan", lambda t: _replace(t, "vx0 = 20.0", "vx0 = nan"), "ego.vx0"),
    ("inf", lambda t: _replace(t, "xf = 85.0", "xf = inf"), "ego.xf"),
    ("tf-zero", lambda t: _replace(t, "tf = 5.0", "tf = 0.0"), "ego.tf"),
    ("tf-negative", lambda t: _replace(t, "tf = 5.0", "tf = -1.0"), "ego.tf"),
    ("length", lambda t: _replace(t, "length = 4.8", "length = 0.0"), "vehicles[0].length"),
    ("width", lambda t: _replace(t, "width = 1.8", "width = -1.8"), "vehicles[0].width"),
    ("safety-x", lambda t: _replace(t, "safety_x = 5.0", "safety_x = -0.1"), "vehicles[0].safety_x"),
    ("safety-y", lambda t: _replace(t, "safety_y = 0.5", "safety_y = -0.5"), "vehicles[0].safety_y"),
    ("corner", lambda t: _replace(t, 'corner = "front-lower"', 'corner = "front-left"'), "vehicles[0].corner"),
    ("empty-poly", lambda t: _replace(t, "x_poly = [-15.0, 18.0, 0.0, 0.0]", "x_poly = []"), "vehicles[0].x_poly"),
    ("poly-nan", lambda t: _replace(t, "x_poly = [-15.0, 18.0, 0.0, 0.0]", "x_poly = [-15.0, nan]"),
     "vehicles[0].x_poly[1]"),
    ("neither", lambda t: _replace(t, "x_poly = [-15.0, 18.0, 0.0, 0.0]", ""), "vehicles[0].x_poly"),
    ("both", lambda t: t + "[vehicles.history]\nt = [-1.0, 0.0]\nx = [-33.0, -15.0]\n", "vehicles[0].x_poly"),
    ("no-vehicles", lambda t: t[: t.index("[[vehicles]]")], "vehicles"),
]

BAD_HISTORY = [
    ("not-increasing", lambda t: _replace(t, "t = [-1.0, -0.5, 0.0]", "t = [-1.0, -1.0, 0.0]"),
     "vehicles[0].history.t"),
    ("mismatched", lambda t: _replace(t, "x = [-33.0, -24.0, -15.0]", "x = [-33.0, -15.0]"), "vehicles[0].history.x"),
    ("not-at-zero", lambda t: _replace(t, "t = [-1.0, -0.5, 0.0]", "t = [-1.5, -1.0, -0.5]"), "vehicles[0].history.t"),
    ("too-short", lambda t: _replace(_replace(t, "t = [-1.0, -0.5, 0.0]", "t = [0.0]"), "x = [-33.0, -24.0, -15.0]",
                                     "x = [-15.0]"),
     "vehicles[0].history.t"),
    ("history-unknown-key", lambda t: t + "v = [1.0, 2.0, 3.0]\n", "vehicles[0].history.v"),
]


def line_naming(r, field):
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    err = r.stderr.strip()
    assert len(err.splitlines()) == 1, err
    assert "Traceback" not in r.stderr
    assert field in err, (field, err)
    assert r.stdout == ""


@pytest.mark.parametrize("name,mutate,field", BAD, ids=[b[0] for b in BAD])
def test_bad_scenarios_are_refused(tmp_path, name, mutate, field):
    p = write(tmp_path, mutate(GOOD))
    before = p.read_bytes()
    r = run_cli("plan", p, "--json")
    line_naming(r, field)
    assert str(p) in r.stderr
    assert p.read_bytes() == before  # nothing the user gave is touched


@pytest.mark.parametrize("name,mutate,field", BAD_HISTORY, ids=[b[0] for b in BAD_HISTORY])
def test_bad_histories_are_refused(tmp_path, name, mutate, field):
    p = write(tmp_path, mutate(HIST))
    line_naming(run_cli("plan", p), field)


def test_history_shorter_than_the_predictor_needs(tmp_path):
    """A valid history that the shipped predictor cannot use (too short for its order)."""
    text = _replace(_replace(HIST, "t = [-1.0, -0.5, 0.0]", "t = [-0.1, 0.0]"), "x = [-33.0, -24.0, -15.0]",
                    "x = [-16.8, -15.0]")
    line_naming(run_cli("plan", write(tmp_path, text)), "vehicles[0].history")


def test_missing_file_and_bad_options(tmp_path):
    line_naming(run_cli("plan", tmp_path / "nope.toml"), "nope.toml")
    p = write(tmp_path, GOOD)
    r = run_cli("plan", p, "--planner", "magic")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--planner" in r.stderr
    r = run_cli("plan", p, "--steps", "-3")
    assert r.returncode == 2 and "--steps" in r.stderr and "Traceback" not in r.stderr


def test_solver_failure_exits_3_without_a_cost(monkeypatch, capsys):
    from iamp.cli import main as cli
    from iamp.cli import plan as cli_plan
    from iamp.planners.qp.planner import QPPlanner

    orig = cli_plan.make_planner

    def loose(args):
        planner = orig(args)
        if isinstance(planner, QPPlanner):
            planner.solver_settings = {"max_iter": 2, "polishing": False, "eps_abs": 1e-12}
        return planner

    monkeypatch.setattr(cli_plan, "prepared_plan", lambda args: loose(args).plan)
    code = cli.main(["plan", "paper-1-poly", "--planner", "qp", "--solver", "osqp", "--steps", "10", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 3
    assert out["status"] != "optimal" and out["cost"] is None
