"""``iamp bench``'s closed-loop numbers (issue 20 item 5): whole SUMO episodes, one process.

The case: the ``merge`` mission, ``medium`` traffic, seed 1, 10 s of mission clock (the ego
seeks a gap the whole time: every 0.3 s three candidate problems, most rejected on ``a_x``).
Timed (medians of whole :func:`~iamp.simulation.episode.run_episode` calls, after one warm-up
that also loads numba's cached search): ``pmp`` with the PMP screen
(:func:`iamp.simulation.planning.screened`) and without it, ``qp``, ``free``.  The ratio
``loop_pmp_screen_to_pure`` compares the two ``pmp`` runs taken in this one process; the
episodes' numbers (summary minus wall/plan times, step log) are compared too
(``same_numbers``).  Needs ``iamp[sim]`` (SUMO); skipped otherwise.
"""

from __future__ import annotations

from typing import Any, TypedDict

from iamp.comparison.timing import StatsJSON, measure

__all__ = ["LoopBench", "LoopCase", "bench_loop"]


class LoopCase(TypedDict):
    """The episode timed: mission, traffic, seed, mission clock [s]."""

    mission: str
    traffic: str
    seed: int
    duration_s: float


class LoopBench(TypedDict):
    """:func:`bench_loop`: each run's statistics [s], their medians, the screen's ratio, whether the two
    ``pmp`` episodes agree and the planner calls of one episode."""

    case: LoopCase
    repeats: int
    pmp_screen: StatsJSON
    pmp_pure: StatsJSON
    qp: StatsJSON
    free: StatsJSON
    episode_s: dict[str, float]
    loop_pmp_screen_to_pure: float
    same_numbers: bool
    planner_calls: int


#: The episode timed (module docstring).
CASE: LoopCase = {"mission": "merge", "traffic": "medium", "seed": 1, "duration_s": 10.0}
_TIMES = ("plan_time_s", "wall_s", "max_rss_mb")


def _episode(planner: str, screen: bool) -> Any:
    from iamp.simulation.controller import ControllerConfig
    from iamp.simulation.episode import EpisodeSpec, run_episode

    spec = EpisodeSpec(planner=planner, mission=str(CASE["mission"]), traffic=str(CASE["traffic"]),
                       seed=int(CASE["seed"]), duration_s=float(CASE["duration_s"]))
    return run_episode(spec, config=ControllerConfig(screen=screen))


def _numbers(result: Any) -> tuple[Any, ...]:
    log = result.log
    return ({k: v for k, v in result.summary.items() if k not in _TIMES}, log.t, log.ego, log.mode, log.ids,
            [a.tolist() for a in log.nb])


def bench_loop(repeats: int = 3) -> LoopBench:
    """Medians of whole 10 s episodes (module docstring)."""
    stats: dict[str, StatsJSON] = {}
    runs: dict[str, Any] = {}
    for name, planner, screen in (("pmp_screen", "pmp", True), ("pmp_pure", "pmp", False), ("qp", "qp", True),
                                  ("free", "free", True)):
        def run(p: str = planner, s: bool = screen) -> Any:
            return _episode(p, s)

        st, last = measure(run, repeats=repeats, warmup=1)
        stats[name] = st.to_dict()
        runs[name] = last
    return {"case": CASE.copy(), "repeats": repeats, "pmp_screen": stats["pmp_screen"], "pmp_pure": stats["pmp_pure"],
            "qp": stats["qp"], "free": stats["free"],
            "episode_s": {k: stats[k]["median"] for k in ("pmp_screen", "pmp_pure", "qp", "free")},
            "loop_pmp_screen_to_pure": stats["pmp_screen"]["median"] / stats["pmp_pure"]["median"],
            "same_numbers": _numbers(runs["pmp_screen"]) == _numbers(runs["pmp_pure"]),
            "planner_calls": int(runs["pmp_pure"].summary["planner_calls"])}
