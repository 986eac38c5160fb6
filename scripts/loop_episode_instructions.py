"""Machine instructions of one closed-loop episode, counted by valgrind's callgrind.

The episode is ``iamp bench``'s loop case (:data:`iamp.comparison.bench.loop.CASE`: the merge
mission, dense traffic, seed 1, 60 s) for one planner, run as the bench runs it
(:func:`iamp.comparison.bench.loop.forget_kept_data` before each episode).  The count covers one
``run_episode`` call after a warm-up episode in the same process (collection switched on with
``callgrind_control -i on`` between them), so that it does not count imports, SUMO's start-up or the
first episode's caches; it includes SUMO's own step, the predictor, the controller and the planner.
CPU times on a shared machine move by 10-50 % between runs; the count does not depend on the load.
Needs valgrind (Debian: ``apt install valgrind``) and ``iamp[sim]``; about 10-20 minutes.  For
before/after comparisons run it on two checkouts (``PYTHONPATH=CHECKOUT``, from another folder)::

    python scripts/loop_episode_instructions.py pmp
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

_INSIDE = "IAMP_EPISODE_UNDER_CALLGRIND"


def _episode(planner: str) -> None:
    """Runs under callgrind: a warm-up episode uncounted, then one counted."""
    from iamp.comparison.bench import loop
    from iamp.planners.kernels import warm_kernels

    warm_kernels()
    loop.forget_kept_data()
    loop._episode(planner)
    loop.forget_kept_data()
    pid = str(os.getpid())
    subprocess.run(["callgrind_control", "-i", "on", pid], check=True, capture_output=True)
    summary = loop._episode(planner).summary
    subprocess.run(["callgrind_control", "-i", "off", pid], check=True, capture_output=True)
    print(f"{summary['planner_calls']} planner calls, success {summary['success']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("planner", choices=("pmp", "qp", "pmp-active", "qp-avoid", "free"))
    args = ap.parse_args()
    if os.environ.get(_INSIDE):
        _episode(args.planner)
        return
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        run = subprocess.run(["valgrind", "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={out}",
                              sys.executable, __file__, args.planner],
                             env={**os.environ, _INSIDE: "1"}, capture_output=True, text=True)
        if run.returncode != 0 or not out.exists():
            sys.exit(f"valgrind failed (exit {run.returncode}): {run.stderr.strip().splitlines()[-1:]}")
        totals = re.findall(r"^totals:\s+(\d+)", out.read_text(), re.MULTILINE)
        if not totals:
            sys.exit(f"no instruction count in {out}")
    print(f"{sum(int(t) for t in totals) / 1e6:.1f} million instructions per episode ({args.planner}); "
          f"{run.stdout.strip()}")


if __name__ == "__main__":
    main()
