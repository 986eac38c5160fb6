r"""Campaigns: every (mission, planner, traffic, seed) episode on Dask distributed, resumable.

* Episodes run as tasks on a ``distributed`` cluster: a :class:`distributed.LocalCluster`
  of ``workers`` processes with one thread each (``libsumo`` runs one simulation per
  process) by default, or an existing scheduler at ``scheduler`` (``tcp://host:8786``).
  Tasks are submitted **seed by seed** (every mission, planner and density of seed 1, then
  seed 2, ...), so an interrupted campaign holds complete paired seeds.
* **Seeds are paired**: seed ``S`` gives the same traffic (SUMO's ``--seed`` and the initial
  platoon) to every planner, so planners can be compared episode by episode.
* **The manifest** (``manifest.json``) records every parameter that defines an episode
  (duration, period, deadline, warm-up, settle time, cooperation, sublane, the episode
  format) and the grid (missions, planners, densities, seeds).  A resumed campaign whose
  episode parameters differ refuses (:class:`ManifestMismatch`, exit 2, naming them) —
  unless ``force``, which discards the rows made with the old parameters.  The grid may
  grow (more seeds, planners, missions); the manifest records the union.
* Every finished episode is appended to ``episodes.csv`` at once, by an atomic rewrite
  (temporary file + rename), so an interrupt loses at most the episodes still running; a
  rerun skips every ``(mission, planner, traffic, seed)`` already in the file.  A failed
  episode goes to ``errors.csv`` instead and is retried by the next run.
* Rates are reported with Wilson score intervals (95 %, ``z = 1.96``): for ``k`` of ``n``,

  .. math::  \frac{\hat p + z^2/2n}{1 + z^2/n} \pm \frac{z}{1 + z^2/n}
             \sqrt{\frac{\hat p(1-\hat p)}{n} + \frac{z^2}{4n^2}}, \qquad \hat p = k/n ;

  paired differences between planners are in :mod:`iamp.simulation.stats`.
"""

from __future__ import annotations

import contextlib
import csv
import importlib
import io
import json
import logging
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from iamp.core.atomic import write_text
from iamp.core.errors import IampError, MissingDependencyError
from iamp.simulation.network import INSTALL_HINT
from iamp.simulation.stats import campaign_report, wilson  # noqa: F401 - wilson re-exported

COLUMNS = ("mission", "planner", "traffic", "seed", "cooperation", "sublane", "duration_s", "period_s",
           "simulated_s", "distance_to_end_m", "success", "time_to_merge_s", "stopped_at_end", "contacts",
           "contacts_at_fault", "contacts_not_at_fault", "rss_dangerous_s", "rss_dangerous_lateral_s",
           "rss_dangerous_longitudinal_s", "rss_dangerous_both_s", "follower_emergency_brakes",
           "axis_aligned_contacts", "sumo_only_contacts", "monitor_only_contacts", "contact_disagreements",
           "overlap_contacts", "sumo_contacts", "mingap_violations", "min_ttc_s", "ttc_below_1_5_s",
           "new_follower", "follower_max_decel", "ego_peak_accel", "ego_ax_min", "ego_ax_max", "ego_ay_peak",
           "ego_jerk_peak", "limit_violations", "jerk_violations", "curvature_max", "curvature_violations", "ego_lost",
           "lane_change_done_s", "lane_changes",
           "intrusion_s", "min_gap_m", "min_follower_accel", "rms_accel_x", "rms_accel_y", "rms_jerk_x",
           "rms_jerk_y", "plan_time_p50_s", "plan_time_p95_s", "plan_time_max_s", "plans", "planner_calls",
           "executed_plans", "constrained_plans", "infeasible_plans", "rejected", "late_plans", "fallbacks",
           "aborts", "deadline_s", "wall_total_s", "wall_sumo_s", "wall_prediction_s", "wall_planning_s",
           "max_rss_mb", "ego_in_forecast", "ego_iterations", "ego_converged", "ego_replans")
