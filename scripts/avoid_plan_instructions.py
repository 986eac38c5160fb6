"""Machine instructions per continuous-time avoidance plan, counted by valgrind's callgrind.

The CPU times of ``scripts/avoid_plan_cpu.py`` move by 10-30 % between runs on a shared machine;
the count of instructions executed does not depend on the load.  This script plans the same
problems as ``avoid_plan_cpu.py`` (the overtake, ``one`` or ``three`` vehicles, FOH, ``N = 50``,
``--safety continuous``, the planner's vehicles forgotten before each plan) under ``valgrind
--tool=callgrind`` with collection switched off until the warm-up plans are done
(``callgrind_control -i on``), and prints the instructions per plan.  Counts include numpy,
scipy, the backend and the compiled kernels; they are repeatable to about 0.1 % (allocation
addresses differ).  Needs valgrind (Debian: ``apt install valgrind``); about 7 minutes, most of
it importing under valgrind.  For before/after comparisons run it on two checkouts
(``PYTHONPATH=CHECKOUT``, from another folder)::

    python scripts/avoid_plan_instructions.py one piqp
    python scripts/avoid_plan_instructions.py three clarabel --plans 3
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

# the same planner, problem and command line as the CPU-time script (this folder is on sys.path)
from avoid_plan_cpu import case_arguments, planner_and_problem

_INSIDE = "IAMP_UNDER_CALLGRIND"


def _plans(case: str, solver: str, plans: int) -> None:
    """Runs under callgrind: warm-up uncounted, then ``plans`` counted plans."""
    planner, problem = planner_and_problem(case, solver)
    for _ in range(2):
        planner.forget_vehicles()
        planner.plan(problem)
    pid = str(os.getpid())
    subprocess.run(["callgrind_control", "-i", "on", pid], check=True, capture_output=True)
    for _ in range(plans):
        planner.forget_vehicles()
        plan = planner.plan(problem)
    subprocess.run(["callgrind_control", "-i", "off", pid], check=True, capture_output=True)
    print(f"{plan.status}, cost {plan.cost}, {plan.diagnostics.n_solves} QP solves")


def main() -> None:
    args = case_arguments(__doc__.splitlines()[0], 5)
    if os.environ.get(_INSIDE):
        _plans(args.case, args.solver, max(1, args.plans))
        return
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        env = {**os.environ, _INSIDE: "1"}
        run = subprocess.run(["valgrind", "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={out}",
                              sys.executable, __file__, args.case, args.solver, "--plans", str(args.plans)],
                             env=env, capture_output=True, text=True)
        if run.returncode != 0 or not out.exists():
            sys.exit(f"valgrind failed (exit {run.returncode}): {run.stderr.strip().splitlines()[-1:]}")
        # "totals:" holds what was collected ("summary:" is 0 with collection off at the start)
        totals = re.findall(r"^totals:\s+(\d+)", out.read_text(), re.MULTILINE)
        if not totals:
            sys.exit(f"no instruction count in {out}")
        per_plan = sum(int(t) for t in totals) / max(1, args.plans)
    print(f"{per_plan / 1e6:.2f} million instructions per plan over {args.plans} plans; {run.stdout.strip()}")


if __name__ == "__main__":
    main()
