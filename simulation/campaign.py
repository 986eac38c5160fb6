r"""Campaigns: every (planner, traffic, seed) episode on Dask distributed, resumable.

* Episodes run as tasks on a ``distributed`` cluster: a :class:`distributed.LocalCluster`
  of ``workers`` processes with one thread each (``libsumo`` runs one simulation per
  process) by default, or an existing scheduler at ``scheduler`` (``tcp://host:8786``).
* Every finished episode is appended to ``episodes.csv`` at once, by an atomic rewrite
  (temporary file + rename), so an interrupt loses at most the episodes still running; a
  rerun skips every ``(planner, traffic, seed)`` already in the file.  A failed episode
  goes to ``errors.csv`` instead and is retried by the next run.
* Rates are reported with Wilson score intervals (95 %, ``z = 1.96``): for ``k`` of ``n``,

  .. math::  \frac{\hat p + z^2/2n}{1 + z^2/n} \pm \frac{z}{1 + z^2/n}
             \sqrt{\frac{\hat p(1-\hat p)}{n} + \frac{z^2}{4n^2}}, \qquad \hat p = k/n .
"""

from __future__ import annotations

import contextlib
import csv
import importlib
import io
import logging
import math
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from iamp.core.atomic import write_text
from iamp.core.errors import MissingDependencyError
from iamp.simulation.network import INSTALL_HINT

COLUMNS = ("planner", "traffic", "seed", "duration_s", "period_s", "lane_change_done_s", "lane_changes",
           "collisions", "sumo_collisions", "overlap_collisions", "intrusion_s", "min_gap_m", "min_ttc_s",
           "min_follower_accel", "rms_accel_x", "rms_accel_y", "rms_jerk_x", "rms_jerk_y", "plan_time_p50_s",
           "plan_time_p95_s", "plan_time_max_s", "plans", "constrained_plans", "failed_plans", "late_plans",
           "fallbacks", "aborts",
           "deadline_s", "wall_total_s", "wall_sumo_s", "wall_prediction_s", "wall_planning_s", "max_rss_mb")
Key = tuple[str, str, int]
#: A neighbour behind the ego braking harder than this [m/s²] (the "average" driver's
#: ``decel``; beyond it SUMO's drivers brake in emergency) marks a hard-brake episode.
HARD_BRAKE = -4.5


def flatten(summary: dict[str, Any]) -> dict[str, Any]:
    """One ``episodes.csv`` row from a SPEC §11 summary (nested keys flattened)."""
    row = {k: summary.get(k) for k in COLUMNS if k in summary}
    row["rms_accel_x"], row["rms_accel_y"] = summary["rms_accel"]
    row["rms_jerk_x"], row["rms_jerk_y"] = summary["rms_jerk"]
    for q in ("p50", "p95", "max"):
        row[f"plan_time_{q}_s"] = summary["plan_time_s"][q]
    for part in ("total", "sumo", "prediction", "planning"):
        row[f"wall_{part}_s"] = summary["wall_s"][part]
    return row


def run_one(spec: dict[str, Any]) -> dict[str, Any]:
    """Task body (runs in a worker): one episode -> one flat row."""
    from iamp.simulation.episode import EpisodeSpec, run_episode

    return flatten(run_episode(EpisodeSpec(**spec)).summary)


