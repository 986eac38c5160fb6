"""The numbers the README's campaign section quotes, recomputed from a campaign's ``episodes.csv``.

Usage::

    python scripts/campaign_readme.py reports/campaign-new/episodes.csv [--wall-from SEED]

Prints (markdown) the success table per mission (Wilson 95 % over the densities), the contact
episodes, the merge's hard brakes of the new follower, and the paired comparisons the README
cites (exact McNemar p and paired-bootstrap 95 % intervals from :mod:`iamp.simulation.stats`;
paired by ``(traffic, seed)``), plus the medians of time to merge, executed peak, plan time and
wall time per episode (``--wall-from``: the wall time of the seeds from SEED on only, e.g. those
one version of the code made).  Nothing here is typed in by hand: the README's numbers are this output.
"""

from __future__ import annotations

import csv
import statistics
import sys
from collections import defaultdict
from typing import Any

from iamp.simulation.stats import EVENTS, paired, wilson

MISSIONS = ("merge", "onramp", "slow-leader", "discretionary")
PLANNERS = ("pmp", "qp", "pmp-active", "qp-avoid", "free", "mobil", "sumo")
#: (mission, reference, other): the pairs the README quotes.
PAIRS = [("merge", "pmp", p) for p in ("qp", "pmp-active", "qp-avoid", "free", "mobil", "sumo")] + [
    ("merge", "free", "pmp-active"), ("merge", "qp-avoid", "pmp-active"),
    *[(m, "qp-avoid", "pmp-active") for m in ("onramp", "slow-leader", "discretionary")],
    ("onramp", "pmp", "qp")]


def pct(k: int, n: int) -> str:
    lo, hi = wilson(k, n)
    return f"{k}/{n} [{100 * lo:.0f}, {100 * hi:.0f}] %"


def interval(d: dict[str, Any], scale: float = 100.0, unit: str = "pp", digits: int = 0) -> str:
    if d.get("diff") is None:
        return "n/a"
    lo, hi = d["ci"]
    f = f"{{:+.{digits}f}}"
    out = f"{f.format(scale * d['diff'])} {unit} [{f.format(scale * lo)}, {f.format(scale * hi)}]"
    return out + (f", p = {d['p']:.2g}" if "p" in d else f" (n = {d['n']})")


def median_of(eps: list[dict[str, Any]], key: str, only_success: bool = False, first_seed: int = 0) -> str:
    """The median of column ``key`` over ``eps`` (successes only; seeds from ``first_seed`` on)."""
    vals = [float(r[key]) for r in eps if r.get(key) not in ("", None, "None")
            and (not only_success or EVENTS["success"](r)) and int(r["seed"]) >= first_seed]
    return f"{statistics.median(vals):.3g}" if vals else "–"


def main(path: str, wall_from: int = 0) -> int:
    rows = list(csv.DictReader(open(path, newline="")))
    by: dict[tuple[str, str], dict[tuple[str, int], dict[str, Any]]] = defaultdict(dict)
    for r in rows:
        by[(r["mission"], r["planner"])][(r["traffic"], int(r["seed"]))] = r
    seeds = sorted({int(r["seed"]) for r in rows})
    print(f"{len(rows)} episodes, seeds {seeds[0]}..{seeds[-1]} ({len(seeds)}), "
          f"{len({r['traffic'] for r in rows})} densities\n")
    print("| planner | " + " | ".join(MISSIONS) + " | contacts (all) | new follower brakes > 4.5 m/s² (merge) |")
    print("|---" * (len(MISSIONS) + 3) + "|")
    for p in PLANNERS:
        cells = []
        contact = total = 0
        for m in MISSIONS:
            eps = list(by[(m, p)].values())
            cells.append(pct(sum(EVENTS["success"](r) for r in eps), len(eps)))
            contact += sum(EVENTS["contact"](r) for r in eps)
            total += len(eps)
        merge = list(by[("merge", p)].values())
        hard = sum(EVENTS["hard_brake"](r) for r in merge)
        print(f"| {p} | " + " | ".join(cells) + f" | {contact}/{total} | {hard}/{len(merge)} |")
    print("\nContacts per mission:")
    for p in PLANNERS:
        print(f"- {p}: " + ", ".join(f"{m} {sum(EVENTS['contact'](r) for r in by[(m, p)].values())}"
                                      for m in MISSIONS))
    print("\nPaired (other - reference):")
    for m, ref, other in PAIRS:
        res = paired(by[(m, ref)], by[(m, other)])
        print(f"- {m}: {other} vs {ref} ({res['pairs']} pairs): success {interval(res['success'])}; "
              f"contact {interval(res['contact'])}; hard brake {interval(res['hard_brake'])}; "
              f"follower decel {interval(res['follower_max_decel'], 1.0, 'm/s²', 2)}; "
              f"t_merge {interval(res['time_to_merge_s'], 1.0, 's', 2)}; "
              f"executed peak {interval(res['ego_peak_accel'], 1.0, 'm/s²', 2)}")
    print("\nMedians per planner (all missions):")
    for p in PLANNERS:
        eps = [r for m in MISSIONS for r in by[(m, p)].values()]

        print(f"- {p}: t_merge {median_of(eps, 'time_to_merge_s', True)} s, follower decel "
              f"{median_of(eps, 'follower_max_decel')} m/s², executed peak |a| "
              f"{median_of(eps, 'ego_peak_accel')} m/s², "
              f"plan p50 {median_of(eps, 'plan_time_p50_s')} s, "
              f"wall per episode {median_of(eps, 'wall_total_s', first_seed=wall_from)} s"
              + (f" (seeds >= {wall_from})" if wall_from else ""))
    return 0


if __name__ == "__main__":
    argv = sys.argv[1:]
    wall = 0
    if "--wall-from" in argv:
        i = argv.index("--wall-from")
        wall = int(argv[i + 1])
        del argv[i:i + 2]
    sys.exit(main(argv[0] if argv else "reports/campaign-new/episodes.csv", wall))
