"""Command-line wiring of the predictor: ``iamp train``, ``iamp predict``,
``iamp evaluate-predictor``.

:func:`add_parsers` adds the sub-commands to the main ``iamp`` parser; every handler takes
the parsed arguments and returns the exit status (0 success, 2 bad input: one line on
standard error, no traceback).
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from iamp.cli.types import float_in, int_in, leader_model_file, model_file
from iamp.core.errors import IampError, ScenarioError

if TYPE_CHECKING:
    from iamp.core.scenario import Scenario
    from iamp.prediction.predictor import Predictor

EXIT_OK, EXIT_BAD_INPUT = 0, 2

__all__ = ["add_ngsim_options", "add_parsers", "cmd_evaluate_predictor", "cmd_predict", "cmd_train", "parse_bins",
           "predict_json"]


def _error(exc: BaseException) -> int:
    msg = exc.one_line() if isinstance(exc, ScenarioError) else str(exc)
    sys.stderr.write(f"iamp: error: {msg}\n")
    return EXIT_BAD_INPUT






#: The most acceleration bins ``--bins`` / ``--bin-width`` may ask for: the chain's transition
#: matrices grow with the square of the bins (the default is 13; 10^8 bins asked for 284 PiB).
MAX_BINS = 1000


def parse_bins(spec: str | None, width: float, a_max: float) -> np.ndarray:
    """Interior acceleration bin edges from the ``--bins`` / ``--bin-width`` / ``--a-max`` options.

    ``spec`` ``None``: bins of ``width`` centred on 0 over ``±a_max``; an integer ``N``: ``N``
    equal bins over ``[-a_max, a_max]`` (outer bins open); a comma-separated list: the
    interior edges themselves (strictly increasing, m/s²).
    """
    from iamp.prediction.predictor import symmetric_edges

    if spec is None:
        if 2 * round(a_max / width) + 1 > MAX_BINS:  # symmetric_edges' number of bins
            raise ValueError(f"--bin-width {width:g} over --a-max {a_max:g} gives more than {MAX_BINS} bins")
        return symmetric_edges(width, a_max)
    spec = spec.strip()
    if "," not in spec:
        try:
            n = int(spec)
        except ValueError:
            raise ValueError(f"--bins must be a number of bins or comma-separated edges (got {spec!r})") from None
        if not 2 <= n <= MAX_BINS:
            raise ValueError(f"--bins must be between 2 and {MAX_BINS} bins (got {n})")
        return np.linspace(-a_max, a_max, n + 1)[1:-1]
    try:
        edges = np.array([float(s) for s in spec.split(",") if s.strip()], dtype=float)
    except ValueError:
        raise ValueError(f"--bins edges must be numbers (got {spec!r})") from None
    if edges.size < 1 or not np.all(np.isfinite(edges)) or np.any(np.diff(edges) <= 0):
        raise ValueError("--bins edges must be finite and strictly increasing")
    if edges.size + 1 > MAX_BINS:
        raise ValueError(f"--bins gives {edges.size + 1} bins, more than {MAX_BINS}")
    return edges


def add_ngsim_options(parser: argparse.ArgumentParser) -> None:
    """``--location`` and ``--units`` of every command that reads NGSIM data."""
    parser.add_argument("--location", default=None,
                        help="NGSIM only: keep the rows of this Location (e.g. us-101, i-80); other rows are counted "
                             "as dropped (a file without a Location column: its rows are labelled with it, "
                             "noted in the report)")
    parser.add_argument("--units", default=None, choices=("feet", "metres"),
                        help="NGSIM only: the unit of lengths, speeds and accelerations in the file (default: "
                             "detected from vehicle lengths and widths, lane width and speeds; a file whose data "
                             "cannot tell is refused)")


# ---------------------------------------------------------------------------------------
# iamp train
# ---------------------------------------------------------------------------------------

def cmd_train(args: argparse.Namespace) -> int:
    """``iamp train``: fit an MTD model on recorded tracks and write it (atomically)."""
    from iamp.cli.progress import call_with_progress, progress_enabled
    from iamp.core.outputs import check_output  # fail fast: not an input, no silent overwrite, writable
    from iamp.prediction.loaders.formats import load_with_report, ngsim_options
    from iamp.prediction.predictor import train_from_tracks

    check_output(args.out, args.data, getattr(args, "force", False))
    try:
        edges = parse_bins(args.bins, args.bin_width, args.a_max)
        tracks, report = load_with_report(args.data, args.format,
                                          **ngsim_options(args.format, args.location, args.units))
        for line in report.lines():
            print(line)
        if args.model_kind == "leader" and len(args.data) != 1:
            raise ValueError("--model-kind leader needs exactly one data file (leaders are found within one recording)")
        model = call_with_progress(
            train_from_tracks, tracks, desc="train", enabled=progress_enabled(args), dt=args.dt, edges=edges,
            order=args.order, estimator=args.estimator, jerk_psd=args.jerk_psd,
            provenance={"trained_by": "iamp train", "inputs": [str(p) for p in args.data], "format": args.format})
        if args.model_kind == "leader":
            from iamp.prediction.leader.leaders import leaders_for
            from iamp.prediction.leader.model import train_leader_model

            leaders = leaders_for(args.data[0], args.format, tracks)
            lm = call_with_progress(
                train_leader_model, tracks, leaders, args.law, model, desc="calibrate", enabled=progress_enabled(args),
                provenance={"trained_by": "iamp train --model-kind leader", "inputs": [str(p) for p in args.data],
                            "format": args.format}, calibration=args.calibration)
            lm.save(args.out)
        else:
            model.save(args.out)
    except (IampError, ValueError, OSError) as exc:
        return _error(exc)
    if args.model_kind == "leader":
        fit = lm.law.fit
        print(f"leader model: {lm.law.name} " + ", ".join(f"{k}={v:.4g}" for k, v in lm.law.params.items()))
        print(f"leaders: {leaders.source} ({100 * leaders.known_fraction:.1f} % of rows); calibration: "
              f"{fit.get('criterion')}")
        if "trajectory_rms_m" in fit:
            print(f"trajectory RMS over {fit['trajectory_windows']} windows: {fit['trajectory_rms_m_start']:.3f} m "
                  f"(acceleration fit) -> {fit['trajectory_rms_m']:.3f} m")
        print(f"fallback (no leader): the MTD model trained here, order {model.order}, {model.n_states} states")
        print(f"wrote {args.out}")
        return EXIT_OK
    s = model.summary()
    print(f"trained MTD model: order {s['order']}, {s['n_states']} states, dt {model.dt:g} s, "
          f"estimator {s['estimator']}, {model.provenance.get('n_tracks_used')} tracks")
    print(f"log-likelihood {s['loglik']:.6g} over N = {s['n_obs']} transitions")
    print(f"parameters k = n m (m-1) + (n-1) = {s['n_parameters']}")
    print(f"AIC {s['aic']:.6g}   BIC {s['bic']:.6g}")
    print("lambda " + " ".join(f"{v:.6f}" for v in s["lambda"]))
    print(f"wrote {args.out}")
    return EXIT_OK


# ---------------------------------------------------------------------------------------
# iamp predict
# ---------------------------------------------------------------------------------------

def predict_json(scenario: Scenario, predictor: Predictor | None, model_label: str) -> dict[str, Any]:
    """The SPEC §5b object for ``scenario``.

    Vehicles with a ``history`` are predicted (``t``/``x`` are the predicted samples before
    the cubic fit); vehicles given by ``x_poly`` pass through unchanged and their ``t``/``x``
    are the polynomial sampled at the same times ``0, Δt, …, t_f`` (Δt of the model).
    """
    tf = scenario.ego.tf
    vehicles = []
    preds = {}
    for i, v in enumerate(scenario.vehicles):
        if v.history is not None:
            if predictor is None:
                raise ValueError(f"vehicle {v.name!r} is given by a history but no predictor was given")
            preds[i] = predictor.predict(v.history, tf)
    if preds:
        t = next(iter(preds.values())).t
    else:
        dt = predictor.dt if predictor is not None else 0.1
        M = max(int(math.ceil(tf / dt - 1e-9)), 1)
        t = dt * np.arange(M + 1)
        t[-1] = tf
    for i, v in enumerate(scenario.vehicles):
        if i in preds:
            p = preds[i]
            vehicles.append({"name": v.name, "x_poly": list(p.x_poly), "t": p.t.tolist(), "x": p.x.tolist(),
                             "source": "history", "fit_rmse": p.fit_rmse})
        else:
            x = np.polynomial.polynomial.polyval(t, np.asarray(v.x_poly, dtype=float))
            vehicles.append({"name": v.name, "x_poly": [float(c) for c in v.x_poly or ()], "t": t.tolist(),
                             "x": x.tolist(), "source": "x_poly"})
    return {"scenario": scenario.name, "model": model_label, "vehicles": vehicles}


def cmd_predict(args: argparse.Namespace) -> int:
    """``iamp predict``: predict every history vehicle of a scenario."""
    from iamp.cli.scenarios import load_cli_scenario as load_scenario  # a file, a built-in, or - (stdin)
    from iamp.cli.text import polynomial
    from iamp.prediction.predictor import Predictor

    try:
        scenario = load_scenario(args.scenario)
        predictor = Predictor.from_file(args.model) if args.model else Predictor.default()
        out = predict_json(scenario, predictor, predictor.name)
        if args.leader_model is not None:
            from iamp.prediction.leader.model import LeaderPredictor, predict_scenario, scenario_leaders

            lp = LeaderPredictor.from_file(args.leader_model)
            lead = scenario_leaders(scenario.vehicles)
            for i, (coef, tt, xx) in predict_scenario(lp, scenario.vehicles, scenario.ego.tf).items():
                fr = float(np.sqrt(np.mean((np.polynomial.polynomial.polyval(tt, coef) - xx) ** 2)))
                out["vehicles"][i].update({"x_poly": list(coef), "t": tt.tolist(), "x": xx.tolist(), "fit_rmse": fr,
                                           "leader": scenario.vehicles[lead[i]].name if i in lead else None})
            out["model"] = args.leader_model
    except (IampError, ValueError, OSError) as exc:
        return _error(exc)
    if args.json:
        sys.stdout.write(json.dumps(out) + "\n")
        return EXIT_OK
    print(f"scenario {out['scenario']}  (model: {out['model']}, {predictor!r})")
    for v in out["vehicles"]:
        c = v["x_poly"]
        poly = polynomial(c)
        extra = f", fit RMSE {v['fit_rmse']:.3g} m" if "fit_rmse" in v else ""
        print(f"  {v['name']:8s} [{v['source']}] x(t) = {poly}{extra}")
        print(f"           x({v['t'][-1]:g}) = {v['x'][-1]:.3f} m")
    return EXIT_OK


# ---------------------------------------------------------------------------------------
# iamp evaluate-predictor
# ---------------------------------------------------------------------------------------

def cmd_evaluate_predictor(args: argparse.Namespace) -> int:
    """``iamp evaluate-predictor``: on ``--data`` (SPEC §13), else the protocol on the shipped data."""
    if args.data is None:
        return _evaluate_shipped(args)
    if args.format is None:
        return _error(ValueError("--data needs --format (highd, ngsim or sumo)"))
    from iamp.cli.progress import progress_bar, progress_enabled
    from iamp.prediction.evaluation.user import evaluate_file

    if args.markdown is not None:
        if args.no_interaction:
            return _error(ValueError("--markdown writes the interaction tables; it excludes --no-interaction"))
        from iamp.core.outputs import check_output

        try:
            check_output(args.markdown, [args.data], args.force, option="--markdown")
        except (IampError, ValueError, OSError) as exc:
            return _error(exc)
    try:
        with progress_bar(8, "evaluate-predictor", enabled=progress_enabled(args)) as tick:
            res = evaluate_file(args.data, args.format, model=args.model, split=args.split, seed=args.seed,
                                location=args.location, units=args.units, progress=tick,
                                leader_model=args.leader_model, interaction=not args.no_interaction)
    except (IampError, ValueError, OSError) as exc:
        return _error(exc)
    if args.markdown is not None:
        from iamp.core.atomic import write_text
        from iamp.prediction.evaluation.leader_report import interaction_markdown

        cmd = "iamp evaluate-predictor " + " ".join(shlex.quote(a) for a in sys.argv[2:])
        write_text(args.markdown, interaction_markdown(res, Path(str(args.data)).name) + f"\nCommand: `{cmd}`\n")
    if args.json:
        sys.stdout.write(json.dumps(res, allow_nan=False) + "\n")
        return EXIT_OK
    from iamp.prediction.loaders.report import LoadReport

    for line in LoadReport.from_dict(res["load_report"]).lines():
        print(line)
    print(f"{res['data']}: {res['tracks']} tracks, {res['windows']} windows (3 s history, 5 s future); "
          f"model: {res['model']}")
    print("RMSE [m] at " + "/".join(f"{h:g}" for h in res["horizons_s"]) + " s, ADE, FDE:")
    for name in res["rmse_m"]:
        print(f"  {name:4s} " + " ".join(f"{v:6.2f}" for v in res["rmse_m"][name])
              + f"   {res['ade_m'][name]:6.2f} {res['fde_m'][name]:6.2f}")
    for name, d in res["diff_to_cv"].items():
        lo, hi = d["fde_m"]["ci95"]
        print(f"  {name} - cv: FDE {d['fde_m']['diff']:+.2f} m (95 % CI {lo:+.2f} .. {hi:+.2f}, track bootstrap)")
    if res["lateral_rmse_m"]:
        print("lateral RMSE of y = const [m]: " + " ".join(f"{v:.2f}" for v in res["lateral_rmse_m"]["constant_y"]))
    if res.get("interaction"):
        print_interaction(res["interaction"])
    return EXIT_OK


def print_interaction(inter: dict[str, Any]) -> None:
    """The ``interaction`` section as text: per subset, RMSE at 5 s with its CI and the change against CV."""
    lm = inter["leader_model"]
    print(f"leaders: {inter['leader_source']}; {inter['windows_leader_known']} windows with a known leader "
          f"({inter.get('windows_leader_rejected', 0)} named leaders refused: not ahead over the whole history); "
          f"congested: speed < {inter['congested_below_mps']:.2f} m/s ({inter['windows_congested']} windows)")
    print(f"leader model: {lm['law']} " + ", ".join(f"{k}={v:.3g}" for k, v in lm["params"].items())
          + f" ({lm['note']})")
    for sub, tb in inter["tables"].items():
        if "methods" not in tb:
            print(f"  [{sub}] no windows")
            continue
        print(f"  [{sub}] {tb['windows']} windows, {tb['tracks']} tracks: RMSE at 5 s [m] (95 % CI), vs CV")
        for name, r in tb["methods"].items():
            lo, hi = r["rmse_ci95"][-1]
            d = r.get("diff_to_cv")
            rel = (f"{100 * d['rmse_5s_rel']:+6.1f} % ({100 * d['rmse_5s_rel_ci95'][0]:+.1f} .. "
                   f"{100 * d['rmse_5s_rel_ci95'][1]:+.1f})") if d else ""
            print(f"    {name:14s} {r['rmse_m'][-1]:6.2f} ({lo:.2f} .. {hi:.2f})  ADE {r['ade_m']:.2f}  "
                  f"FDE {r['fde_m']:.2f}  {rel}")


def _evaluate_shipped(args: argparse.Namespace) -> int:
    from iamp.core.outputs import guarded_folder  # checked, locked and marked output folder

    with guarded_folder(args.out, "evaluate-predictor", getattr(args, "force", False)):
        return _evaluate_shipped_into(args)


def _evaluate_shipped_into(args: argparse.Namespace) -> int:
    from iamp.prediction.evaluation.evaluate import HORIZONS, write_evaluation_report

    try:
        res = write_evaluation_report(args.out, rerun=args.rerun, select=not args.no_select)
    except (IampError, ValueError, OSError) as exc:
        return _error(exc)
    if args.json:
        sys.stdout.write(json.dumps(res, allow_nan=False) + "\n")
        return EXIT_OK
    cfg = res["chosen"]
    print(f"chosen: order {cfg['order']}, dt {cfg['dt']:g} s, bin width {cfg['width']:g} m/s^2, "
          f"estimator {cfg.get('estimator', 'mle')}")
    print("test RMSE [m] at " + "/".join(f"{h:g}" for h in HORIZONS) + " s, ADE, FDE:")
    for name, r in res["test"].items():
        print(f"  {name:22s} " + " ".join(f"{v:6.2f}" for v in r["rmse"]) + f"   {r['ade']:6.2f} {r['fde']:6.2f}")
    print(f"wrote {args.out}/predictor_eval.json and {args.out}/tables/predictor_*.tex")
    return EXIT_OK


# ---------------------------------------------------------------------------------------
# parsers
# ---------------------------------------------------------------------------------------

def add_parsers(subparsers: Any) -> None:
    """Add ``train``, ``predict`` and ``evaluate-predictor`` to ``iamp``'s sub-parsers."""
    from iamp.cli.progress import add_quiet_flag
    from iamp.prediction.evaluation.evaluate import DEFAULT_CONFIG

    t = subparsers.add_parser(
        "train", help="train an MTD predictor model on recorded trajectories",
        description="Fit Raftery's mixture-transition-distribution model of the longitudinal "
                    "acceleration to recorded tracks and write it as JSON (atomically). Prints the "
                    "log-likelihood, the parameter count k = n m (m-1) + (n-1), AIC, BIC and the lag weights.")
    t.add_argument("data", nargs="+", help="data files or directories")
    t.add_argument("--format", required=True, choices=("highd", "ngsim", "sumo"), help="data format")
    add_ngsim_options(t)
    t.add_argument("--out", required=True, help="model file to write (JSON)")
    t.add_argument("--model-kind", choices=("mtd", "leader"), default="mtd",
                   help="mtd: the paper's single-vehicle chain (default); leader: a car-following law calibrated on "
                        "the vehicles with a leader (NGSIM Preceding, else lane + position), with the MTD trained "
                        "here as the fallback where no leader is known")
    t.add_argument("--law", choices=("idm", "linear"), default="idm", help="leader model: car-following law")
    t.add_argument("--calibration", choices=("trajectory", "acceleration"), default="trajectory",
                   help="leader model: least squares on 5-s trajectories along the leader's CV forecast (default) "
                        "or on observed accelerations")
    t.add_argument("--force", action="store_true", help="replace --out if it exists")
    t.add_argument("--order", type=int_in("order"), default=DEFAULT_CONFIG["order"],
                   help=f"chain order n (default {DEFAULT_CONFIG['order']})")
    t.add_argument("--bins", default=None,
                   help="acceleration bins: a number N of equal bins over [-A, A] (A = --a-max; outer bins "
                        "open), or comma-separated interior edges in m/s^2 (default: bins of --bin-width "
                        "centred on 0)")
    t.add_argument("--bin-width", type=float_in("accel_mps2"), default=DEFAULT_CONFIG["width"],
                   help=f"bin width in m/s^2 when --bins is not given (default {DEFAULT_CONFIG['width']:g})")
    t.add_argument("--a-max", type=float_in("accel_mps2"), default=DEFAULT_CONFIG["a_max"],
                   help=f"range of the bins in m/s^2 (default {DEFAULT_CONFIG['a_max']:g})")
    t.add_argument("--dt", type=float_in("model_dt_s"), default=DEFAULT_CONFIG["dt"],
                   help=f"chain time step in s (default {DEFAULT_CONFIG['dt']:g})")
    t.add_argument("--jerk-psd", type=float_in("jerk_psd"), default=DEFAULT_CONFIG["jerk_psd"],
                   help="jerk spectral density q in m^2/s^5 of the smoother estimating the initial state at "
                        f"prediction time (stored in the model; default {DEFAULT_CONFIG['jerk_psd']:g})")
    t.add_argument("--estimator", choices=("mle", "mle-lambda", "lp"), default="mle",
                   help="mle: joint maximum likelihood of lambda and Q_i (EM, default); mle-lambda: Q_i from "
                        "lag-i counts, lambda by maximum likelihood; lp: Q_i from lag-i counts, lambda by the "
                        "Ching-Fung-Ng linear programme")
    add_quiet_flag(t)
    t.set_defaults(func=cmd_train)

    p = subparsers.add_parser(
        "predict", help="predict the trajectories of a scenario's history vehicles",
        description="Predict every vehicle of the scenario that is given by an observed history and fit "
                    "its cubic x_poly (ascending powers c0..c3). With --json, print exactly one JSON object "
                    '{"scenario", "model", "vehicles": [{"name", "x_poly", "t", "x", ...}]} where t/x are the '
                    "predicted samples before the fit. A vehicle given with x_poly in the file passes through "
                    "with its polynomial unchanged; its t/x are then that polynomial sampled at the same times.")
    p.add_argument("scenario", help="scenario TOML file, built-in name, or - (standard input)")
    p.add_argument("--model", type=model_file, default=None,
                   help="model file (default: the shipped model, reported as 'builtin')")
    p.add_argument("--leader-model", type=leader_model_file, default=None,
                   help="leader model (iamp train --model-kind leader): a history vehicle with another history "
                        "vehicle ahead in its lane (|dy| < 1.75 m) is predicted following it")
    p.add_argument("--json", action="store_true", help="print exactly one JSON object (SPEC §5b)")
    p.set_defaults(func=cmd_predict)

    e = subparsers.add_parser(
        "evaluate-predictor", help="evaluate the predictor against baselines and write the report",
        description="With --data FILE --format F: evaluate constant velocity, constant acceleration, the MTD "
                    "predictor and a first-order chain on windows of 3 s history / 5 s future of the file "
                    "(RMSE at 1..5 s, ADE, FDE, lateral RMSE of y = const, track-bootstrap 95 % intervals of each "
                    "method's difference to CV; dropped rows are reported). Without --data: run the evaluation "
                    "protocol on the shipped SUMO data and write predictor_eval.json and tables under --out.")
    e.add_argument("--data", default=None,
                   help="evaluate on this recorded-data file (SPEC §13) instead of the shipped SUMO data")
    e.add_argument("--format", default=None, choices=("highd", "ngsim", "sumo"),
                   help="format of --data (sumo also reads the log of iamp simulate --log)")
    e.add_argument("--model", type=model_file, default=None,
                   help="model file to evaluate (default: the shipped model)")
    e.add_argument("--split", default=None, choices=("vehicle", "time"),
                   help="train on part of --data and evaluate on the held-out rest: 20 %% of the vehicles "
                        "(seeded) or the last 20 %% of the time span")
    e.add_argument("--seed", type=int_in("seed"), default=0,
                   help="seed of the vehicle split and the bootstrap, in [0, 2^31-1] (default 0)")
    add_ngsim_options(e)
    e.add_argument("--leader-model", type=leader_model_file, default=None,
                   help="leader model file (kind 'leader', from iamp train --model-kind leader) to evaluate "
                        "(default: the shipped one; with --split one is calibrated on the training part)")
    e.add_argument("--no-interaction", action="store_true",
                   help="skip the leader-aware predictor and the tables per traffic state and leader")
    e.add_argument("--json", action="store_true", help="print exactly one JSON object")
    e.add_argument("--markdown", metavar="FILE", default=None,
                   help="with --data: also write the tables (RMSE per horizon, ADE/FDE with CIs, change against CV, "
                        "RMSE at 5 s per traffic state and leader) as Markdown, with the command (atomically; "
                        "--force to replace)")
    e.add_argument("--out", default="reports", help="output directory without --data (default: reports)")
    e.add_argument("--force", action="store_true", help="write into an existing --out folder iamp did not write")
    e.add_argument("--rerun", action="store_true",
                   help="recompute even if DIR/predictor_eval.json already holds results of this protocol "
                        "version for the shipped data (by default those are reused and only the tables rewritten)")
    e.add_argument("--no-select", action="store_true",
                   help="when running, skip the grid search and evaluate the default configuration only (fast)")
    add_quiet_flag(e)
    e.set_defaults(func=cmd_evaluate_predictor)
