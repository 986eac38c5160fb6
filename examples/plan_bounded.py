"""
Plan within the car's limits
============================

The template scenario carries a ``[limits]`` table (SPEC §14): the longitudinal and lateral
acceleration ranges, a friction circle and a speed range. The bounded PMP saturates its input
(:math:`u = \\operatorname{sat}(-p_2, -p_4)`), the QP imposes every bound at each grid node;
both report their exact peaks against the bounds.

Run: ``python examples/plan_bounded.py``
"""

from __future__ import annotations

import io
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
from matplotlib.figure import Figure

import iamp
from iamp.cli.plot import plan_figure


def show(fig: Figure) -> None:
    """Show a figure made outside pyplot (``iamp plot``'s) in a pyplot window / the gallery."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    buf.seek(0)
    _, ax = plt.subplots(figsize=(fig.get_figwidth(), fig.get_figheight()))
    ax.imshow(plt.imread(buf))
    ax.set_axis_off()


def main() -> dict[str, iamp.Plan]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bounded.toml"
        # the commented scenario `iamp template` prints: it has a [limits] table
        path.write_text(subprocess.run([sys.executable, "-m", "iamp", "template"], check=True, capture_output=True,
                                       text=True, encoding="utf-8").stdout)
        problem = iamp.load_scenario(str(path))
    print("limits:", problem.limits)
    plans = {"pmp": iamp.plan(problem), "qp": iamp.plan(problem, "qp", solver="clarabel", steps=100)}
    for name, plan in plans.items():
        print(f"{name:4s} {plan.status:8s} J = {plan.cost:.6f}")
        print("     peaks:", plan.peaks.line())
    fig = plan_figure(plans["pmp"], title="the template scenario with its limits: bounded PMP")
    show(fig)
    return plans


if __name__ == "__main__":
    main()