Key = tuple[str, str, str, int]
#: Version of the episode definition (missions, decision layer, metrics); part of the manifest.
#: 17.1: contacts by oriented bodies, the RSS judge's columns (SPEC §17).
#: 17.2: courteous target-lane followers open a gap for the signalling ego (the manifest's ``courtesy``).
#: 17.3: the tactical layer's lane end as a braking bound, end speeds searched within the gap, courteous
#: followers asked within their RSS distance behind the ego plus 60.5 m (issue 30, the on-ramp).
#: 17.4: the initial traffic: the slow-leader truck departs before the ego (it was refused and
#: appeared behind it), initial vehicles SUMO refuses at t = 0 are removed (they appeared later
#: beside the ego), the loop follows every vehicle within its RSS distance (b0ecb32).
#: 17.5: the ego's (and the truck's) speed factor fixed at 1 (SUMO drew it from its default
#: ``speedDev`` 0.1: the ego began missions at up to 1.43 times the speed limit); the target gap
#: chosen beyond ``reach_m`` when none is within it (beside a single car the ego drove level
#: with it to its lane's end); a plan is driven only if its path turns no tighter than a car's
#: turning radius and does not start sideways, and the tactical layer steers within it
#: (plans at a crawl turned on radii down to 0.4 m, the ego slid sideways at a standstill); the
#: columns ``curvature_max`` and ``curvature_violations``.
#: 17.6: a plan's path also ends on its last velocity's heading and leaves the ego standing at most
#: :data:`~iamp.simulation.kinematics.STOP_HEADING_MAX` to the road (plans that stopped the ego at
#: up to 50° to its lane, then straightened in place), and the lane keeping brakes along the heading
#: where RSS's lateral response cuts a lateral speed faster than a car turns.
#: 17.7: the lane keeping's lateral acceleration toward a vehicle beside the ego that is not
#: longitudinally safe for a response time (within a lane width) and changes lanes toward it is at
#: most 0.75 of RSS's ``a_lat,max`` once its speed toward it exceeds the rest share
#: (``Controller._lateral_caps``).
#: 17.8: past the aim point of a target gap open ahead (a follower, no leader) the gap term asks
#: no drop back and no slowing to the follower's speed (``tactical.seek_accel``).
#: 17.9: the lane keeping's lateral caps measure the gaps between the bodies at their headings, as
#: the judge does (the ego stopped turned toward the next lane reaches 2 m into it, not 0.9 m), and
#: allow no motion toward a car not longitudinally safe that is already nearer than RSS's lateral
#: distance (``Controller._lateral_caps``).
#: 17.10: RSS's longitudinal proper response as the rear car, as the judge measures the situation
#: (``Controller._front_danger``): a plan that does not brake with ``brake_min`` while a vehicle ahead
#: is closer than RSS's distance and laterally unsafe is left (withdrawn in the origin lane, else the
#: fail-safe), no lane change starts then and the following brakes; the tactical layer's turn bound
#: taken at the least speed the kept ``v_x`` allows (``Controller._turn_bound``).
#: 17.11: the lateral caps and the front danger measure each neighbour's observed state as the judge
#: does (its logged speed times ``cos ψ`` and heading, not the prediction's cubic at 0); a plan into a
#: gap with a follower and no leader ends at least at the ego's roll, ``min(v, roll_speed)``
#: (``tactical.gap_end``: not at a stopped follower's standstill).
#: 17.12: a vehicle behind that comes into the ego's lane by its own lateral motion (a cut-in behind)
#: keeps the RSS distance itself, as the rear of a pair that already shared the lane does
#: (``failsafe.feasible_brakes``; the ego not moving toward it sideways).
#: 17.13: the fail-safe brakes only where RSS asks it or the state one period ahead without braking
#: would have no verified fail-safe (``Controller._abort_now``), and ends (the ego seeks again, or is
#: done in the target lane) after its first period without braking, or once the ego's body (plus
#: ``margin_y``) is inside its lane's band as a withdrawn change's is (``Controller._in_lane``), or at a
#: standstill.
#: 17.14: a change committed with an open end (no follower or no leader) takes the target lane's
#: vehicle that bounds the gap there at a re-plan, by name (``Controller._committed_gap``): a slower
#: car ahead or a faster one behind that comes near during the change.
#: 17.15: a plan's end speed is at least the speed at which its lane change's last turn stays within a
#: car's turning radius where that speed is reachable (``tactical.turn_end_speed``): a plan into a
#: crawling gap no longer ends at the gap's speed while it still turns.
#: 17.16: a plan into an empty target lane (a gap with neither follower nor leader) ends at the reachable
#: speed nearest the road's speed limit (``Gap.speed``, ``Controller._with_lane_speed``), not at the
#: ego's own speed.
EPISODE_FORMAT = "17.16"
#: Manifest keys that define an episode: a resumed campaign must match them.
EPISODE_KEYS = ("episode_format", "duration_s", "period_s", "deadline_s", "warmup_s", "settle_s", "cooperation",
                "sublane", "ego_in_forecast", "rss", "courtesy")


