"""``episodes.csv`` in the grid's order once a campaign has finished (``sort_episodes``): episodes
are appended as the workers finish them, so without the sort the same command wrote its rows in
another order on another run (``iamp reproduce``'s campaign-small: ``pmp`` and ``pmp-active``
swapped between two runs of the same commit)."""

from __future__ import annotations

import csv
import io
import random
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.campaign import sort_episodes

MISSIONS, PLANNERS, TRAFFICS = ["merge", "onramp"], ["pmp", "qp-avoid", "free"], ["medium", "dense"]
HEADER = ["mission", "planner", "traffic", "seed", "success", "note"]


def grid() -> list[dict[str, str]]:
    return [{"mission": m, "planner": p, "traffic": t, "seed": str(s), "success": str(s % 2 == 0),
             "note": f"a, {m}"}  # a comma: the writer quotes it, the rewrite keeps it
            for s in (1, 2, 10) for m in MISSIONS for t in TRAFFICS for p in PLANNERS]


def write(path: Path, rows: list[dict[str, str]]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=HEADER, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    path.write_text(buf.getvalue(), encoding="utf-8")


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_any_completion_order_gives_the_grid_order(tmp_path_factory, seed: int) -> None:
    tmp = tmp_path_factory.mktemp("c")
    expected = grid()  # seed, then mission, traffic, planner (numeric seeds: 10 after 2)
    shuffled = expected[:]
    random.Random(seed).shuffle(shuffled)
    a, b = tmp / "a.csv", tmp / "b.csv"
    write(a, shuffled)
    write(b, expected)
    sort_episodes(a, MISSIONS, PLANNERS, TRAFFICS)
    assert a.read_bytes() == b.read_bytes()
    before = b.read_bytes()
    sort_episodes(b, MISSIONS, PLANNERS, TRAFFICS)  # already in order: the same bytes
    assert b.read_bytes() == before


def test_values_outside_the_grid_come_last_and_a_missing_file_is_left_alone(tmp_path: Path) -> None:
    rows = [{"mission": "slow-leader", "planner": "pmp", "traffic": "medium", "seed": "1", "success": "1", "note": ""},
            {"mission": "merge", "planner": "sumo", "traffic": "medium", "seed": "1", "success": "1", "note": ""},
            {"mission": "merge", "planner": "free", "traffic": "medium", "seed": "1", "success": "1", "note": ""}]
    path = tmp_path / "episodes.csv"
    write(path, rows)
    sort_episodes(path, MISSIONS, PLANNERS, TRAFFICS)
    got = [(r["mission"], r["planner"]) for r in csv.DictReader(io.StringIO(path.read_text(encoding="utf-8")))]
    assert got == [("merge", "free"), ("merge", "sumo"), ("slow-leader", "pmp")]
    sort_episodes(tmp_path / "none.csv", MISSIONS, PLANNERS, TRAFFICS)
    assert not (tmp_path / "none.csv").exists()
