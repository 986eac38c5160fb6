"""``iamp commonroad bench`` (SPEC §16, §16b; issue 29 item 2, issue 33 items 4 and 6): the output
folder's ownership, resuming an interrupted bench, the manifest's refusals, and CommonRoad's cost
functions as the drivability checker's evaluator defines them.

The folder/resume tests replace the per-scenario work by a stub (no data needed, a second each);
the end-to-end ones need the ``[commonroad]`` extra and the shared US-101 scenarios and skip with
the reason where either is absent.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import HAVE_COMMONROAD, data_path, needs_commonroad, needs_commonroad_data
from hypothesis import given, settings
from hypothesis import strategies as st

DATA = data_path("commonroad", "US101")
HAVE_EXTRA = HAVE_COMMONROAD
needs_extra = needs_commonroad
needs_data = needs_commonroad_data("commonroad", "US101")
CLI = [sys.executable, "-W", "ignore", "-m", "iamp", "commonroad", "bench"]


def _scenarios(folder: Path, n: int) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for i in range(n):
        p = folder / f"S-{i}.xml"
        p.write_text("<commonRoad/>\n")
        out.append(p)
    return out


class _Stub:
    """Stands in for :func:`iamp.commonroad.bench.run_one`: counts calls, may be interrupted."""

    def __init__(self, interrupt_at: int | None = None) -> None:
        self.calls: list[tuple[str, str]] = []
        self.interrupt_at = interrupt_at

    def __call__(self, path: Path, planner: str, out_dir: Path | None, timeout_s: float, cost_function: str = "WX1",
                 vehicle_model: str = "PM", vehicle_type: int = 2) -> object:
        from iamp.commonroad.bench import Row

        if self.interrupt_at is not None and len(self.calls) == self.interrupt_at:
            raise KeyboardInterrupt
        self.calls.append((path.stem, planner))
        return Row(path.stem, planner, "valid", vehicle_model=vehicle_model, solve_time_s=0.5,
                   benchmark_id=f"{vehicle_model}{vehicle_type}:{cost_function}:{path.stem}:2020a",
                   costs={"WX1": 1.0 + len(self.calls), "SM1": None, "TR1": 2.0})


@needs_extra
def test_interrupted_bench_resumes_where_it_stopped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C after 3 of 6 results: the 3 (the first planner's) are on disk (atomically, with their
    parameters); the next run computes only the other 3 and returns all 6 in order; a third run
    computes nothing."""
    from iamp.commonroad import bench as B

    files = _scenarios(tmp_path / "in", 3)
    out = tmp_path / "out"
    stub = _Stub(interrupt_at=3)
    monkeypatch.setattr(B, "run_one", stub)
    with pytest.raises(KeyboardInterrupt):
        B.bench(tmp_path / "in", ["avoid", "free"], out, vehicle_model="KS")
    assert sorted(str(p.relative_to(out / "rows")) for p in (out / "rows").rglob("*.json")) == [
        "avoid/S-0.json", "avoid/S-1.json", "avoid/S-2.json"]  # planner by planner
    assert not list(out.rglob("*.tmp"))
    done = list(stub.calls)
    stub2 = _Stub()
    monkeypatch.setattr(B, "run_one", stub2)
    rows = B.bench(tmp_path / "in", ["avoid", "free"], out, vehicle_model="KS")
    assert [(r.scenario, r.planner) for r in rows] == [(f.stem, p) for p in ("avoid", "free") for f in files]
    assert not set(stub2.calls) & set(done) and len(stub2.calls) == 3
    stub3 = _Stub()
    monkeypatch.setattr(B, "run_one", stub3)
    again = B.bench(tmp_path / "in", ["avoid", "free"], out, vehicle_model="KS")
    assert stub3.calls == [] and [r.__dict__ for r in again] == [r.__dict__ for r in rows]


@needs_extra
@settings(max_examples=15, deadline=None)
@given(model=st.sampled_from(["PM", "KS"]), vtype=st.sampled_from([1, 2, 3]),
       cf=st.sampled_from(["WX1", "SM1", "TR1"]), timeout=st.sampled_from([60.0, 120.0]),
       change=st.sampled_from(["vehicle_model", "vehicle_type", "cost_function", "timeout_s"]))
