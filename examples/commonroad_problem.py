"""
Solve a CommonRoad problem from recorded US-101 traffic
=======================================================

CommonRoad is how this field compares motion planners. ``iamp commonroad plan`` reads a
scenario (the road, the recorded vehicles, the planning problem with its goal region), plans in
a road-aligned frame with the active set and the avoidance QP, writes a CommonRoad solution and
reports CommonRoad's costs; ``iamp commonroad check`` asks CommonRoad's own checker for the
verdict. Needs the ``[commonroad]`` extra and the recorded scenarios (the folder named by
``IAMP_DATA``, else ``../shared/data`` beside the repository); without them it says so and stops.

Run: ``python examples/commonroad_problem.py``
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
from PIL import Image

HERE = Path(__file__).resolve().parent if "__file__" in globals() else Path.cwd()


def data_folder() -> Path:
    """The recorded CommonRoad US-101 scenarios (``$IAMP_DATA/commonroad/US101``)."""
    root = Path(os.environ.get("IAMP_DATA", HERE.parent.parent / "shared" / "data"))
    return root / "commonroad" / "US101"


def main() -> dict[str, object] | None:
    folder = data_folder()
    if importlib.util.find_spec("commonroad") is None or not folder.is_dir():
        print(f"skipped: needs pip install 'iamp[commonroad]' and the scenarios in {folder}")
        return None
    scenario = sorted(folder.glob("*.xml"))[0]
    with tempfile.TemporaryDirectory() as tmp:
        solution = Path(tmp) / "solution.xml"
        run = subprocess.run([sys.executable, "-m", "iamp", "commonroad", "plan", str(scenario), "--out",
                              str(solution), "--json"], check=True, capture_output=True, text=True, encoding="utf-8")
        result = json.loads(run.stdout)
        print(f"{scenario.name}: {result['status']}, horizon {result['tf']} s, costs {result['costs']}")
        check = subprocess.run([sys.executable, "-m", "iamp", "commonroad", "check", str(scenario), str(solution)],
                               capture_output=True, text=True, encoding="utf-8")
        print(check.stdout.strip())
        gif = Path(tmp) / "solution.gif"
        subprocess.run([sys.executable, "-m", "iamp", "plot", "--commonroad", str(scenario), "--solution",
                        str(solution), "--out", str(gif), "--fps", "2"], check=True, capture_output=True)
        with Image.open(gif) as im:  # the last frame of the animation, shown in the gallery
            im.seek(im.n_frames - 1)
            frame = im.convert("RGB")
    _, ax = plt.subplots(figsize=(8, 6.5))
    ax.imshow(frame)
    ax.set_axis_off()
    return {"plan": result, "check": check.stdout, "returncode": check.returncode}


if __name__ == "__main__":
    main()
