#!/usr/bin/env python3
"""Generate the predictor's shipped training data with Eclipse SUMO, deterministically.

    pip install 'iamp[sumo]'            # eclipse-sumo + sumolib from PyPI (carries the binaries)
    python scripts/sumo/generate_dataset.py            # writes prediction/data/sumo_highway.{npz,json}

What it does
------------
1. ``netconvert`` builds the network from the plain-XML files beside this script
   (``highway.nod.xml``, ``highway.edg.xml``, ``highway.con.xml``; no junction-internal lanes):
   a straight road along +x,
   2.5 km with three lanes at 120 km/h, then a 0.7 km work zone where the left lane ends and
   the limit is 80 km/h.
2. ``sumo`` runs the demand of ``highway.rou.xml`` (four car driver types and 12 % trucks,
   Krauss with sigma 0.3..0.8, speedFactor distributions, LC2013 lane changing, Poisson arrivals
   rising to a peak that overloads the bottleneck) with ``--seed``, ``--step-length`` and FCD
   output including the acceleration, as ``;``-separated CSV.
3. :func:`iamp.prediction.loaders.formats.load_sumo_fcd` reads it (vehicle lengths from the vTypes, so
   positions are vehicle centres); the warm-up (``t < --warmup``) and the road's ends
   (outside ``--x-min .. --x-max``: insertion and arrival) are dropped, as are tracks shorter
   than ``--min-track``; tracks are renumbered 0..n-1 in order of appearance.
4. The table is resampled to the simulation step (it is already uniform; the predictor picks
   its own step) and saved with ``Tracks.save(decimals=2)`` -- SUMO writes two decimals, so this
   is lossless -- to ``--out``.  If the file exceeded ``--max-mb``, whole tracks would be dropped
   (seeded) until it fits.  Beside it goes a JSON file with the provenance: SUMO version, seed,
   step length, network, vTypes, flows, options, statistics and the sha256 of the npz.

Everything is deterministic for a given SUMO version: the same command writes byte-identical
files (no timestamps; the npz has fixed zip dates).  The script prints a short summary.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
NETWORK_FILES = {"nodes": "highway.nod.xml", "edges": "highway.edg.xml", "connections": "highway.con.xml"}
ROUTES_FILE = "highway.rou.xml"
#: netconvert options: keep the given coordinates, no junction-internal lanes (the lane drop's
#: junction has zero length, so x is continuous without them).
NETCONVERT_OPTIONS = ["--no-turnarounds", "--offset.disable-normalization", "--no-internal-links"]
DEFAULT_OUT = REPO / "prediction" / "data" / "sumo_highway.npz"

DEFAULTS = {
    "seed": 42,
    "step_length": 0.1,
    "end": 1300.0,       # the last vehicles depart at 900 s and need < 400 s to leave
    "warmup": 120.0,     # s: the road starts empty
    "x_min": 150.0,      # m: insertion region
    "x_max": 3150.0,     # m: arrival region (the road ends at 3200 m)
    "min_track": 20.0,   # s
    "max_mb": 3.0,
}


def find_tool(name: str) -> str:
    """The SUMO binary ``name``: from the ``eclipse-sumo`` wheel, ``$SUMO_HOME/bin``, or PATH."""
    candidates = []
    try:
        import sumo  # the eclipse-sumo wheel

        candidates.append(Path(sumo.SUMO_HOME) / "bin" / name)
    except ImportError:
        pass
    if os.environ.get("SUMO_HOME"):
        candidates.append(Path(os.environ["SUMO_HOME"]) / "bin" / name)
    for cand in candidates:
        if cand.is_file() and os.access(cand, os.X_OK):
            return str(cand)
    found = shutil.which(name)
    if found:
        return found
    raise SystemExit(f"error: '{name}' not found; install Eclipse SUMO with: pip install 'iamp[sumo]'")


def tool_version(exe: str) -> str:
    out = subprocess.run([exe, "--version"], capture_output=True, text=True, check=True).stdout
    first = out.strip().splitlines()[0].strip()
    return first


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run(cmd: list[str], cwd: Path) -> str:
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"error: {Path(cmd[0]).name} failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
    return proc.stdout + proc.stderr


def xml_elements(path: Path, tag: str) -> list[dict]:
    return [dict(el.attrib) for el in ET.parse(path).getroot().iter(tag)]


def config_summary() -> dict:
    """Network, driver types and demand, read back from the configuration files."""
    routes = HERE / ROUTES_FILE
    vtypes = xml_elements(routes, "vType")
    dist = xml_elements(routes, "vTypeDistribution")
    flows = xml_elements(routes, "flow")
    for fl in flows:
        m = re.fullmatch(r"exp\(([0-9.]+)\)", fl.get("period", ""))
        if m:
            fl["mean_vehicles_per_hour"] = round(float(m.group(1)) * 3600.0, 1)
    return {
        "network": {
            "description": "straight road along +x: 'main' 2500 m, 3 lanes, 33.33 m/s (120 km/h), then "
                           "'workzone' 700 m, 2 lanes, 22.22 m/s (80 km/h); lane 2 (left) ends at x = 2500; "
                           "lanes 0 and 1 continue in place (lane 0 = rightmost)",
            "nodes": xml_elements(HERE / NETWORK_FILES["nodes"], "node"),
            "edges": xml_elements(HERE / NETWORK_FILES["edges"], "edge"),
            "connections": xml_elements(HERE / NETWORK_FILES["connections"], "connection"),
        },
        "vtype_distributions": dist,
        "vtypes": vtypes,
        "routes": xml_elements(routes, "route"),
        "flows": flows,
        "car_following_model": "Krauss (SUMO default), sigma redrawn every sigmaStep",
        "lane_change_model": "LC2013 (SUMO default)",
        "input_sha256": {name: sha256(HERE / name) for name in [*NETWORK_FILES.values(), ROUTES_FILE]},
    }


def sumo_statistics(path: Path) -> dict:
    root = ET.parse(path).getroot()
    out = {}
    for tag in ("vehicles", "teleports", "safety", "vehicleTripStatistics"):
        el = root.find(tag)
        if el is not None:
            out[tag] = {k: (float(v) if re.fullmatch(r"-?[0-9.]+(e-?[0-9]+)?", v) else v) for k, v in el.attrib.items()}
    return out


def table_statistics(tracks) -> dict:
    q = [0.0, 0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99, 1.0]
    durations, lane_changes, with_lc, with_stop = [], 0, 0, 0
    for _tid, t, _x, v, _a, lane in tracks.iter_tracks():
        durations.append(t[-1] - t[0] + tracks.dt)
        n_lc = int(np.count_nonzero(np.diff(lane)))
        lane_changes += n_lc
        with_lc += n_lc > 0
        with_stop += bool(v.min() < 1.0)
    rnd = lambda arr: [round(float(x), 3) + 0.0 for x in arr]  # noqa: E731
    types = tracks.meta.get("track_types", [])
    return {
        "rows": len(tracks),
        "tracks": tracks.n_tracks,
        "total_duration_s": round(tracks.duration, 1),
        "track_duration_s_quantiles": dict(zip(map(str, q), rnd(np.quantile(durations, q)))),
        "acceleration_quantiles": dict(zip(map(str, q), rnd(np.quantile(tracks.a, q)))),
        "speed_quantiles": dict(zip(map(str, q), rnd(np.quantile(tracks.v, q)))),
        "fraction_a_below_-1": round(float(np.mean(tracks.a < -1.0)), 4),
        "fraction_a_above_1": round(float(np.mean(tracks.a > 1.0)), 4),
        "lane_changes": lane_changes,
        "tracks_with_lane_change": with_lc,
        "tracks_with_near_stop_v_below_1": with_stop,
        "tracks_by_type": {k: types.count(k) for k in sorted(set(types))},
    }


def build_table(fcd: Path, args, lengths: dict, extra_meta: dict):
    from iamp.prediction.loaders.formats import load_sumo_fcd
    from iamp.prediction.tracks.table import Tracks

    raw = load_sumo_fcd(fcd, lengths=lengths)
    keep = (raw.t >= args.warmup) & (raw.x >= args.x_min) & (raw.x <= args.x_max)
    # x increases along a track and time too, so each kept part of a track is contiguous
    part = raw.select(keep)
    ids, starts, counts = np.unique(part.track_id, return_index=True, return_counts=True)
    long_enough = counts * part.dt >= args.min_track
    kept_ids = ids[long_enough]
    part = part.select(np.isin(part.track_id, kept_ids))
    new_id = np.searchsorted(kept_ids, part.track_id)
    source_ids = [raw.meta["source_ids"][i] for i in kept_ids]
    types = [raw.meta["track_types"][i] for i in kept_ids]
    meta = {
        "format": "sumo-fcd",
        "name": "sumo_highway",
        "dataset": "sumo_highway",
        "description": "Eclipse SUMO simulation of a 3-lane highway with a 2-lane work zone (lane drop at "
                       "x = 2500 m, 80 km/h) under demand rising to a peak and back: free flow, queues and "
                       "stop-and-go waves, lane changes; cars of four driver types and 12 % trucks.",
        "generator": "scripts/sumo/generate_dataset.py",
        **extra_meta,
        "reference_point": raw.meta["reference_point"],
        "coordinate": "network x; the road runs along +x from 0 to 3200 m",
        "lane_numbering": "SUMO lane index, 0 = rightmost; lane 2 exists only for x < 2500 m",
        "units": "SI (s, m, m/s, m/s^2)",
        "acceleration_source": raw.meta["acceleration_source"],
        "trimmed": {"warmup_s": args.warmup, "x_window_m": [args.x_min, args.x_max],
                    "min_track_duration_s": args.min_track},
        "source_ids": source_ids,
        "track_types": types,
    }
    table = Tracks(new_id, part.t, part.x, part.v, part.a, part.lane, part.dt, meta)
    return table.resample(args.step_length)


def select_tracks(table, fraction: float, seed: int):
    """Keep a seeded random subset of whole tracks (used only if the file is too large)."""
    from iamp.prediction.tracks.table import Tracks

    ids = table.ids()
    n_keep = max(1, int(fraction * ids.size))
    keep = np.sort(np.random.default_rng(seed).permutation(ids.size)[:n_keep])
    sub = table.select(np.isin(table.track_id, ids[keep]))
    meta = dict(sub.meta)
    meta["source_ids"] = [table.meta["source_ids"][i] for i in keep]
    meta["track_types"] = [table.meta["track_types"][i] for i in keep]
    meta["subsampled_tracks"] = {"kept": int(n_keep), "of": int(ids.size), "seed": seed}
    return Tracks(np.searchsorted(ids[keep], sub.track_id), sub.t, sub.x, sub.v, sub.a, sub.lane, sub.dt, meta)


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=DEFAULTS["seed"], help="SUMO's --seed (default %(default)s)")
    p.add_argument("--step-length", type=float, default=DEFAULTS["step_length"],
                   help="simulation step in s (default %(default)s)")
    p.add_argument("--end", type=float, default=DEFAULTS["end"], help="simulation end in s (default %(default)s)")
    p.add_argument("--warmup", type=float, default=DEFAULTS["warmup"],
                   help="drop samples before this time, s (default %(default)s)")
    p.add_argument("--x-min", type=float, default=DEFAULTS["x_min"], help="default %(default)s m")
    p.add_argument("--x-max", type=float, default=DEFAULTS["x_max"], help="default %(default)s m")
    p.add_argument("--min-track", type=float, default=DEFAULTS["min_track"],
                   help="drop tracks shorter than this, s (default %(default)s)")
    p.add_argument("--max-mb", type=float, default=DEFAULTS["max_mb"],
                   help="size limit of the npz in MB (default %(default)s)")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT,
                   help="output .npz (the .json goes beside it; default prediction/data/sumo_highway.npz)")
    p.add_argument("--workdir", type=Path, default=None,
                   help="keep the network, FCD and SUMO logs here (default: a temporary directory)")
    return p.parse_args(argv)


def command_line(args) -> str:
    parts = ["python", "scripts/sumo/generate_dataset.py", "--seed", str(args.seed)]
    for key, default in DEFAULTS.items():
        if key == "seed":
            continue
        val = getattr(args, key)
        if val != default:
            parts += [f"--{key.replace('_', '-')}", f"{val:g}"]
    if args.out.resolve() != DEFAULT_OUT.resolve():
        parts += ["--out", str(args.out)]
    return " ".join(parts)


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    t_start = time.monotonic()
    sumo, netconvert = find_tool("sumo"), find_tool("netconvert")
    version = tool_version(sumo)
    out = args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    json_path = out.with_suffix(".json")

    sumo_opts = ["--step-length", f"{args.step_length:g}", "--seed", str(args.seed), "--begin", "0",
                 "--end", f"{args.end:g}", "--fcd-output", "fcd.csv", "--fcd-output.acceleration",
                 "--precision", "2", "--statistic-output", "statistics.xml", "--no-step-log",
                 "--duration-log.statistics"]
    netconvert_opts = NETCONVERT_OPTIONS

    with tempfile.TemporaryDirectory(prefix="iamp-sumo-") as tmp:
        work = args.workdir if args.workdir is not None else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for name in [*NETWORK_FILES.values(), ROUTES_FILE]:
            shutil.copyfile(HERE / name, work / name)
        run([netconvert, "-n", NETWORK_FILES["nodes"], "-e", NETWORK_FILES["edges"], "-x",
             NETWORK_FILES["connections"], "-o", "highway.net.xml", *netconvert_opts], work)
        t_sim = time.monotonic()
        log = run([sumo, "-n", "highway.net.xml", "-r", ROUTES_FILE, *sumo_opts], work)
        (work / "sumo.log").write_text(log)
        sim_seconds = time.monotonic() - t_sim
        stats = sumo_statistics(work / "statistics.xml")

        lengths = {vt["id"]: float(vt["length"]) for vt in xml_elements(HERE / ROUTES_FILE, "vType")
                   if "length" in vt}
        provenance = {"sumo_version": version, "seed": args.seed, "step_length": args.step_length}
        table = build_table(work / "fcd.csv", args, lengths, provenance)

    table.save(out, decimals=2)
    size_mb = out.stat().st_size / 1e6
    if size_mb > args.max_mb:
        table = select_tracks(table, 0.97 * args.max_mb / size_mb, args.seed)
        table.save(out, decimals=2)
        size_mb = out.stat().st_size / 1e6

    summary = {
        "dataset": out.name,
        "description": table.meta["description"],
        "generator": "scripts/sumo/generate_dataset.py",
        "command": command_line(args),
        "sumo_version": version,
        "netconvert_version": tool_version(netconvert),
        "seed": args.seed,
        "step_length": args.step_length,
        "simulation": {"begin": 0.0, "end": args.end, "sumo_options": sumo_opts,
                       "netconvert_options": netconvert_opts},
        "configuration": config_summary(),
        "processing": {
            "loader": "iamp.prediction.loaders.formats.load_sumo_fcd (x = front bumper - length/2, lengths from the vTypes)",
            "warmup_dropped_s": args.warmup,
            "x_window_m": [args.x_min, args.x_max],
            "min_track_duration_s": args.min_track,
            "resampled_to_dt_s": table.dt,
            "storage": "Tracks.save(decimals=2): x, v, a rounded to 0.01 (SUMO writes 2 decimals)",
            "subsampled_tracks": table.meta.get("subsampled_tracks"),
        },
        "sumo_statistics": stats,
        "statistics": table_statistics(table),
        "npz_bytes": out.stat().st_size,
        "npz_sha256": sha256(out),
    }
    tmp_json = json_path.with_name(f".{json_path.name}.tmp")
    tmp_json.write_text(json.dumps(summary, indent=1, sort_keys=False) + "\n")
    os.replace(tmp_json, json_path)

    st = summary["statistics"]
    print(f"{out} ({size_mb:.2f} MB), {json_path.name}")
    print(f"{version}; seed {args.seed}; step {args.step_length:g} s; sumo ran {sim_seconds:.1f} s; "
          f"total {time.monotonic() - t_start:.1f} s")
    print(f"{st['tracks']} tracks, {st['rows']} rows, {st['total_duration_s'] / 3600:.2f} h; "
          f"{st['lane_changes']} lane changes; a quantiles 1/50/99 %: "
          f"{st['acceleration_quantiles']['0.01']} / {st['acceleration_quantiles']['0.5']} / "
          f"{st['acceleration_quantiles']['0.99']} m/s^2")
    return 0


if __name__ == "__main__":
    sys.exit(main())