def test_other_parameters_are_refused_unless_forced(tmp_path_factory: pytest.TempPathFactory, model: str,
                                                    vtype: int, cf: str, timeout: float, change: str) -> None:
    """A folder made with some parameters: the same ones resume (the manifest is kept); any other
    value of a defining parameter is refused naming it, and nothing is deleted; ``force`` discards
    the stored rows and solutions and records the new parameters."""
    from iamp.commonroad import bench as B

    out = tmp_path_factory.mktemp("bench")
    params = B.params_of(model, vtype, cf, timeout)
    B.prepare_folder(out, params)
    row = B.Row("S-0", "avoid", "valid")
    B.store_row(out, row, params, "S-0")
    (out / "solutions" / "avoid").mkdir(parents=True)
    (out / "solutions" / "avoid" / "S-0.solution.xml").write_text("x")
    assert B.prepare_folder(out, dict(params)) == params
    assert B.load_row(out, "avoid", "S-0", params) == row
    other = {"vehicle_model": "KS" if model == "PM" else "PM", "vehicle_type": vtype % 3 + 1,
             "cost_function": "JB1", "timeout_s": timeout + 1.0}[change]
    changed = dict(params, **{change: other})
    with pytest.raises(B.BenchMismatch, match=change):
        B.prepare_folder(out, changed)
    assert B.load_row(out, "avoid", "S-0", params) == row  # nothing deleted by a refusal
    assert B.load_row(out, "avoid", "S-0", changed) is None  # a row of other parameters is never reused
    B.prepare_folder(out, changed, force=True)
    assert not (out / "rows").exists() and not (out / "solutions").exists()
    assert json.loads((out / "manifest.json").read_text()) == changed


@needs_extra
def test_results_without_a_manifest_are_refused(tmp_path: Path) -> None:
    from iamp.commonroad import bench as B

    params = B.params_of()
    B.store_row(tmp_path, B.Row("S-0", "avoid", "valid"), params, "S-0")
    with pytest.raises(B.BenchMismatch, match="without a manifest"):
        B.prepare_folder(tmp_path, params)


