"""CPU time of everyday ``iamp`` commands against a bare ``import numpy, scipy.linalg``.

Issue 22 item 10: ``plan``, ``predict`` and ``scenarios`` should cost at most 1.5x that import.
Each command runs in a fresh interpreter ``--repeats`` times; the CPU time (user + system, from
``getrusage(RUSAGE_CHILDREN)``) is the median.  A ratio, not a wall time: it does not depend on
the load of the machine as much.  ``tests/test_issue22.py::test_item10_*`` checks the cause (no
heavy module imported), this script the effect::

    python scripts/startup_cpu.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys

COMMANDS = (["plan", "paper-1-poly", "--json"], ["predict", "paper-2", "--json"], ["scenarios"])


def cpu_seconds(argv: list[str], repeats: int) -> float:
    """Median CPU seconds of ``argv`` run ``repeats`` times."""
    times = []
    for _ in range(repeats):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        times.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    base = cpu_seconds([sys.executable, "-c", "import numpy, scipy.linalg"], args.repeats)
    print(f"import numpy, scipy.linalg: {base:.3f} s CPU (median of {args.repeats})")
    worst = 0.0
    for cmd in COMMANDS:
        c = cpu_seconds([sys.executable, "-m", "iamp", *cmd], args.repeats)
        worst = max(worst, c / base)
        print(f"iamp {' '.join(cmd):28s} {c:.3f} s CPU  {c / base:.2f}x")
    print(f"worst {worst:.2f}x (target <= 1.5x)")
    return 0 if worst <= 1.5 else 1


if __name__ == "__main__":
    raise SystemExit(main())
