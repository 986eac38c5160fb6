"""``iamp bench``'s closed-loop numbers (issue 32 item 5): whole 60 s SUMO episodes, one process.

The case (:data:`CASE`): the ``merge`` mission, ``dense`` traffic, seed 1, 60 s of mission
clock, the same episode as ``iamp simulate --mission merge --traffic dense --seed 1 --planner P
--duration 60``.  Every iamp planner of the loop (:data:`iamp.simulation.planning.IAMP_PLANNERS`)
plans with the passenger car's limits imposed (SPEC §14, §15).  Timed: the wall time of one whole
:func:`~iamp.simulation.episode.run_episode` call per planner (``repeats`` of them, median) after
:data:`WARMUP` untimed episode of the same planner (``warmup`` in the JSON), with the episode's own
split (``wall_s``: SUMO, prediction, planning), its planner calls and its outcome (``success``,
``contacts``).  The warm-up episode's own wall time is reported too (``first_episode_s``): the
first episode of a process also pays for loading SUMO (``libsumo``), the predictor's model and the
planner's modules, once per process — a campaign's workers run many episodes each, a single
``iamp simulate`` pays it once.  What the episode plans is deterministic (the same
seed gives the same episode); only the times vary.  Issue 32's target: a 60 s episode in at
most :data:`TARGET_EPISODE_S` of wall time for every iamp planner.  Needs ``iamp[sim]`` (SUMO).
"""

from __future__ import annotations

import time
from typing import Any, TypedDict

from iamp.comparison.timing import StatsJSON, measure

__all__ = ["CASE", "TARGET_EPISODE_S", "WARMUP", "LoopBench", "LoopCase", "LoopRow", "bench_loop"]


class LoopCase(TypedDict):
    """The episode timed: mission, traffic, seed, mission clock [s]."""

    mission: str
    traffic: str
    seed: int
    duration_s: float


class LoopRow(TypedDict):
    """One planner's episode: wall time statistics [s], the episode's own split of its last run
    (``sumo``, ``prediction``, ``planning``, ``total``), planner calls and outcome."""

    episode: StatsJSON
    first_episode_s: float
    wall_s: dict[str, float]
    planner_calls: int
    success: bool
    contacts: int
    limit_violations: int


class LoopBench(TypedDict):
    """:func:`bench_loop`: the case, the repeats, the untimed episodes before them, one row per planner
    and their medians."""

    case: LoopCase
    repeats: int
    warmup: int
    planners: dict[str, LoopRow]
    episode_s: dict[str, float]
    target_episode_s: float


#: The episode timed (module docstring).
CASE: LoopCase = {"mission": "merge", "traffic": "dense", "seed": 1, "duration_s": 60.0}
#: Issue 32 item 5: a 60 s episode takes at most this much wall time, for every iamp planner.
TARGET_EPISODE_S = 1.0
#: Untimed episodes of each planner before the timed ones (their wall time: ``first_episode_s``).
WARMUP = 1


def _episode(planner: str) -> Any:
    from iamp.simulation.episode import EpisodeSpec, run_episode

    spec = EpisodeSpec(planner=planner, mission=str(CASE["mission"]), traffic=str(CASE["traffic"]),
                       seed=int(CASE["seed"]), duration_s=float(CASE["duration_s"]))
    return run_episode(spec)


def bench_loop(repeats: int = 1, planners: tuple[str, ...] | None = None) -> LoopBench:
    """Time whole 60 s episodes per iamp planner (module docstring).

    Parameters
    ----------
    repeats : int
        Timed episodes per planner (the median is reported), after :data:`WARMUP` untimed ones.
    planners : tuple of str, optional
        The planners (default every iamp planner of the loop).

    Returns
    -------
    LoopBench
        The case, one row per planner and ``episode_s`` (planner -> median wall time [s]).
    """
    from iamp.simulation.planning import IAMP_PLANNERS

    rows: dict[str, LoopRow] = {}
    for name in planners or IAMP_PLANNERS:
        def run(p: str = name) -> Any:
            return _episode(p)

        first = 0.0
        for _ in range(WARMUP):  # timed here: measure() does not report its warm-up calls
            t0 = time.perf_counter()
            run()
            first = time.perf_counter() - t0
        st, last = measure(run, repeats=repeats, warmup=0)
        assert last is not None  # measure calls run at least once
        s = last.summary
        episode = st.to_dict()
        episode["warmup"] = WARMUP  # the untimed episodes run here, before measure()
        rows[name] = {"episode": episode, "first_episode_s": first,
                      "wall_s": {k: float(v) for k, v in dict(s["wall_s"]).items()},
                      "planner_calls": int(s["planner_calls"]), "success": bool(s["success"]),
                      "contacts": int(s["contacts"]), "limit_violations": int(s["limit_violations"])}
    return {"case": CASE.copy(), "repeats": repeats, "warmup": WARMUP, "planners": rows,
            "episode_s": {k: float(r["episode"]["median"]) for k, r in rows.items()},
            "target_episode_s": TARGET_EPISODE_S}