class ManifestMismatch(IampError):
    """A resumed campaign's episode parameters differ from its manifest's."""


def flatten(summary: dict[str, Any]) -> dict[str, Any]:
    """One ``episodes.csv`` row from a SPEC §11 summary (nested keys flattened)."""
    row = {k: summary.get(k) for k in COLUMNS if k in summary}
    row["ego_ax_min"], row["ego_ax_max"] = summary["ego_ax_range"]
    row["rejected"] = ";".join(f"{k}={v}" for k, v in summary.get("rejected", {}).items())
    for kind, secs in summary.get("rss_dangerous_by_response_s", {}).items():
        row[f"rss_dangerous_{kind}_s"] = secs
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
    return (str(row.get("mission") or "discretionary"), str(row["planner"]), str(row["traffic"]), int(row["seed"]))


def manifest_of(missions: Iterable[str], planners: Iterable[str], traffics: Iterable[str], seeds: int,
                episode: dict[str, Any]) -> dict[str, Any]:
    """The manifest: the episode parameters (with the RSS judge's, SPEC §17) and the grid."""
    from dataclasses import asdict

    from iamp.simulation.missions import courtesy_of
    from iamp.simulation.rss import DEFAULT

    courtesy = courtesy_of(str(episode.get("cooperation", "default")))
    episode = {"rss": DEFAULT.as_dict(), "courtesy": None if courtesy is None else asdict(courtesy), **episode}
    return {"episode_format": EPISODE_FORMAT, **{k: episode[k] for k in EPISODE_KEYS if k in episode},
            "missions": list(missions), "planners": list(planners), "traffic": list(traffics), "seeds": int(seeds)}


def check_manifest(out: Path, wanted: dict[str, Any], force: bool) -> dict[str, Any]:
    """Compare ``wanted`` with ``out/manifest.json``; return the manifest to write.

    Raises :class:`ManifestMismatch` naming the differing episode parameters unless ``force``
    (then the old rows are discarded).
    """
    path = out / "manifest.json"
    if not path.is_file():
        if (out / "episodes.csv").is_file() and read_rows(out / "episodes.csv") and not force:
            raise ManifestMismatch(f"{out / 'episodes.csv'}: episodes without a manifest (made by an older "
                                   "iamp); use --force to discard them")
        if force:
            (out / "episodes.csv").unlink(missing_ok=True)
        return wanted
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ManifestMismatch(f"{path}: unreadable manifest ({exc}); use --force to start again") from None
    off = {"ego_in_forecast": False}  # manifests from before the option: it was off
    old, wanted = {**off, **old}, {**off, **wanted}
    diff = [k for k in EPISODE_KEYS if old.get(k) != wanted.get(k)]
    if diff:
        if not force and old.get("episode_format") != wanted.get("episode_format"):
            raise ManifestMismatch(f"{path}: the campaign was made by another iamp (episode format "
                                   f"{old.get('episode_format')!r}, now {wanted.get('episode_format')!r}: "
                                   f"{', '.join(k for k in diff if k != 'episode_format') or 'the same parameters'}"
                                   " differ or are new); its episodes are not comparable with new ones - use "
                                   "another --out, or --force to discard them (--no-run still summarises them)")
        if not force:
            said = ", ".join(f"{k} (was {old.get(k)!r}, now {wanted.get(k)!r})" for k in diff)
            raise ManifestMismatch(f"{path}: the campaign was made with other parameters: {said}; "
                                   "use the same ones to resume, or --force to discard its episodes")
        (out / "episodes.csv").unlink(missing_ok=True)
        (out / "errors.csv").unlink(missing_ok=True)
        return wanted
    merged = dict(wanted)
    for k in ("missions", "planners", "traffic"):
        merged[k] = list(dict.fromkeys([*old.get(k, []), *wanted[k]]))
    merged["seeds"] = max(int(old.get("seeds", 0)), int(wanted["seeds"]))
    return merged


