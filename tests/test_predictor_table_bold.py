"""Issue 29 item 17: Table 8's caption promises the best value of every column in bold (ADE and FDE too)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from iamp.prediction.evaluation.report import rmse_table_tex

ROOT = Path(__file__).resolve().parents[1]


def test_every_column_bolds_exactly_its_best_printed_value() -> None:
    res = json.loads((ROOT / "reports" / "predictor_eval.json").read_text(encoding="utf-8"))
    rows = [line for line in rmse_table_tex(res).splitlines() if line.count("&") == 7 and "Method" not in line]
    assert rows
    cells = [[c.strip().rstrip("\\").strip() for c in row.split("&")[1:]] for row in rows]
    for j in range(7):
        column = cells and [c[j] for c in cells]
        values = [float(re.sub(r"\\textbf\{(.*)\}", r"\1", c)) for c in column]
        best = min(values)
        for c, v in zip(column, values):
            assert c.startswith("\\textbf{") == (f"{v:.2f}" == f"{best:.2f}"), (j, c)
