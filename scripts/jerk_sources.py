"""Where the executed jerk violations of closed-loop episodes come from (issue 30, SPEC §17).

The monitor (``simulation/monitor.py``) counts ``jerk_violations``: steps at which the executed
jerk, the difference of two consecutive executed accelerations ``a_k = (s_{k+1} - 2 s_k +
s_{k-1})/Δt²`` divided by ``Δt``, exceeds the car's bound (5 m/s³) on either axis.  This script
reads step logs (``iamp simulate ... --log steps.csv``) and attributes every such step to who
commanded the four positions it is computed from (log steps ``k-1 .. k+2`` of the violation
between ``a_k`` and ``a_{k+1}``):

``sumo``
    SUMO's driver moved the ego at every one of them (before iamp takes control, after it
    hands over);
``hand-over``
    SUMO and iamp both (the step at which control changes hands);
``urgent brake``
    iamp, with an urgent brake among them: the fail-safe (mode ``abort``) or a commanded
    deceleration step larger than the rate limit (RSS's proper response, applied at once by
    design, ``Controller._move``);
``mode switch``
    iamp, in two of its modes (``seek``/``active``/``done``/``hold``), no urgent brake;
``plan``
    iamp executing a plan (mode ``active``) throughout;
``tactical``
    iamp's tactical layer (``seek``, ``done``, ``hold``) throughout.

Usage (from the repository root)::

    python scripts/jerk_sources.py run OUT_DIR [--seeds 1-5] [--planners pmp-active,qp-avoid,free]
        [--missions merge,onramp,slow-leader] [--traffic medium,dense,los-e] [--cooperation default]
    python scripts/jerk_sources.py table OUT_DIR        # the table (Markdown) from the logs in OUT_DIR

``run`` writes one ``<mission>-<traffic>-<planner>-<seed>.csv`` step log and ``.json`` episode
per episode (``iamp simulate``; existing files are kept, so it resumes) and then the table.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

from iamp.core.physical import PASSENGER_CAR
from iamp.simulation.controller import JERK_SHARE

KINDS = ("sumo", "hand-over", "urgent brake", "mode switch", "plan", "tactical")
DT = 0.1  # the closed loop's period [s]
JERK = float(PASSENGER_CAR.jerk or 5.0)  # the car's jerk bound, the monitor's [m/s³]


def classify(modes: list[str], ax_cmd: np.ndarray, x: np.ndarray, y: np.ndarray, dt: float = DT,
             jerk: float = JERK) -> tuple[Counter[str], Counter[str]]:
    """Count the jerk violations of one episode by source and by axis.

    Parameters
    ----------
    modes : list of str
        The controller's mode at each log step (``sumo`` where SUMO drives the ego).
    ax_cmd : numpy.ndarray
        The ego's state ``a_x`` at each log step (the input iamp applied; ``nan`` where none).
    x, y : numpy.ndarray
        The executed centre positions at each log step [m].

    Returns
    -------
    tuple of collections.Counter
        ``(by source, by axis)``; the counts sum to the monitor's ``jerk_violations``.
    """
    ax = (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2
    ay = (y[2:] - 2 * y[1:-1] + y[:-2]) / dt**2
    jx, jy = np.abs(np.diff(ax)) / dt, np.abs(np.diff(ay)) / dt
    by_kind: Counter[str] = Counter()
    by_axis: Counter[str] = Counter()
    for i in np.flatnonzero((jx > jerk) | (jy > jerk)):
        lo, hi = max(int(i), 0), min(int(i) + 3, len(modes) - 1)  # positions i .. i+3: commands i-1 .. i+2
        ms = set(modes[max(lo - 1, 0):hi])
        cmd = ax_cmd[max(lo - 1, 0):hi + 1]
        drops = np.diff(cmd[np.isfinite(cmd)])
        if ms == {"sumo"}:
            kind = "sumo"
        elif "sumo" in ms:
            kind = "hand-over"
        elif "abort" in ms or (drops.size and drops.min() < -JERK_SHARE * jerk * dt - 1e-9):  # beyond _move's rate
            kind = "urgent brake"
        elif len(ms) > 1:
            kind = "mode switch"
        elif ms == {"active"}:
            kind = "plan"
        else:
            kind = "tactical"
        by_kind[kind] += 1
        by_axis["x" if jx[i] > jerk and not jy[i] > jerk else "y" if not jx[i] > jerk else "both"] += 1
    return by_kind, by_axis


def read_log(path: Path) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """The ego's rows of a step log: modes, state ``a_x``, ``x``, ``y``."""
    rows = [r for r in csv.DictReader(path.open()) if r["vehicle"] == "ego"]
    f = [float(r["ax"]) if r["ax"] not in ("", "nan") else np.nan for r in rows]
    return ([r["mode"] for r in rows], np.array(f), np.array([float(r["x"]) for r in rows]),
            np.array([float(r["y"]) for r in rows]))


def table(out: Path) -> str:
    """The Markdown table of every step log in ``out`` (per planner), checked against the episodes' counts."""
    per: dict[str, Counter[str]] = {}
    axes: dict[str, Counter[str]] = {}
    episodes: Counter[str] = Counter()
    with_any: Counter[str] = Counter()
    for log in sorted(out.glob("*.csv")):
        ep = json.loads(log.with_suffix(".json").read_text())
        planner = ep["planner"]
        kinds, axis = classify(*read_log(log))
        if sum(kinds.values()) != ep["jerk_violations"]:
            raise SystemExit(f"{log}: {sum(kinds.values())} violations classified, the monitor counts "
                             f"{ep['jerk_violations']}")
        per.setdefault(planner, Counter()).update(kinds)
        axes.setdefault(planner, Counter()).update(axis)
        episodes[planner] += 1
        with_any[planner] += bool(ep["jerk_violations"])
    head = ("| planner | episodes | with a violation | steps | " + " | ".join(KINDS)
            + " | x only / y only / both |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for p in sorted(per):
        c, a = per[p], axes[p]
        lines.append(f"| {p} | {episodes[p]} | {with_any[p]} | {sum(c.values())} | "
                     + " | ".join(str(c[k]) for k in KINDS) + f" | {a['x']} / {a['y']} / {a['both']} |")
    return "\n".join(lines)


def _range(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("out", type=Path)
    r.add_argument("--seeds", default="1-5")
    r.add_argument("--planners", default="pmp-active,qp-avoid,free")
    r.add_argument("--missions", default="merge,onramp,slow-leader")
    r.add_argument("--traffic", default="medium,dense,los-e")
    r.add_argument("--cooperation", default="default")
    t = sub.add_parser("table")
    t.add_argument("out", type=Path)
    a = ap.parse_args(argv)
    if a.cmd == "run":
        a.out.mkdir(parents=True, exist_ok=True)
        for m in a.missions.split(","):
            for tr in a.traffic.split(","):
                for p in a.planners.split(","):
                    for s in _range(a.seeds):
                        stem = a.out / f"{m}-{tr}-{p}-{s}"
                        if stem.with_suffix(".json").exists():
                            continue
                        cmd = [sys.executable, "-m", "iamp", "simulate", "--mission", m, "--traffic", tr,
                               "--planner", p, "--seed", str(s), "--cooperation", a.cooperation,
                               "--log", str(stem.with_suffix(".csv")), "--json"]
                        res = subprocess.run(cmd, capture_output=True, text=True, check=False)
                        if res.returncode != 0:
                            print(f"{stem.name}: exit {res.returncode}: {res.stderr.strip()[-200:]}", file=sys.stderr)
                            continue
                        stem.with_suffix(".json").write_text(res.stdout)
    print(table(a.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
