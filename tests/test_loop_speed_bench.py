"""``iamp bench``'s closed-loop numbers time warm episodes and say so (issue 32 item 5).

Each planner's timed episodes follow one untimed episode of the same planner (``"warmup": 1`` in
the JSON, also in the episode's statistics), whose own wall time is kept as ``first_episode_s``
(the first episode of a process also loads ``libsumo``, the predictor's model and the planner's
modules).  The timed episodes are the warm-up's episode again: the same planner calls and outcome
(``same_episode``).  Wall and CPU time are the medians of the timed runs; the split (``wall_s``)
is the median run's.
"""

from __future__ import annotations

import pytest


def test_bench_loop_times_episodes_after_one_warm_up_episode(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("libsumo")
    from iamp.comparison.bench import loop
    from iamp.simulation.episode import run_episode

    runs: list[dict[str, object]] = []

    def recording(spec: object, **kw: object) -> object:
        r = run_episode(spec, **kw)  # type: ignore[arg-type]
        runs.append(r.summary)
        return r

    monkeypatch.setattr("iamp.simulation.episode.run_episode", recording)
    monkeypatch.setitem(loop.CASE, "duration_s", 3.0)  # a short episode: the bookkeeping, not the speed
    out = loop.bench_loop(3, ("free",))
    assert out["warmup"] == loop.WARMUP == 1 and out["repeats"] == 3
    row = out["planners"]["free"]
    assert row["episode"]["n"] == row["cpu"]["n"] == 3 and row["episode"]["warmup"] == 1
    assert len(runs) == 4  # the warm-up and the three timed episodes
    assert row["first_episode_s"] > 0.0
    assert out["episode_s"]["free"] == row["episode"]["median"] > 0.0
    assert out["episode_cpu_s"]["free"] == row["cpu"]["median"] > 0.0
    warm, *timed = runs
    for key in ("planner_calls", "success", "contacts", "simulated_s", "lane_change_done_s"):
        assert all(warm[key] == t[key] for t in timed)
    assert row["same_episode"] is True
    assert row["planner_calls"] == timed[0]["planner_calls"]
    assert row["simulated_s"] == timed[0]["simulated_s"] == pytest.approx(3.0)
    # the split is one timed run's own (the median run's), not a mixture of runs
    assert any(row["wall_s"] == t["wall_s"] for t in timed)
    assert row["episode"]["min"] <= row["episode"]["median"] <= row["episode"]["max"]


def test_bench_loop_says_when_runs_differ(monkeypatch: pytest.MonkeyPatch) -> None:
    """``same_episode`` is false when one run planned differently (here: a planner call count altered)."""
    pytest.importorskip("libsumo")
    from iamp.comparison.bench import loop
    from iamp.simulation.episode import run_episode

    calls = {"n": 0}

    def altered(spec: object, **kw: object) -> object:
        r = run_episode(spec, **kw)  # type: ignore[arg-type]
        calls["n"] += 1
        if calls["n"] == 2:
            r.summary["planner_calls"] += 1
        return r

    monkeypatch.setattr("iamp.simulation.episode.run_episode", altered)
    monkeypatch.setitem(loop.CASE, "duration_s", 1.0)
    assert loop.bench_loop(1, ("free",))["planners"]["free"]["same_episode"] is False
    with pytest.raises(ValueError):
        loop.bench_loop(0, ("free",))


def test_bench_loop_command_line(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """``iamp bench --loop --json`` prints the loop's JSON object alone; without --json a line per planner;
    ``--planner``/``--repeats`` only with ``--loop`` and only iamp planners of the loop."""
    pytest.importorskip("libsumo")
    import json

    from iamp.cli.main import main
    from iamp.comparison.bench import loop

    monkeypatch.setitem(loop.CASE, "duration_s", 1.0)
    assert main(["bench", "--loop", "--repeats", "1", "--planner", "free", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc["planners"]) == {"free"} and doc["repeats"] == 1 and doc["planners"]["free"]["same_episode"]
    assert main(["bench", "--loop", "--repeats", "1", "--planner", "free"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and out[1].split()[0] == "free"
    assert main(["bench", "--planner", "free"]) != 0
    assert main(["bench", "--loop", "--planner", "mobil"]) != 0


def test_every_timed_episode_computes_its_own_predictions(monkeypatch: pytest.MonkeyPatch) -> None:
    """Nothing the warm-up computed is reused by the timed episodes: each propagates as many pasts
    through the prediction model as the warm-up did (without the bench's forget_kept_data, the
    predictor's kept node accelerations would spare a repeated episode nearly every propagation)."""
    pytest.importorskip("libsumo")
    from iamp.comparison.bench import loop
    from iamp.prediction.mtd.model import MTDModel
    from iamp.simulation.episode import run_episode

    rows = {"n": 0}
    per_episode: list[int] = []
    original = MTDModel.propagate_batch

    def counting(self: MTDModel, init_states: object, steps: int) -> object:
        rows["n"] += len(init_states)  # type: ignore[arg-type]
        return original(self, init_states, steps)  # type: ignore[arg-type]

    def episode(spec: object, **kw: object) -> object:
        rows["n"] = 0
        r = run_episode(spec, **kw)  # type: ignore[arg-type]
        per_episode.append(rows["n"])
        return r

    monkeypatch.setattr(MTDModel, "propagate_batch", counting)
    monkeypatch.setattr("iamp.simulation.episode.run_episode", episode)
    monkeypatch.setitem(loop.CASE, "duration_s", 3.0)
    loop.bench_loop(2, ("free",))
    assert len(per_episode) == 3 and per_episode[0] > 0
    assert per_episode[1] == per_episode[2] == per_episode[0]
    # the check is not vacuous: the same episode again without forgetting propagates (nearly) nothing
    from iamp.comparison.bench.loop import _episode

    loop.forget_kept_data()
    _episode("free")
    _episode("free")
    assert per_episode[-1] < per_episode[0] // 2