@needs_extra
def test_cli_refuses_a_folder_holding_the_users_files(tmp_path: Path) -> None:
    """Issue 29 item 2: ``--out`` onto a folder with the user's own ``bench.md`` exited 0 and
    overwrote it; now exit 2, one line naming the folder and ``--force``, the file untouched (this
    happens before any scenario is read, so a stand-in scenario suffices)."""
    _scenarios(tmp_path / "in", 1)
    user = tmp_path / "mine"
    user.mkdir()
    (user / "bench.md").write_text("my notes\n")
    r = subprocess.run([*CLI, str(tmp_path / "in"), "--out", str(user)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "--force" in r.stderr and str(user) in r.stderr and "Traceback" not in r.stderr
    assert (user / "bench.md").read_text() == "my notes\n"
    assert not (user / ".iamp-output").exists()


@needs_data
@pytest.mark.slow  # 20-60 s on a loaded 2-core machine; the stub tests above are its fast version
def test_cli_bench_resumes_and_refuses_other_parameters(tmp_path: Path) -> None:
    """End to end on one scenario: a KS bench writes its manifest, row and solution (benchmark ID
    ``KS2:WX1:<scenario>:2020a``) and is valid; the same command again plans nothing (stored);
    ``--vehicle-model PM`` into it is refused (exit 2) until ``--force``."""
    folder = tmp_path / "one"
    folder.mkdir()
    name = "USA_US101-14_1_T-1"
    (folder / f"{name}.xml").symlink_to(DATA / f"{name}.xml")
    out = tmp_path / "out"
    base = [*CLI, str(folder), "--planners", "avoid", "--out", str(out)]
    r = subprocess.run([*base, "--vehicle-model", "KS"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    data = json.loads((out / "bench.json").read_text())
    row = data["rows"][0]
    assert row["category"] == "valid" and row["benchmark_id"] == f"KS2:WX1:{name}:2020a"
    assert all(row["costs"][cf] is not None and row["costs"][cf] > 0 for cf in ("WX1", "SM1", "TR1"))
    assert 'benchmark_id="KS2:WX1:' in (out / "solutions" / "avoid" / f"{name}.solution.xml").read_text()
    again = subprocess.run([*base, "--vehicle-model", "KS"], capture_output=True, text=True, timeout=600)
    assert again.returncode == 0 and "(stored)" in again.stderr
    assert json.loads((out / "bench.json").read_text())["rows"] == data["rows"]
    # a peer's folder holding the same solution: judged and scored exactly as iamp's row, labelled by peer.json
    peer = tmp_path / "peer"
    peer.mkdir()
    (peer / f"{name}.solution.xml").write_text((out / "solutions" / "avoid" / f"{name}.solution.xml").read_text())
    (peer / "peer.json").write_text(json.dumps([{"scenario": name, "planner": "x-peer", "status": "goal reached",
                                                 "solve_time_s": 1.0}]))
    withpeer = subprocess.run([*base, "--vehicle-model", "KS", "--peer", str(peer), "--json"], capture_output=True,
                              text=True, timeout=600)
    assert withpeer.returncode == 0, withpeer.stderr[-2000:]
    both = {r["planner"]: r for r in json.loads(withpeer.stdout)["rows"]}
    assert both["x-peer"]["category"] == "valid" and both["x-peer"]["costs"] == both["avoid"]["costs"]
    assert both["x-peer"]["benchmark_id"] == both["avoid"]["benchmark_id"]
    pm = subprocess.run([*base, "--vehicle-model", "PM"], capture_output=True, text=True, timeout=600)
    assert pm.returncode == 2 and "vehicle_model" in pm.stderr and "Traceback" not in pm.stderr
    forced = subprocess.run([*base, "--vehicle-model", "PM", "--force"], capture_output=True, text=True, timeout=600)
    assert forced.returncode == 0, forced.stderr[-2000:]
    assert json.loads((out / "bench.json").read_text())["rows"][0]["benchmark_id"] == f"PM2:WX1:{name}:2020a"


# --- the cost functions --------------------------------------------------------------------------


def _signals(v: np.ndarray, dt: float, steering: np.ndarray | None = None, goal_v: float | None = None) -> object:
    from iamp.commonroad.costs import _Signals

    n = len(v)
    return _Signals(dt=dt, k=np.arange(n, dtype=float), position=np.zeros((n, 2)), velocity=v,
                    orientation=np.zeros(n), steering=steering, goal_v=goal_v, lon=np.cumsum(v) * dt,
                    lat_lane=np.zeros(n), dpsi_lane=np.zeros(n), dist_ahead=np.full(n, math.inf))


@needs_extra
@settings(max_examples=40, deadline=None)
@given(n=st.integers(8, 120), v0=st.floats(0.0, 30.0), a=st.floats(-3.0, 3.0), vg=st.floats(0.0, 30.0),
       rate=st.floats(-0.3, 0.3))
def test_partial_costs_match_their_closed_forms(n: int, v0: float, a: float, vg: float, rate: float) -> None:
    """On a constant acceleration and a steering ramp the evaluator's partial costs have closed
    forms (Simpson's rule is exact for cubics): ``A = a^2 (n-2)dt`` (the differenced signal has
    ``n-1`` samples), ``J = 0``, ``L = v0 T + a T^2/2``, ``T = (n-1)dt``, ``V = ∫(v_g - v)^2``,
    ``SR = rate^2 (n-2)dt``, ``SA = ∫(rate t)^2``, ``D = 0`` without a vehicle ahead; WX1 is their
    weighted sum with the evaluator's weights."""
    from iamp.commonroad.costs import COST_FUNCTIONS, _partial

    dt = 0.1
    t = np.arange(n) * dt
    T = (n - 1) * dt
    s = _signals(v0 + a * t, dt, steering=rate * t, goal_v=vg)
    assert _partial("A", s) == pytest.approx(a * a * (n - 2) * dt, rel=1e-9, abs=1e-12)  # type: ignore[arg-type]
    assert _partial("J", s) == pytest.approx(0.0, abs=1e-6)  # type: ignore[arg-type]
    assert _partial("L", s) == pytest.approx(v0 * T + 0.5 * a * T * T, rel=1e-9, abs=1e-9)  # type: ignore[arg-type]
    assert _partial("T", s) == pytest.approx(T)  # type: ignore[arg-type]
    c = vg - v0
    v_exact = c * c * T - c * a * T * T + a * a * T**3 / 3.0 if vg else 0.0
    assert _partial("V", s) == pytest.approx(v_exact, rel=1e-9, abs=1e-9)  # type: ignore[arg-type]
    assert _partial("SR", s) == pytest.approx(rate * rate * (n - 2) * dt, rel=1e-9, abs=1e-12)  # type: ignore
    assert _partial("SA", s) == pytest.approx(rate * rate * T**3 / 3.0, rel=1e-9, abs=1e-12)  # type: ignore
    assert _partial("D", s) == 0.0  # type: ignore[arg-type]
    w = dict(COST_FUNCTIONS["WX1"])
    assert w == {"T": 10.0, "V": 1.0, "A": 0.1, "J": 0.1, "D": 0.1, "L": 10.0}
    assert dict(COST_FUNCTIONS["SM1"]) == {"A": 50.0, "SA": 50.0, "SR": 50.0, "L": 1.0, "V": 20.0, "O": 50.0}
    assert dict(COST_FUNCTIONS["TR1"]) == {"Jlon": 0.01, "SR": 22.0, "D": 8.0, "LC": 0.5}


@needs_extra
def test_steering_costs_are_undefined_for_a_point_mass() -> None:
    from iamp.commonroad.costs import _partial

    s = _signals(np.full(10, 10.0), 0.1)
    with pytest.raises(ValueError, match="steering"):
        _partial("SR", s)  # type: ignore[arg-type]


#: CommonRoad's own evaluator (commonroad_dc.costs.evaluation.CostFunctionEvaluator, drivability
#: checker 2025.4 with commonroad-clcs 2025.2, run in the peer's environment by
#: scripts/commonroad_costs.py) on KS solutions of iamp's default planner; the committed
#: cross-check of reports/commonroad/ has every solution of the bench.
CROSSCHECK = Path(__file__).resolve().parents[1] / "reports" / "commonroad" / "costs-crosscheck.json"


@needs_data
def test_costs_agree_with_commonroads_evaluator() -> None:
    """iamp's costs on six of the bench's committed KS solutions of the default planner against the
    evaluator's numbers on the same files: WX1 within 0.01 %, SM1 within 0.2 % (their only
    lane-relative term, the heading to the lane, is small), TR1's median within 2 % (its lane-centre
    and distance terms come from another projection; on a lane change up to 19 %, module
    docstring of iamp.commonroad.costs)."""
    from commonroad.common.solution import CommonRoadSolutionReader

    from iamp.commonroad.convert import load
    from iamp.commonroad.costs import evaluate

    if not CROSSCHECK.is_file():
        pytest.skip(f"no cross-check file ({CROSSCHECK})")
    ref = json.loads(CROSSCHECK.read_text())
    keys = sorted(k for k in ref if k.startswith("solutions/avoid/"))[:6]
    assert len(keys) == 6
    tr1 = []
    for rel in keys:
        sol = CommonRoadSolutionReader.open(str(CROSSCHECK.parent / rel))
        mine = evaluate(load(DATA / f"{sol.scenario_id}.xml"), sol)
        assert mine["WX1"]["total"] == pytest.approx(ref[rel]["WX1"]["total"], rel=1e-4), rel
        assert mine["SM1"]["total"] == pytest.approx(ref[rel]["SM1"]["total"], rel=2e-3), rel
        tr1.append(abs(mine["TR1"]["total"] / ref[rel]["TR1"]["total"] - 1.0))
    assert sorted(tr1)[len(tr1) // 2] < 0.02
