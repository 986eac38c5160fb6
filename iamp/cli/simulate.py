"""``iamp simulate`` (one closed-loop episode in SUMO) and ``iamp campaign`` (many, on Dask).

Both need the optional extra ``pip install 'iamp[sim]'``; without it they exit with status 2
and one line saying so.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from iamp.cli.types import EXIT_MISSION_FAILED, EXIT_OK, float_in, int_in
from iamp.simulation.planning import PLANNERS

TRAFFIC = ("light", "medium", "dense", "los-e")
MISSIONS = ("merge", "onramp", "slow-leader", "discretionary")
COOPERATION = ("low", "default", "high")


def _csv_choice(choices: tuple[str, ...]):  # type: ignore[no-untyped-def]
    def parse(text: str) -> list[str]:
        items = [s.strip() for s in text.split(",") if s.strip()]
        bad = [s for s in items if s not in choices]
        if bad or not items:
            raise argparse.ArgumentTypeError(f"expected a comma-separated list of {', '.join(choices)} "
                                             f"(got {text!r})")
        return items

    return parse


FIGURE_FORMATS = ("png", "pdf", "svg")


def check_destinations(args: argparse.Namespace) -> None:
    """Check ``--log`` and ``--figure`` before the episode (issue 22 item 2).

    Each must be a writable file path that does not exist (or ``--force``), the figure must
    end in a known format, and the two must differ (``--log x --figure x`` would lose the log).
    """
    from iamp.core.errors import ScenarioError
    from iamp.core.outputs import _same, check_output

    force = bool(getattr(args, "force", False))
    if args.log and args.figure and _same(Path(args.log), Path(args.figure)):
        raise ScenarioError("is also the --log file; writing the figure would replace the log - choose another "
                            "path", "--figure", str(args.figure))
    if args.figure:
        suffix = Path(args.figure).suffix.lstrip(".").lower()
        if suffix not in FIGURE_FORMATS:
            raise ScenarioError(f"must end in {', '.join('.' + f for f in FIGURE_FORMATS)} "
                                f"(got {Path(args.figure).name!r})", "--figure", str(args.figure))
        check_output(args.figure, (), force, option="--figure")
    if args.log:
        check_output(args.log, (), force, option="--log")



def _summary_lines_11(s: dict[str, Any]) -> list[str]:
    """The SPEC §11 summary (an episode without a mission)."""
    from iamp.cli.text import quantity

    pt = s["plan_time_s"]
    done = s["lane_change_done_s"]
    lines = [f"episode   {s['planner']}, {s['traffic']} traffic, seed {s['seed']}, {s['duration_s']:g} s at "
             f"{s['period_s']:g} s",
             f"lane      {s['lane_changes']} lane changes; "
             + ("none completed" if done is None else f"first completed at {done:.1f} s"),
             f"safety    {s['collisions']} collisions (SUMO {s['sumo_collisions']}, body overlap "
             f"{s['overlap_collisions']}); intrusion {s['intrusion_s']:.1f} s; min gap "
             f"{quantity(s['min_gap_m'], 'm', missing='n/a (no vehicle in the lane of the ego)')}; min TTC "
             f"{quantity(s['min_ttc_s'], 's', missing='n/a (no vehicle closing in)')}",
             f"comfort   rms accel {s['rms_accel'][0]:.2f}, {s['rms_accel'][1]:.2f} m/s²; rms jerk "
             f"{s['rms_jerk'][0]:.2f}, {s['rms_jerk'][1]:.2f} m/s³"]
    if s["plans"]:
        ms = [quantity(None if pt[k] is None else pt[k] * 1e3, "ms") for k in ("p50", "p95", "max")]
        lines.append(f"plans     {s['plans']} ({s['constrained_plans']} with a constraint; failed "
                     f"{s['failed_plans']}, late {s['late_plans']}, fallbacks {s['fallbacks']}, aborts "
                     f"{s['aborts']}); time p50 {ms[0]}, p95 {ms[1]}, max {ms[2]}")
    w = s["wall_s"]
    lines.append(f"wall      {w['total']:.1f} s (SUMO {w['sumo']:.1f}, prediction {w['prediction']:.1f}, "
                 f"planning {w['planning']:.1f}); peak memory {s['max_rss_mb']:.0f} MB")
    return lines


def _responsibility_lines(s: dict[str, Any]) -> list[str]:
    """The SPEC §17 lines: RSS blame, SUMO's disagreements, the followers' emergency brakes."""
    if "contacts_at_fault" not in s:
        return []
    by = s.get("rss_dangerous_by_response_s", {})
    lines = [f"RSS       {s['contacts_at_fault']} contacts at fault, {s['contacts_not_at_fault']} not; "
             f"{s['rss_dangerous_s']:.1f} s dangerous by the ego (began sideways {by.get('lateral', 0.0):.1f} s, "
             f"longitudinally {by.get('longitudinal', 0.0):.1f} s, both {by.get('both', 0.0):.1f} s); "
             f"{s['follower_emergency_brakes']} emergency brakes (>= 8 m/s²) of a vehicle behind the ego"]
    for c in s.get("sumo_only", []) + s.get("monitor_only", []):
        who = "SUMO only" if c in s.get("sumo_only", []) else "bodies only"
        lines.append(f"          contact with {c['vehicle']} at {c['t']:.1f} s reported by {who}: {c['reason']}")
    return lines


def summary_lines(s: dict[str, Any]) -> list[str]:
    """The text summary of an episode (``iamp simulate`` without ``--json``): rounded numbers,
    ``n/a`` with its reason where a metric has no value, no ``None``."""
    if "mission" not in s:
        return _summary_lines_11(s)
    from iamp.cli.text import quantity

    pt = s["plan_time_s"]
    merged = s["time_to_merge_s"]
    fd = s["follower_max_decel"]
    lo, hi = s["ego_ax_range"]
    lines = [f"episode   {s['mission']}: {s['planner']}, {s['traffic']} traffic ({s['cooperation']} cooperation), "
             f"seed {s['seed']}, {s['simulated_s']:g} of {s['duration_s']:g} s at {s['period_s']:g} s",
             f"mission   {'success' if s['success'] else 'FAILED'}; in the target lane "
             + ("never" if merged is None else f"at {merged:.1f} s")
             + ("; stopped at the lane's end" if s["stopped_at_end"] else ""),
             f"safety    {s['contacts']} contacts (body overlap {s['overlap_contacts']}, SUMO {s['sumo_contacts']}); "
             f"{s['mingap_violations']} minGap violations; min TTC "
             f"{quantity(s['min_ttc_s'], 's', missing='n/a (no vehicle closing in)')} "
             f"({s['ttc_below_1_5_s']:.1f} s below 1.5 s); new follower braked "
             f"{quantity(fd, 'm/s²', missing='n/a (no new follower)')}",
             *_responsibility_lines(s),
             f"executed  peak |a| {s['ego_peak_accel']:.2f} m/s² (a_x {lo:.2f}..{hi:.2f}, "
             f"|a_y| {s['ego_ay_peak']:.2f}); "
             f"{s['limit_violations']} steps beyond the passenger car's limits",
             f"comfort   rms accel {s['rms_accel'][0]:.2f}, {s['rms_accel'][1]:.2f} m/s²; rms jerk "
             f"{s['rms_jerk'][0]:.2f}, {s['rms_jerk'][1]:.2f} m/s³"]
    if s["plans"]:
        ms = [quantity(None if pt[k] is None else pt[k] * 1e3, "ms", missing="n/a (no planner call)")
              for k in ("p50", "p95", "max")]
        lines.append(f"plans     {s['plans']} ({s['planner_calls']} planner calls, "
                     f"{s['infeasible_plans']} not verified; "
                     f"{s['executed_plans']} periods executed, {s['constrained_plans']} with an imposed constraint; "
                     f"fallbacks {s['fallbacks']}, aborts {s['aborts']}); time p50 {ms[0]}, p95 {ms[1]}, max {ms[2]}")
    w = s["wall_s"]
    lines.append(f"wall      {w['total']:.1f} s (SUMO {w['sumo']:.1f}, prediction {w['prediction']:.1f}, "
                 f"planning {w['planning']:.1f}); peak memory {s['max_rss_mb']:.0f} MB")
    return lines


#: ``simulate`` options of the highway episode and their defaults (``None`` in the parser, so that
#: an option given with ``--commonroad``, where it has no meaning, can be refused by name).
HIGHWAY_DEFAULTS: dict[str, object] = {"mission": "merge", "traffic": "medium", "planner": "pmp",
                                       "cooperation": "default", "duration": 60.0, "period": 0.1}
#: Flags of the highway episode (off by default).
HIGHWAY_FLAGS = ("sublane", "deadline", "ego_in_forecast")
#: Options of ``--commonroad`` only, and their defaults.
COMMONROAD_DEFAULTS: dict[str, object] = {"road_planner": "avoid", "recording": None, "routes": "repaired"}


def check_simulate_options(args: argparse.Namespace) -> None:
    """Refuse an option that does not apply to the kind of episode asked for (issue 29 item 11),
    then fill in the defaults.

    With ``--commonroad`` the scenario folder sets the traffic, the mission, the period and the
    length, and the planner is ``--road-planner``: ``--mission``, ``--traffic``, ``--planner``,
    ``--cooperation``, ``--duration``, ``--period``, ``--sublane``, ``--deadline``,
    ``--ego-in-forecast`` and ``--figure`` are refused; ``--seed`` (SUMO's seed), ``--log``,
    ``--force`` and ``--json`` apply.  Without it, ``--road-planner`` and ``--recording`` are
    refused.

    Raises
    ------
    iamp.ScenarioError
        Naming the first such option.
    """
    from iamp.core.errors import ScenarioError

    def flag(dest: str) -> str:
        return "--" + dest.replace("_", "-")

    if getattr(args, "commonroad", None):
        for dest in (*HIGHWAY_DEFAULTS, *HIGHWAY_FLAGS):
            if getattr(args, dest, None) not in (None, False):
                raise ScenarioError("does not apply with --commonroad (the scenario folder sets the traffic, the "
                                    "mission, the period and the length; its planner is --road-planner)", flag(dest))
        if getattr(args, "figure", None):
            raise ScenarioError("is not drawn for a --commonroad episode (the figure shows the highway missions); "
                                "use --log for the executed steps", "--figure")
        for dest, default in COMMONROAD_DEFAULTS.items():
            if getattr(args, dest, None) is None:
                setattr(args, dest, default)
        return
    for dest in COMMONROAD_DEFAULTS:
        if getattr(args, dest, None) is not None:
            raise ScenarioError("applies only with --commonroad FOLDER", flag(dest))
    for dest, value in HIGHWAY_DEFAULTS.items():
        if getattr(args, dest, None) is None:
            setattr(args, dest, value)


def cmd_simulate(args: argparse.Namespace) -> int:
    check_simulate_options(args)
    if getattr(args, "commonroad", None):
        return _simulate_commonroad(args)
    from iamp.simulation.episode import EpisodeSpec, run_episode, write_log

    check_destinations(args)  # before SUMO starts: a refusal costs a second, not an episode

    spec = EpisodeSpec(traffic=args.traffic, seed=args.seed, planner=args.planner, mission=args.mission,
                       cooperation=args.cooperation, sublane=args.sublane, duration_s=args.duration,
                       period_s=args.period, deadline_s=args.period if args.deadline else None,
                       ego_in_forecast=bool(args.ego_in_forecast))
    if args.planner == "qp-avoid":
        from iamp.simulation.planning import make_planner

        make_planner("qp-avoid")  # refuses with one line before SUMO starts if unavailable
    result = run_episode(spec)
    if args.log:
        write_log(result, args.log)
    if args.figure:
        from iamp.simulation.figures import episode_figure

        episode_figure(result, args.figure)
    s = result.summary
    if args.json:
        print(json.dumps(s, allow_nan=False))
    else:
        for line in summary_lines(s):
            print(line)
    return EXIT_OK if s["success"] else EXIT_MISSION_FAILED


def _simulate_commonroad(args: argparse.Namespace) -> int:
    """``iamp simulate --commonroad FOLDER`` (SPEC §16): the interactive scenario in closed loop."""
    from iamp.commonroad import require
    from iamp.commonroad.interactive import simulate_with_log

    require()

    def progress(text: str) -> None:
        if not args.json:
            sys.stderr.write(f"  {text}\n")

    if args.log:
        check_destinations(args)
    r, log = simulate_with_log(args.commonroad, args.road_planner, recording=args.recording, progress=progress,
                               seed=args.seed, repair_routes=args.routes == "repaired")
    if args.log:
        from iamp.simulation.episode import write_log

        write_log(log, args.log)
    code = EXIT_OK if r["success"] else EXIT_MISSION_FAILED
    if args.json:
        sys.stdout.write(json.dumps(r, indent=1, default=float) + "\n")
        return code
    ttg = "-" if r["time_to_goal_s"] is None else f"{r['time_to_goal_s']:.1f} s"
    sys.stdout.write(f"{r['scenario']}: {r['status']} (time {ttg}, window {r['goal_window_s'][0]:.1f}-"
                     f"{r['goal_window_s'][1]:.1f} s), collisions {r['collisions']}, min TTC "
                     f"{r['min_ttc_s'] if r['min_ttc_s'] is None else round(r['min_ttc_s'], 2)} s, peak |u| "
                     f"{r['ego_peak_accel']:.2f} m/s^2, infeasible plans {r['infeasible_plans']}, fallbacks "
                     f"{r['fallbacks']}, plan time median {r['plan_time_s']['median'] or 0:.3f} s\n")
    if r["off_road_steps"]:
        a, b = r["off_road_times_s"]
        sys.stdout.write(f"off road  {r['off_road_steps']} executed steps at {a:.1f}-{b:.1f} s: the body collides with "
                         "the road boundary of CommonRoad's solution checker (the mission failed)\n")
    d = r["sumo_vs_recording"]
    if d is not None and d["vehicles_compared"]:
        sys.stdout.write(f"SUMO vs the recording: {d['vehicles_compared']} vehicles, largest position deviation "
                         f"median {d['median_abs_deviation_m']:.1f} m, max {d['max_abs_deviation_m']:.1f} m; "
                         f"lane changes recorded {d['lane_changes_recorded']}, in SUMO {d['lane_changes_sumo']}\n")
    for line in _responsibility_lines(r):
        sys.stdout.write(line + "\n")
    return code


#: Seconds allowed for the TCP connection to ``--scheduler`` before a campaign starts.
SCHEDULER_TIMEOUT_S = 3.0
DASK_DEFAULT_PORT = 8786


def check_scheduler(address: str, timeout: float = SCHEDULER_TIMEOUT_S) -> None:
    """Connect to the Dask scheduler at ``address`` once, with a short timeout, before any work.

    ``tcp://HOST[:PORT]`` / ``tls://...`` / ``HOST:PORT`` (Dask's default port 8786 when none is
    given); other transports are left to Dask.  An address that does not parse is bad input
    (:class:`~iamp.core.errors.ScenarioError`); one that does not answer is the user's
    environment (:class:`~iamp.core.errors.EnvironmentProblem`); both name the address.
    """
    import socket
    from urllib.parse import urlsplit

    from iamp.core.errors import EnvironmentProblem, ScenarioError

    parsed = urlsplit(address if "://" in address else f"tcp://{address}")
    if parsed.scheme not in ("tcp", "tls"):
        return
    try:
        host, port = parsed.hostname, parsed.port or DASK_DEFAULT_PORT
    except ValueError:
        host, port = None, 0
    if not host:
        raise ScenarioError("must be an address like tcp://HOST:PORT", "--scheduler", address)
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        reason = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        if isinstance(exc, TimeoutError):
            reason = f"no answer within {timeout:g} s"
        raise EnvironmentProblem(f"cannot reach the Dask scheduler at {address}", reason,
                                 getattr(exc, "errno", None)) from None


def cmd_campaign(args: argparse.Namespace) -> int:
    from iamp.core.outputs import guarded_folder  # checked (writable, ours or --force), locked, marked

    if args.scheduler:
        check_scheduler(args.scheduler)  # seconds, before the folder is touched (Dask itself waits 30 s)

    with guarded_folder(args.out, "campaign", getattr(args, "force", False)):
        return _campaign_into(args)


def _campaign_into(args: argparse.Namespace) -> int:
    from iamp.cli.progress import progress_bar
    from iamp.simulation.campaign import latex_table, paired_table, read_rows, run_campaign
    from iamp.simulation.figures import campaign_figures

    if "qp-avoid" in args.planners:
        from iamp.simulation.planning import make_planner

        make_planner("qp-avoid")
    out = Path(args.out)
    quiet = bool(args.quiet) or not sys.stderr.isatty()
    with progress_bar(0, "campaign", enabled=not quiet) as tick:
        if args.no_run:
            stats = {"ran": 0, "skipped": 0, "failed": 0, "seconds": 0.0}
        else:
            stats = run_campaign(args.planners, args.traffic, args.seeds, out, missions=args.missions,
                                 workers=args.workers, scheduler=args.scheduler, duration_s=args.duration,
                                 period_s=args.period, deadline=args.deadline, cooperation=args.cooperation,
                                 sublane=args.sublane, ego_in_forecast=bool(args.ego_in_forecast),
                                 force=args.force, progress=tick)
    from iamp.simulation.stats import campaign_report

    rows = [r for r in read_rows(out / "episodes.csv") if r["planner"] in args.planners
            and r["traffic"] in args.traffic and r.get("mission", "discretionary") in args.missions]
    report = campaign_report(rows, args.planners, reference=args.reference)
    from iamp.core.atomic import write_text

    write_text(out / "table.tex", latex_table(report["cells"]))
    write_text(out / "paired.tex", paired_table(report["paired"]))
    write_text(out / "summary.json", json.dumps(report, indent=1, allow_nan=False) + "\n")
    campaign_figures(report["cells"], rows, out)
    if not args.quiet:
        print(f"{stats['ran']} episodes run, {stats['skipped']} already done, {stats['failed']} failed "
              f"({stats['seconds']:.0f} s); {out / 'episodes.csv'}, manifest.json, table.tex, paired.tex, "
              "summary.json, rates.png, distributions.png")
        for c in report["cells"]:
            lo, hi = c["success_ci"]
            print(f"  {c['mission']:>13} {c['planner']:>10} {c['traffic']:>6}: success {c['success_episodes']}/"
                  f"{c['episodes']} [{100 * lo:.0f}, {100 * hi:.0f}] %, contacts {c['contact_episodes']} "
                  f"(ego at fault in {c.get('contact_at_fault_episodes', '--')}), emergency brakes because of the "
                  f"ego in {c.get('emergency_brake_episodes', '--')}")
    return EXIT_OK


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``iamp simulate`` and ``iamp campaign``."""
    p = sub.add_parser("simulate", help="one closed-loop lane-change episode in SUMO traffic (needs iamp[sim])",
                       description="Run one closed-loop episode: SUMO traffic, the shared predictor, the planner "
                                   "every period (SPEC §11, §15); an independent monitor judges it with RSS "
                                   "(SPEC §17).",
                       epilog=f"Exit status: 0 the mission succeeded; {EXIT_MISSION_FAILED} it failed (not in the "
                              "target lane in time, a contact, or with --commonroad the goal missed or an executed "
                              "body off CommonRoad's road); 2 bad input.")
    p.add_argument("--mission", choices=MISSIONS, default=None,
                   help="what the ego must do (SPEC §15; default merge: its lane ends 400 m ahead)")
    p.add_argument("--traffic", choices=TRAFFIC, default=None,
                   help="traffic density (default medium; los-e: 35 vehicles per km and lane)")
    p.add_argument("--seed", type=int_in("seed"), default=1,
                   help="SUMO and traffic seed in [0, 2^31-1] (default 1; with --commonroad SUMO's seed)")
    p.add_argument("--planner", choices=PLANNERS, default=None,
                   help="who drives the ego (SPEC §15; default pmp; sumo and mobil are the baselines)")
    p.add_argument("--cooperation", choices=COOPERATION, default=None,
                   help="SUMO drivers' cooperation (lcCooperative, lcAssertive, lcSpeedGain, "
                        "sigma) and whether the target-lane follower the signalling ego asks opens a gap "
                        "(SPEC §17's courtesy; none under low); docs/closed-loop.md; default default")
    p.add_argument("--sublane", action="store_true", help="the sumo planner with SUMO's sublane model SL2015")
    p.add_argument("--duration", type=float_in("episode_s"), default=None, help="episode length [s] (default 60)")
    p.add_argument("--period", type=float_in("period_s"), default=None,
                   help="control period = SUMO step [s] (default 0.1)")
    p.add_argument("--deadline", action="store_true",
                   help="a plan slower than the period is late and falls back (default: use plans however long "
                        "they take, so that the same seed gives the same numbers)")
    p.add_argument("--ego-in-forecast", action="store_true",
                   help="the target-lane follower's prediction reacts to the ego's plan, re-planned "
                        "at most 3 times per gap (tolerance 1 m; iamp planners only; docs/ego-in-forecast.md)")
    p.add_argument("--no-deadline", action="store_true", help=argparse.SUPPRESS)  # the default now (was opt-in)
    p.add_argument("--log", default=None, help="write the step log (ego + neighbours per step) as CSV "
                   "(an existing file only with --force)")
    p.add_argument("--figure", default=None, help="write a figure of the episode (.png, .pdf or .svg; an "
                   "existing file only with --force)")
    p.add_argument("--force", action="store_true", help="replace an existing --log / --figure file")
    p.add_argument("--json", action="store_true",
                   help="print exactly one JSON object (SPEC §11, §15, §17); the exit status is 0 when the "
                        f"mission succeeded, {EXIT_MISSION_FAILED} when it failed")
    p.add_argument("--commonroad", default=None, metavar="FOLDER",
                   help="an interactive CommonRoad scenario folder (*.cr.xml + *.sumo.cfg): the ego from its "
                        "planning problem, closed loop to its goal (SPEC §16; needs iamp[sim,commonroad])")
    p.add_argument("--road-planner", default=None, choices=("avoid", "pmp", "qp", "all-pmp", "free"),
                   help="with --commonroad: the road planner (iamp commonroad plan --planner; default avoid)")
    p.add_argument("--recording", default=None, metavar="SCENARIO.xml",
                   help="with --commonroad: the recorded scenario of the same vehicles, to report how SUMO's "
                        "traffic differs from it")
    p.add_argument("--routes", default=None, choices=("repaired", "as-shipped"),
                   help="with --commonroad: SUMO's routes with an edge repeated right after itself collapsed "
                        "(default repaired: SUMO refuses such routes and, told to ignore the error, stops those "
                        "vehicles at the repeated edge's end for good), or the scene's files as shipped")
    p.set_defaults(func=cmd_simulate)

    c = sub.add_parser("campaign", help="every planner x traffic x seed episode on Dask (needs iamp[sim])",
                       description="Run a campaign of closed-loop episodes on Dask distributed; resumes.")
    c.add_argument("--missions", type=_csv_choice(MISSIONS), default=["merge"],
                   help=f"comma-separated missions ({', '.join(MISSIONS)}; default merge)")
    c.add_argument("--planners", type=_csv_choice(PLANNERS), default=list(PLANNERS),
                   help=f"comma-separated planners (default all: {', '.join(PLANNERS)})")
    c.add_argument("--traffic", type=_csv_choice(TRAFFIC), default=["medium", "dense", "los-e"],
                   help=f"comma-separated densities ({', '.join(TRAFFIC)}; default medium,dense,los-e)")
    c.add_argument("--cooperation", choices=COOPERATION, default="default",
                   help="SUMO drivers' cooperation for every episode, with SPEC §17's courteous followers "
                        "except under low (docs/closed-loop.md; default default)")
    c.add_argument("--sublane", action="store_true", help="the sumo planner with SL2015")
    c.add_argument("--reference", choices=PLANNERS, default="pmp",
                   help="the planner every other one is compared with, seed by seed (default pmp)")
    c.add_argument("--no-run", action="store_true", help="only summarise the episodes already in --out")
    c.add_argument("--seeds", type=int_in("seeds"), default=20, help="seeds 1..N (N at most 10000)")
    c.add_argument("--out", required=True, help="output folder (episodes.csv, table.tex, figures)")
    c.add_argument("--force", action="store_true",
                   help="write into an existing folder that iamp did not write (no .iamp-output marker), and "
                        "discard its episodes if they were made with other parameters")
    c.add_argument("--workers", type=int_in("workers"), default=2, help="local Dask workers (processes)")
    c.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    c.add_argument("--duration", type=float_in("episode_s"), default=60.0, help="episode length [s]")
    c.add_argument("--period", type=float_in("period_s"), default=0.1, help="control period [s]")
    c.add_argument("--deadline", action="store_true", help="a plan slower than the period falls back")
    c.add_argument("--ego-in-forecast", action="store_true",
                   help="the target-lane follower's prediction reacts to the ego's plan, re-planned "
                        "at most 3 times per gap (tolerance 1 m; iamp planners only; docs/ego-in-forecast.md)")
    c.add_argument("--no-deadline", action="store_true", help=argparse.SUPPRESS)  # the default now (was opt-in)
    c.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    c.set_defaults(func=cmd_campaign)