def _append(path: Path, columns: tuple[str, ...], row: dict[str, Any]) -> None:
    """Rewrite ``path`` atomically with ``row`` appended.

    A file written with the same columns keeps its bytes and gains one line.  A file from an
    older iamp with other columns (a resumed campaign) is rewritten under ``columns`` followed by
    its own columns that ``columns`` lacks: every old value stays under its name, a column the
    old rows did not have is empty there (never a row longer than its header).
    """
    old = path.read_text(encoding="utf-8") if path.is_file() else ""
    header = next(csv.reader(io.StringIO(old)), None) if old else None
    clean = {k: ("" if v is None else v) for k, v in row.items()}
    buf = io.StringIO()
    if header == list(columns):
        csv.DictWriter(buf, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n").writerow(clean)
        write_text(path, old + buf.getvalue())
        return
    fields = list(columns) + [c for c in (header or []) if c not in columns]
    w = csv.DictWriter(buf, fieldnames=fields, extrasaction="ignore", restval="", lineterminator="\n")
    w.writeheader()
    if header is not None:
        w.writerows(csv.DictReader(io.StringIO(old)))
    w.writerow(clean)
    write_text(path, buf.getvalue())


def sort_episodes(path: Path, missions: Iterable[str], planners: Iterable[str], traffics: Iterable[str]) -> None:
    """Rewrite ``path`` (``episodes.csv``) atomically with its rows in the grid's order: seed, then
    mission, traffic and planner in the order given (values outside them last, by name).

    Episodes are appended as they finish, which depends on the workers; sorting once the
    campaign has finished makes the file the same for the same command on any machine.  The rows
    are rewritten as read (the same strings under the same header), so a file already in order
    keeps its bytes.

    Parameters
    ----------
    path : pathlib.Path
        The campaign's ``episodes.csv`` (nothing happens when it does not exist).
    missions, planners, traffics : iterable of str
        The grid's order.
    """
    if not path.is_file():
        return
    old = path.read_text(encoding="utf-8")
    header = next(csv.reader(io.StringIO(old)), None)
    if header is None:
        return
    order = [list(missions), list(planners), list(traffics)]

    def rank(row: dict[str, str]) -> tuple[Any, ...]:
        m, p, t, s = _key(row)
        pos = [o.index(v) if v in o else len(o) for o, v in zip(order, (m, p, t))]
        return (s, pos[0], m, pos[2], t, pos[1], p)

    rows = sorted(csv.DictReader(io.StringIO(old)), key=rank)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=header, restval="", lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    if buf.getvalue() != old:
        write_text(path, buf.getvalue())


@contextlib.contextmanager
def _quiet_dask(quiet: bool) -> Iterator[None]:
    """While an interrupted campaign shuts its cluster down, Dask's own loggers and warnings
    (workers killed mid-task, streams closed, ...) stay silent: the user sees only iamp's
    line ``iamp: interrupted`` (issue 22 item 16)."""
    if not quiet:
        yield
        return
    roots = ("distributed", "dask", "tornado", "asyncio")
    # every existing logger below them too: Dask's logging configuration gives child loggers
    # (distributed.client, ...) levels of their own, which a parent's level does not override
    names = sorted({*roots, *(n for n in logging.root.manager.loggerDict if n.split(".")[0] in roots)})
    loggers = [logging.getLogger(n) for n in names]
    levels = [(lg.level, lg.disabled) for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
        lg.disabled = True
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                yield
            except Exception:  # a failing shutdown of an interrupted run is not the user's news
                pass
    finally:
        for lg, (level, disabled) in zip(loggers, levels):
            lg.setLevel(level)
            lg.disabled = disabled


def run_campaign(planners: Iterable[str], traffics: Iterable[str], seeds: int, out: str | Path, *,
                 missions: Iterable[str] = ("merge",), workers: int = 2, scheduler: str | None = None,
                 duration_s: float = 60.0, period_s: float = 0.1, deadline: bool = False,
                 cooperation: str = "default", sublane: bool = False, warmup_s: float = 5.0, settle_s: float = 8.0,
                 ego_in_forecast: bool = False, force: bool = False,
                 progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Run the missing episodes of the campaign; returns ``{"ran", "skipped", "failed", "seconds"}``.

    Raises :class:`ManifestMismatch` when ``out`` holds a campaign made with other episode
    parameters (unless ``force``).
    """
    planners, traffics, missions = list(planners), list(traffics), list(missions)
    try:
        dist: Any = importlib.import_module("distributed")
    except ImportError:
        raise MissingDependencyError(f"campaigns need Dask distributed: {INSTALL_HINT}") from None
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    episode = {"duration_s": float(duration_s), "period_s": float(period_s),
               "deadline_s": float(period_s) if deadline else None, "warmup_s": float(warmup_s),
               "settle_s": float(settle_s), "cooperation": cooperation, "sublane": bool(sublane),
               "ego_in_forecast": bool(ego_in_forecast)}
    manifest = check_manifest(out, manifest_of(missions, planners, traffics, seeds, episode), force)
    write_text(out / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    episodes, errors = out / "episodes.csv", out / "errors.csv"
    done = {_key(r) for r in read_rows(episodes)}
    todo = [(m, p, t, s) for s in range(1, int(seeds) + 1) for m in missions for t in traffics for p in planners
            if (m, p, t, s) not in done]
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
        # dashboard_address=None does not disable the dashboard (dask/distributed#8136): it binds :8787 and
        # warns "Port 8787 is already in use" beside another cluster; ":0" takes a free port silently
        # silence_logs CRITICAL: a worker's heartbeat racing the scheduler's shutdown after a complete
        # run logged "Failed to communicate with scheduler during heartbeat" with a traceback at ERROR
        # (2 workers, 4500 episodes); an episode's own failure reaches iamp through its future
        cluster = dist.LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                                    dashboard_address=":0", memory_limit="2GiB", silence_logs=logging.CRITICAL)
        client = dist.Client(cluster)
    interrupted = False
    try:
        futures = {client.submit(run_one, {"planner": p, "traffic": t, "seed": s, "mission": m,
                                           "duration_s": duration_s, "period_s": period_s,
                                           "deadline_s": episode["deadline_s"], "cooperation": cooperation,
                                           "sublane": sublane, "warmup_s": warmup_s, "settle_s": settle_s,
                                           "ego_in_forecast": bool(ego_in_forecast)},
                                 pure=False): (m, p, t, s)
                   for m, p, t, s in todo}
        n_done = skipped
        for fut in dist.as_completed(futures):
            m, p, t, s = futures[fut]
            try:
                _append(episodes, COLUMNS, fut.result())
            except Exception as exc:  # an episode's failure is recorded, not fatal
                failed += 1
                _append(errors, ("mission", "planner", "traffic", "seed", "error"),
                        {"mission": m, "planner": p, "traffic": t, "seed": s, "error": repr(exc)[:300]})
            n_done += 1
            if progress:
                progress(n_done, total)
        sort_episodes(episodes, missions, planners, traffics)
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
# tables
# ---------------------------------------------------------------------------------------

def summarise(rows: list[dict[str, str]], planners: Iterable[str] | None = None) -> list[dict[str, Any]]:
    """Per (mission, traffic, planner): rates with Wilson intervals and medians
    (:func:`iamp.simulation.stats.cell_summary`)."""
    names = list(planners) if planners is not None else list(dict.fromkeys(r["planner"] for r in rows))
    return list(campaign_report(rows, names)["cells"])


def _pct(k: int | None, n: int, ci: tuple[float, float] | None) -> str:
    if k is None or ci is None:
        return "--"  # not measured (a campaign made before the column existed)
    return f"{k}/{n} [{100 * ci[0]:.0f}, {100 * ci[1]:.0f}]"


def _num(v: float | None, fmt: str, scale: float = 1.0) -> str:
    return "--" if v is None else format(scale * v, fmt)


def latex_table(cells: list[dict[str, Any]]) -> str:
    """A booktabs table per cell: success and contacts (k/n, Wilson 95 % in %), contacts the ego was
    responsible for and the followers' emergency brakes because of the ego (RSS, SPEC §17), hard
    brakes of the new follower, medians of the RSS-dangerous time, time to merge, follower
    deceleration, executed peak, plan time."""
    lines = [r"\begin{tabular}{lllrllllllrrrrrr}", r"\toprule",
             r"mission & traffic & planner & $n$ & success & contact & at fault & emergency brake & hard brake & "
             r"limits & RSS danger [s] & $t_{merge}$ [s] & "
             r"$d_{f}$ [m/s$^2$] & $|a|_{max}$ [m/s$^2$] & constrained & plan $p_{50}$ [ms] \\", r"\midrule"]
    for c in cells:
        n = c["episodes"]
        lines.append(
            f"{c['mission']} & {c['traffic']} & {c['planner']} & {n} & "
            f"{_pct(c['success_episodes'], n, c['success_ci'])} & {_pct(c['contact_episodes'], n, c['contact_ci'])} & "
            f"{_pct(c.get('contact_at_fault_episodes'), n, c.get('contact_at_fault_ci'))} & "
            f"{_pct(c.get('emergency_brake_episodes'), n, c.get('emergency_brake_ci'))} & "
            f"{_pct(c['hard_brake_episodes'], n, c['hard_brake_ci'])} & "
            f"{_pct(c['limit_violation_episodes'], n, c['limit_violation_ci'])} & "
            f"{_num(c.get('rss_dangerous_s_median'), '.1f')} & "
            f"{_num(c['time_to_merge_s_median'], '.1f')} & {_num(c['follower_max_decel_median'], '.1f')} & "
            f"{_num(c['ego_peak_accel_median'], '.1f')} & {c['constrained_plans']}/{c['executed_plans']} & "
            f"{_num(c['plan_time_p50_s_median'], '.2f', 1e3)} \\\\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines).replace("_", r"\_").replace(r"$t\_{merge}$", r"$t_{merge}$") \
        .replace(r"$d\_{f}$", r"$d_{f}$").replace(r"$p\_{50}$", r"$p_{50}$").replace(r"$|a|\_{max}$", r"$|a|_{max}$") \
        + "\n"


def paired_table(comparisons: list[dict[str, Any]]) -> str:
    """Paired differences (other − reference) over all densities of a mission: rates with the
    McNemar p-value, means with the paired-bootstrap 95 % interval."""
    def rate(d: dict[str, Any] | None) -> str:
        if d is None:
            return "--"  # not measured in these episodes
        return f"{100 * d['diff']:+.0f} [{100 * d['ci'][0]:+.0f}, {100 * d['ci'][1]:+.0f}] p={d['p']:.2g}"

    def cont(d: dict[str, Any], scale: float = 1.0, fmt: str = "+.2f") -> str:
        if d["diff"] is None:
            return "--"
        lo, hi = (format(scale * v, fmt) for v in d["ci"])
        return f"{format(scale * d['diff'], fmt)} [{lo}, {hi}]"

    lines = [r"\begin{tabular}{lllrllllllll}", r"\toprule",
             r"mission & planner & vs & pairs & success [pp] & contact [pp] & at fault [pp] & emergency brake [pp] & "
             r"hard brake [pp] & "
             r"$\Delta d_f$ [m/s$^2$] & $\Delta t_{merge}$ [s] & $\Delta |a|_{max}$ [m/s$^2$] \\", r"\midrule"]
    for c in comparisons:
        if c["traffic"] != "all":
            continue
        lines.append(f"{c['mission']} & {c['planner']} & {c['reference']} & {c['pairs']} & {rate(c['success'])} & "
                     f"{rate(c['contact'])} & {rate(c.get('contact_at_fault'))} & {rate(c.get('emergency_brake'))} & "
                     f"{rate(c['hard_brake'])} & {cont(c['follower_max_decel'])} & "
                     f"{cont(c['time_to_merge_s'])} & {cont(c['ego_peak_accel'])} \\\\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    text = "\n".join(lines).replace("_", r"\_")
    for a, b in ((r"$\Delta d\_f$", r"$\Delta d_f$"), (r"$\Delta t\_{merge}$", r"$\Delta t_{merge}$"),
                 (r"$\Delta |a|\_{max}$", r"$\Delta |a|_{max}$")):
        text = text.replace(a, b)
    return text + "\n"
