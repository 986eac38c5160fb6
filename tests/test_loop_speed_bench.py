"""``iamp bench``'s closed-loop numbers time warm episodes and say so (issue 32 item 5).

Each planner's timed episodes follow one untimed episode of the same planner (``"warmup": 1`` in
the JSON, also in the episode's statistics), whose own wall time is kept as ``first_episode_s``
(the first episode of a process also loads ``libsumo``, the predictor's model and the planner's
modules).  The timed episode is the warm-up's episode again: the same planner calls and outcome.
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
    out = loop.bench_loop(1, ("free",))
    assert out["warmup"] == loop.WARMUP == 1
    row = out["planners"]["free"]
    assert row["episode"]["n"] == 1 and row["episode"]["warmup"] == 1
    assert len(runs) == 2  # the warm-up and the timed episode
    assert row["first_episode_s"] > 0.0
    assert out["episode_s"]["free"] == row["episode"]["median"] > 0.0
    warm, timed = runs
    for key in ("planner_calls", "success", "contacts", "simulated_s", "lane_change_done_s"):
        assert warm[key] == timed[key]
    assert row["planner_calls"] == timed["planner_calls"]