def read_rows(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        return []
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _key(row: dict[str, Any]) -> Key:
    return (str(row["planner"]), str(row["traffic"]), int(row["seed"]))


def _append(path: Path, columns: tuple[str, ...], row: dict[str, Any]) -> None:
    """Rewrite ``path`` atomically with ``row`` appended (header kept)."""
    old = path.read_text(encoding="utf-8") if path.is_file() else ""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n")
    if not old:
        w.writeheader()
    w.writerow({k: ("" if v is None else v) for k, v in row.items()})
    write_text(path, old + buf.getvalue())


@contextlib.contextmanager
def _quiet_dask(quiet: bool) -> Iterator[None]:
    """While an interrupted campaign shuts its cluster down, Dask's own loggers and warnings
    (workers killed mid-task, streams closed, ...) stay silent: the user sees only iamp's
    line ``iamp: interrupted`` (issue 22 item 16)."""
    if not quiet:
        yield
        return
    loggers = [logging.getLogger(n) for n in ("distributed", "dask", "tornado", "asyncio")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                yield
            except Exception:  # a failing shutdown of an interrupted run is not the user's news
                pass
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


def run_campaign(planners: Iterable[str], traffics: Iterable[str], seeds: int, out: str | Path, *,
                 workers: int = 2, scheduler: str | None = None, duration_s: float = 60.0,
                 period_s: float = 0.1, deadline: bool = True,
                 progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Run the missing episodes of the campaign; returns ``{"ran", "skipped", "failed", "seconds"}``."""
    try:
        dist: Any = importlib.import_module("distributed")
    except ImportError:
        raise MissingDependencyError(f"campaigns need Dask distributed: {INSTALL_HINT}") from None
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    episodes, errors = out / "episodes.csv", out / "errors.csv"
    done = {_key(r) for r in read_rows(episodes)}
    todo = [(p, t, s) for p in planners for t in traffics for s in range(1, int(seeds) + 1) if (p, t, s) not in done]
    total, skipped = len(todo) + len(done), len(done)
    if progress:
        progress(skipped, total)
    start, failed = time.perf_counter(), 0
    if not todo:
        return {"ran": 0, "skipped": skipped, "failed": 0, "seconds": 0.0}
    cluster = None
    if scheduler:
        client = dist.Client(scheduler)
    else:
        cluster = dist.LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                                    dashboard_address=None, memory_limit="2GiB", silence_logs=logging.ERROR)
        client = dist.Client(cluster)
    interrupted = False
    try:
        limit = period_s if deadline else None
        futures = {client.submit(run_one, {"planner": p, "traffic": t, "seed": s, "duration_s": duration_s,
                                           "period_s": period_s, "deadline_s": limit}, pure=False): (p, t, s)
                   for p, t, s in todo}
        n_done = skipped
        for fut in dist.as_completed(futures):
            p, t, s = futures[fut]
            try:
                _append(episodes, COLUMNS, fut.result())
            except Exception as exc:  # an episode's failure is recorded, not fatal
                failed += 1
                _append(errors, ("planner", "traffic", "seed", "error"),
                        {"planner": p, "traffic": t, "seed": s, "error": repr(exc)[:300]})
            n_done += 1
            if progress:
                progress(n_done, total)
    except BaseException:  # Ctrl-C, SIGTERM (as an exception under the CLI), a failure
        interrupted = True
        raise
    finally:
        with _quiet_dask(interrupted):
            client.close()
            if cluster is not None:
                cluster.close()
    return {"ran": len(todo) - failed, "skipped": skipped, "failed": failed, "seconds": time.perf_counter() - start}


# ---------------------------------------------------------------------------------------
# summary
# ---------------------------------------------------------------------------------------

def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of ``k`` successes in ``n`` trials."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z / den * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (max(0.0, centre - half), min(1.0, centre + half))


def _floats(rows: list[dict[str, str]], col: str) -> np.ndarray:
    return np.array([float(r[col]) for r in rows if r.get(col, "") not in ("", "None")])


def summarise(rows: list[dict[str, str]]) -> list[dict[str, Any]]:
    """Per (planner, traffic): rates with Wilson intervals and medians."""
    groups: dict[tuple[str, str], list[dict[str, str]]] = {}
    for r in rows:
        groups.setdefault((r["planner"], r["traffic"]), []).append(r)
    order = {"light": 0, "medium": 1, "dense": 2}
    out = []
    for (planner, traffic), rs in sorted(groups.items(), key=lambda kv: (kv[0][0], order.get(kv[0][1], 9))):
        n = len(rs)
        k_col = sum(int(r["collisions"]) > 0 for r in rs)
        k_int = sum(float(r["intrusion_s"]) > 0 for r in rs)
        k_lc = sum(r["lane_change_done_s"] not in ("", "None") for r in rs)
        k_brk = sum(r.get("min_follower_accel", "") not in ("", "None") and float(r["min_follower_accel"]) < HARD_BRAKE
                    for r in rs)
        p95 = _floats(rs, "plan_time_p95_s")
        gaps, ttc = _floats(rs, "min_gap_m"), _floats(rs, "min_ttc_s")
        out.append({
            "planner": planner, "traffic": traffic, "episodes": n,
            "collision_episodes": k_col, "collision_rate": k_col / n, "collision_ci": wilson(k_col, n),
            "intrusion_episodes": k_int, "intrusion_rate": k_int / n, "intrusion_ci": wilson(k_int, n),
            "hard_brake_episodes": k_brk, "hard_brake_rate": k_brk / n, "hard_brake_ci": wilson(k_brk, n),
            "lane_change_rate": k_lc / n, "lane_change_ci": wilson(k_lc, n),
            "lane_changes_mean": float(np.mean(_floats(rs, "lane_changes"))),
            "intrusion_s_mean": float(np.mean(_floats(rs, "intrusion_s"))),
            "min_gap_m_median": float(np.median(gaps)) if gaps.size else None,
            "min_ttc_s_median": float(np.median(ttc)) if ttc.size else None,
            "plan_time_p95_s_median": float(np.median(p95)) if p95.size else None,
            "plan_time_max_s": float(np.max(_floats(rs, "plan_time_max_s"))) if p95.size else None,
            "plans": int(_floats(rs, "plans").sum()), "constrained_plans": int(_floats(rs, "constrained_plans").sum()),
            "failed_plans": int(_floats(rs, "failed_plans").sum()), "fallbacks": int(_floats(rs, "fallbacks").sum()),
            "late_plans": int(_floats(rs, "late_plans").sum()), "aborts": int(_floats(rs, "aborts").sum()),
            "wall_s_median": float(np.median(_floats(rs, "wall_total_s"))),
            "max_rss_mb": float(np.max(_floats(rs, "max_rss_mb"))),
        })
    return out


def latex_table(summary: list[dict[str, Any]]) -> str:
    """A booktabs table: rates in % with Wilson 95 % intervals, medians."""

    def pct(rate: float, ci: tuple[float, float]) -> str:
        return f"{100 * rate:.0f} [{100 * ci[0]:.0f}, {100 * ci[1]:.0f}]"

    def num(v: float | None, fmt: str) -> str:
        return "--" if v is None else format(v, fmt)

    lines = [r"\begin{tabular}{llrllllrrr}", r"\toprule",
             r"planner & traffic & $n$ & collisions [\%] & intrusion [\%] & hard brake [\%] & lane change [\%] & "
             r"min gap [m] & plan $p_{95}$ [ms] & fallbacks \\", r"\midrule"]
    for s in summary:
        p95 = s["plan_time_p95_s_median"]
        lines.append(f"{s['planner']} & {s['traffic']} & {s['episodes']} & "
                     f"{pct(s['collision_rate'], s['collision_ci'])} & {pct(s['intrusion_rate'], s['intrusion_ci'])} & "
                     f"{pct(s['hard_brake_rate'], s['hard_brake_ci'])} & "
                     f"{pct(s['lane_change_rate'], s['lane_change_ci'])} & {num(s['min_gap_m_median'], '.1f')} & "
                     f"{num(None if p95 is None else 1e3 * p95, '.2f')} & {s['fallbacks']} \\\\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines).replace("_", r"\_").replace(r"$p\_{95}$", r"$p_{95}$") + "\n"
