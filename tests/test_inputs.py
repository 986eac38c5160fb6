"""Input hardening (issue 9): physical bounds, one-line refusals naming file, field and TOML
line, options that do not apply, model files, and no traceback on any input.

The CLI is called in-process (``iamp.cli.main.main``) to keep the suite fast; the few
process-level behaviours (a real ``python -m iamp`` traceback-free exit) use a subprocess.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from iamp.cli.main import main
from iamp.core.errors import ScenarioError
from iamp.core.limits import LIMITS, polynomial_message
from iamp.core.scenario import builtin_text, loads_scenario
from iamp.core.toml_lines import field_lines, line_of

GOOD = builtin_text("paper-1-poly")
TWO = builtin_text("two-vehicle")
HIST = builtin_text("paper-2")
POLY = "x_poly = [-15.0, 18.0, 0.0, 0.0]"
MODEL = Path(__file__).resolve().parents[1] / "prediction" / "data" / "mtd_default.json"


def run(*argv: object) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse refusals
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def sub(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def line_number(text: str, needle: str) -> int:
    return text[: text.index(needle)].count("\n") + 1


def refused(code: int, out: str, err: str, *fragments: str) -> str:
    assert code == 2, (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err and out == ""
    for f in fragments:
        assert f in lines[0], (f, lines[0])
    return lines[0]


# --------------------------------------------------------------------------------------------
# bounds (iamp.core.limits), each refused with file:line and the field
# --------------------------------------------------------------------------------------------

BOUNDS = [
    ("xf-1e308", "xf = 85.0", "xf = 1e308", "ego.xf"),
    ("x0-huge-int", "x0 = 0.0", "x0 = 100000000000000000000000000000000000", "ego.x0"),
    ("x0-above", "x0 = 0.0", "x0 = 100000.5", "ego.x0"),
    ("vx0", "vx0 = 20.0", "vx0 = -1000.5", "ego.vx0"),
    ("tf-1e6", "tf = 5.0", "tf = 1e6", "ego.tf"),
    ("tf-1e-300", "tf = 5.0", "tf = 1e-300", "ego.tf"),
    ("tf-small", "tf = 5.0", "tf = 0.0099", "ego.tf"),
    ("y-vehicle", "y = 3.75", "y = -2e5", "vehicles[0].y"),
    ("length-huge", "length = 4.8", "length = 1e4", "vehicles[0].length"),
    ("safety-huge", "safety_x = 5.0", "safety_x = 1e9", "vehicles[0].safety_x"),
    ("poly-1e300", POLY, "x_poly = [-15.0, 18.0, 0.0, 1e300]", "vehicles[0].x_poly"),
    ("poly-late-blowup", POLY, "x_poly = [-15.0, 18.0, 0.0, 900.0]", "vehicles[0].x_poly"),
    ("poly-fast", POLY, "x_poly = [-15.0, 1500.0]", "vehicles[0].x_poly"),
    ("poly-65-terms", POLY, "x_poly = [" + ", ".join(["0.0"] * 65) + "]", "vehicles[0].x_poly"),
    ("poly-huge-int", POLY, "x_poly = [1" + "0" * 400 + "]", "vehicles[0].x_poly[0]"),
]


@pytest.mark.parametrize("name,old,new,field", BOUNDS, ids=[b[0] for b in BOUNDS])
def test_unphysical_values_are_refused_with_file_field_and_line(tmp_path, name, old, new, field):
    text = sub(GOOD, old, new)
    p = tmp_path / "s.toml"
    p.write_text(text)
    line = refused(*run("plan", p, "--json"), field)
    assert f"{p}:{line_number(text, new)}:" in line


def test_bounds_hold_at_their_edges():
    """The documented limits are inclusive: a value exactly on a bound is accepted."""
    edge = sub(sub(GOOD, "tf = 5.0", f"tf = {LIMITS['tf_min_s']!r}"), "vx0 = 20.0",
               f"vx0 = {LIMITS['speed_max_mps']!r}")
    s = loads_scenario(edge, "s.toml")
    assert s.ego.tf == LIMITS["tf_min_s"] and s.ego.vx0 == LIMITS["speed_max_mps"]
    with pytest.raises(ScenarioError, match="ego.vx0"):
        loads_scenario(sub(edge, f"vx0 = {LIMITS['speed_max_mps']!r}", "vx0 = 1000.001"), "s.toml")


def test_polynomials_are_judged_by_their_values_not_their_coefficients():
    tf = 5.0
    # a 25-term Taylor series of 10 sin(t/2) + 20 t - 15: big terms that cancel; |x| stays < 1e5
    c = [-15.0, 20.0] + [0.0] * 23
    for k in range(25):
        if k % 2 == 1:
            c[k] += 10.0 * (-1) ** (k // 2) * 0.5**k / math.factorial(k)
    assert polynomial_message(c, tf) is None
    assert polynomial_message([-15.0, 18.0, 0.0, 0.0, 1e-300], tf) is None  # trailing denormal-size term
    # exp(t) with 40 Taylor terms at tf = 20 grows to 4.9e8 > 1e5 although every coefficient is <= 1
    exp_series = [1.0 / math.factorial(k) for k in range(40)]
    assert all(abs(x) <= 1 for x in exp_series)
    msg = polynomial_message(exp_series, 20.0)
    assert msg is not None and "x_s" in msg
    # an interior maximum: x_s(t) = P − 100 (t − 0.5)², ends at P − 25 < 1e5, peak P at t = 0.5
    for peak, ok in ((1e5 - 1, True), (1e5 + 1, False)):
        assert (polynomial_message([peak - 25.0, 100.0, -100.0], 1.0) is None) is ok


def test_taylor_series_scenario_plans(tmp_path):
    c = [-15.0, 18.0] + [(0.1 * (-1) ** k) / math.factorial(k) for k in range(2, 25)]
    text = sub(GOOD, POLY, "x_poly = [" + ", ".join(repr(x) for x in c) + "]")
    p = tmp_path / "taylor.toml"
    p.write_text(text)
    code, out, err = run("plan", p, "--json", "--steps", "20")
    assert code == 0, err
    assert json.loads(out)["status"] == "optimal"


def test_steps_and_qp_work_are_bounded(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(GOOD)
    refused(*run("plan", p, "--steps", "100000"), "--steps", "20000")
    refused(*run("plan", p, "--steps", "0"), "--steps")
    code, out, _err = run("plan", p, "--json", "--steps", "20000")  # the PMP samples 20001 points: fine
    assert code == 0 and len(json.loads(out)["trajectory"]["t"]) == 20001
    refused(*run("plan", p, "--planner", "qp", "--steps", "5000"), "--steps", "limit")


# --------------------------------------------------------------------------------------------
# the TOML text itself
# --------------------------------------------------------------------------------------------

def test_bare_carriage_return_is_refused_but_crlf_is_toml(tmp_path):
    p = tmp_path / "cr.toml"
    bare = sub(GOOD, "tf = 5.0\n", "tf = 5.0 # horizon\rxf = 1.0\n")  # a CR-only "line" hidden in a comment
    p.write_bytes(bare.encode())
    line = refused(*run("plan", p), "carriage return")
    assert f"{p}:{line_number(bare, 'tf = 5.0')}:" in line
    crlf = tmp_path / "crlf.toml"
    crlf.write_bytes(GOOD.replace("\n", "\r\n").encode())
    lf = tmp_path / "lf.toml"
    lf.write_text(GOOD)
    a, b = run("plan", crlf, "--json"), run("plan", lf, "--json")
    assert a[0] == b[0] == 0
    assert json.loads(a[1])["cost"] == json.loads(b[1])["cost"]


@pytest.mark.parametrize("payload,what", [
    ("a = " + "[" * 3000 + "]" * 3000 + "\n", "nested"),
    ("tf = 5.0\x00\n", "syntax"),
    ("[ego\n", "syntax"),
])
def test_pathological_toml_is_one_line(tmp_path, payload, what):
    p = tmp_path / "bad.toml"
    p.write_text(payload + GOOD)
    line = refused(*run("plan", p), str(p))
    assert what in line.lower() or "syntax" in line.lower()


def test_syntax_error_names_its_line(tmp_path):
    text = GOOD + "\n[ego\n"
    p = tmp_path / "s.toml"
    p.write_text(text)
    n = text.count("\n")  # the broken header is the last line
    assert f"{p}:{n}:" in refused(*run("plan", p), "TOML syntax error")


def test_invalid_utf8_and_missing_file(tmp_path):
    p = tmp_path / "latin.toml"
    p.write_bytes(GOOD.encode() + b"# caf\xe9\n")
    line = refused(*run("plan", p), str(p), "not UTF-8")
    assert f"{p}:{GOOD.count(chr(10)) + 1}:" in line  # the line holding the bad byte
    refused(*run("plan", tmp_path / "nope.toml"), "nope.toml")


def test_duplicate_vehicle_names_are_refused(tmp_path):
    text = sub(TWO, 'name = "sv2"', 'name = "sv1"')
    p = tmp_path / "dup.toml"
    p.write_text(text)
    line = refused(*run("plan", p), "vehicles[1].name", "duplicate")
    second = text.index('name = "sv1"', text.index('name = "sv1"') + 1)
    assert f"{p}:{text.count(chr(10), 0, second) + 1}:" in line


def test_too_many_vehicles_and_huge_histories(tmp_path):
    block = GOOD[GOOD.index("[[vehicles]]"):]
    many = GOOD + "".join(sub(block, 'name = "sv1"', f'name = "x{k}"') for k in range(int(LIMITS["vehicles_max"])))
    p = tmp_path / "many.toml"
    p.write_text(many)
    refused(*run("plan", p), "vehicles", "at most")
    n = int(LIMITS["history_samples_max"]) + 1
    t = ", ".join(f"{-(n - 1 - k) * 0.001:.3f}" for k in range(n))
    x = ", ".join(f"{-15.0 - (n - 1 - k) * 0.02:.3f}" for k in range(n))
    text = re.sub(r"t = \[[^\]]*\]", f"t = [{t}]", HIST, count=1)
    text = re.sub(r"\nx = \[[^\]]*\]", f"\nx = [{x}]", text, count=1)
    p.write_text(text)
    refused(*run("plan", p), "vehicles[0].history.t", "at most")


def test_history_sampling_and_positions_are_bounded():
    fast = re.sub(r"t = \[[^\]]*\]", "t = [-1e-5, 0.0]", HIST, count=1)
    fast = re.sub(r"\nx = \[[^\]]*\]", "\nx = [-15.1, -15.0]", fast, count=1)
    with pytest.raises(ScenarioError, match="apart") as e:
        loads_scenario(fast, "h.toml")
    assert e.value.field == "vehicles[0].history.t"
    n = len(re.search(r"t = \[([^\]]*)\]", HIST).group(1).split(","))
    far = re.sub(r"\nx = \[[^\]]*\]", "\nx = [" + ", ".join(["2e5"] * n) + "]", HIST, count=1)
    with pytest.raises(ScenarioError, match="100000") as e:
        loads_scenario(far, "h.toml")
    assert e.value.field == "vehicles[0].history.x[0]"


def test_field_lines_follow_tables_and_arrays_of_tables():
    lines = field_lines(TWO)
    assert lines["ego.tf"] == line_number(TWO, "tf = ")
    second = TWO.index("[[vehicles]]", TWO.index("[[vehicles]]") + 1)
    assert lines["vehicles[1]"] == TWO.count("\n", 0, second) + 1
    assert line_of(TWO, "vehicles[1].x_poly[3]") == lines["vehicles[1].x_poly"] > lines["vehicles[1]"]
    assert line_of(TWO, "vehicles[1].missing") == lines["vehicles[1]"]  # a missing key: its table
    assert line_of(HIST, "vehicles[0].history.t[4]") == line_number(HIST, "t = [")
    assert line_of("", "ego.tf") is None


# --------------------------------------------------------------------------------------------
# options
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("option,value", [("--solver", "osqp"), ("--hold", "zoh"), ("--contact", "refine")])
def test_qp_only_options_are_refused_with_the_pmp(option, value):
    refused(*run("plan", "paper-1-poly", option, value), option, "QP")
    code, out, err = run("plan", "paper-1-poly", "--planner", "qp", "--steps", "10", option, value, "--json")
    assert code == 0, err
    assert json.loads(out)["planner"] == "qp"


def test_defaults_of_qp_options_are_reported():
    code, out, _ = run("plan", "paper-1-poly", "--planner", "qp", "--steps", "10", "--json")
    d = json.loads(out)
    assert code == 0 and d["solver"] == "clarabel" and d["hold"] == "foh"
    code, out, _ = run("plan", "paper-1-poly", "--json", "--steps", "10")
    d = json.loads(out)
    assert d["solver"] is None and d["hold"] is None


def test_model_option_needs_a_history_scenario():
    refused(*run("plan", "paper-1-poly", "--model", MODEL), "--model", "history")
    code, _, err = run("plan", "paper-2", "--model", MODEL, "--json")
    assert code == 0, err


@pytest.mark.parametrize("change", [
    {"dt": 1e-6}, {"dt": 50.0}, {"order": "two"}, {"bins": [1, 2]}, {"lambda": "x"}, {"Q": [[["a"]]]},
    {"settings": [1]}, {"format": 7},
])
def test_malformed_model_files_are_one_line(tmp_path, change):
    d = json.loads(MODEL.read_text())
    d.update(change)
    p = tmp_path / "model.json"
    p.write_text(json.dumps(d))
    code, out, err = run("plan", "paper-2", "--model", p)
    line = refused(code, out, err, "--model", str(p))
    if "dt" in change:
        assert "dt" in line


def test_model_dt_bound_also_applies_to_predictors_in_the_api():
    """A predictor whose step would need more than prediction_steps_max samples is refused."""
    from iamp.core.scenario import loads_scenario as ls

    class Tiny:
        dt, name = 1e-3, "tiny"

        def predict(self, history, tf):  # pragma: no cover - never reached
            raise AssertionError

    s = ls(sub(HIST, "tf = 5.0", "tf = 100.0"), "h.toml")
    with pytest.raises(ScenarioError, match="predicted samples"):
        s.to_problem(Tiny())


# --------------------------------------------------------------------------------------------
# failures and internal errors
# --------------------------------------------------------------------------------------------

def test_pmp_failure_under_json_prints_the_object(monkeypatch):
    from iamp.core.errors import SolverError
    from iamp.planners.pmp.planner import PMPPlanner

    def boom(self, problem, *a, **k):
        raise SolverError("J(t) has no stationary point in (0, tf)", "numerical_error")

    monkeypatch.setattr(PMPPlanner, "plan", boom)
    code, out, _err = run("plan", "paper-1-poly", "--json")
    assert code == 3
    d = json.loads(out)
    assert d["status"] == "numerical_error" and d["cost"] is None and d["planner"] == "pmp"
    assert d["contact_times"] == [] and d["trajectory"]["x"] == []


def test_numerical_breakdown_is_a_failed_plan_not_a_traceback(monkeypatch):
    from iamp.planners.pmp.planner import PMPPlanner

    def singular(self, problem, *a, **k):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(PMPPlanner, "plan", singular)
    code, out, err = run("plan", "paper-1-poly", "--json")
    assert code == 3 and json.loads(out)["status"] == "numerical_error" and "Traceback" not in err
    code, out, err = run("plan", "paper-1-poly")
    assert code == 3 and "numerical_error" in out and "no cost" in out


def test_unexpected_error_is_one_line_and_debug_shows_the_traceback(monkeypatch):
    from iamp.cli import plan as cli_plan

    def bug(args):
        raise KeyError("oops")

    monkeypatch.setattr(cli_plan, "prepared_plan", bug)
    code, _, err = run("plan", "paper-1-poly")
    assert code == 1 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "internal error" in err and "--debug" in err
    code, _out, err = run("plan", "paper-1-poly", "--debug")
    assert code == 1 and "Traceback" in err and "KeyError" in err


def test_ctrl_c_is_exit_130_in_one_line(monkeypatch):
    from iamp.cli import plan as cli_plan

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_plan, "prepared_plan", interrupted)
    code, _out, err = run("plan", "paper-1-poly")
    assert code == 130 and err.strip() == "iamp: interrupted"


def test_stdin_is_read_as_bytes_so_a_bare_cr_is_refused_there_too():
    import subprocess
    import sys

    bare = sub(GOOD, "tf = 5.0\n", "tf = 5.0 # c\rx = 1\n").encode()
    r = subprocess.run([sys.executable, "-m", "iamp", "plan", "-"], input=bare, capture_output=True, timeout=120)
    err = r.stderr.decode()
    assert r.returncode == 2 and "carriage return" in err and "<stdin>:" in err and "Traceback" not in err
    r = subprocess.run([sys.executable, "-m", "iamp", "--debug", "plan", "-", "--json"], input=GOOD.encode(),
                       capture_output=True, timeout=120)
    assert r.returncode == 0 and json.loads(r.stdout)["status"] == "optimal"


@pytest.mark.parametrize("depth", [1, 40, 120])
def test_a_long_path_never_pushes_the_reason_off_the_error_line(monkeypatch, depth):
    """The refusal names the file and field in full and the reason after them, however deep the
    file lies (CI's checkout under a longer prefix once cut SUMO's reason off a 300-character line);
    only an overlong reason is shortened, at its own end."""
    from iamp.cli import plan as cli_plan
    from iamp.core.errors import ScenarioError

    source = "/" + "/".join(f"folder{k}" for k in range(depth)) + "/scene.cr.xml"
    reason = "SUMO refuses to insert the ego (TraCIException: the vehicle type 'bicycle' is too slow)"

    def refuse(args):
        raise ScenarioError(reason, "planningProblem.initialState", source)

    monkeypatch.setattr(cli_plan, "prepared_plan", refuse)
    code, _, err = run("plan", "paper-1-poly")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert lines[0] == f"iamp: error: {source}: field 'planningProblem.initialState': {reason}"

    def refuse_long(args):
        raise ScenarioError("x" * 1000, None, source)

    monkeypatch.setattr(cli_plan, "prepared_plan", refuse_long)
    code, _, err = run("plan", "paper-1-poly")
    line = err.strip()
    assert code == 2 and line.startswith(f"iamp: error: {source}: xxx") and line.endswith("...")
    assert len(line) == len(f"iamp: error: {source}: ") + 300
