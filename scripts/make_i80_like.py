"""Write the I-80-like traffic of :mod:`iamp.prediction.leader.synthetic` as an NGSIM CSV.

Usage: ``python scripts/make_i80_like.py OUT.csv.gz [--seed S]`` (refuses to overwrite without ``--force``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from iamp.prediction.leader.synthetic import i80_like, write_ngsim_csv


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("out")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lanes", type=int, default=4)
    ap.add_argument("--duration", type=float, default=420.0, help="simulated seconds (default 420)")
    ap.add_argument("--force", action="store_true")
    a = ap.parse_args(argv)
    out = Path(a.out)
    if out.exists() and not a.force:
        print(f"iamp: error: {out}: exists (use --force to replace it)", file=sys.stderr)
        return 2
    tr = i80_like(a.seed, lanes=a.lanes, duration_s=a.duration)
    write_ngsim_csv(out, tr)
    print(f"wrote {out}: {tr.x_true.shape[1]} vehicles, seed {a.seed}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
