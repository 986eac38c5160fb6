"""``scripts/jerk_sources.py``: every executed jerk violation counted once, attributed to who commanded it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

SPEC = importlib.util.spec_from_file_location("jerk_sources", Path(__file__).parents[1] / "scripts" / "jerk_sources.py")
assert SPEC is not None and SPEC.loader is not None
js = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(js)


def _positions(ax: np.ndarray, dt: float = 0.1) -> np.ndarray:
    """Positions of a car starting at 20 m/s whose acceleration over step k is ``ax[k]`` (exact)."""
    x, v, out = 0.0, 20.0, [0.0]
    for a in ax:
        x, v = x + v * dt + a * dt**2 / 2, v + a * dt
        out.append(x)
    return np.array(out)


@pytest.mark.parametrize(("modes_at_jump", "command_jump", "kind"), [
    ("active", 0.0, "plan"), ("seek", 0.0, "tactical"), ("sumo", 0.0, "sumo"),
    ("abort", 0.0, "urgent brake"), ("seek", -2.0, "urgent brake")])
def test_a_step_in_acceleration_is_one_violation_of_its_commander(modes_at_jump: str, command_jump: float,
                                                                   kind: str) -> None:
    """0 -> -2 m/s² from one period to the next: the monitor's second differences of the positions
    read 0, -1, -2 m/s² (each the mean of two periods' inputs), so two steps of 10 m/s³ (> 5), both
    attributed to the mode driving around them; a commanded drop larger than the rate limit is an
    urgent brake."""
    n = 40
    ax = np.where(np.arange(n) < 20, 0.0, -2.0)
    x = _positions(ax)
    modes = [modes_at_jump] * (n + 1)
    cmd = np.zeros(n + 1)
    cmd[21:] = command_jump
    by_kind, by_axis = js.classify(modes, cmd, x, np.zeros(n + 1))
    assert by_kind == {kind: 2}
    assert by_axis == {"x": 2}


def test_smooth_motion_and_mixed_modes() -> None:
    """A ramp within the bound (4 m/s³) has no violation; a jump where SUMO and iamp both drove the
    positions it is computed from is a hand-over."""
    n = 40
    ramp = np.clip(np.arange(n) * -0.4, -3.0, 0.0)  # 4 m/s³
    assert sum(js.classify(["active"] * (n + 1), np.zeros(n + 1), _positions(ramp), np.zeros(n + 1))[0].values()) == 0
    ax = np.where(np.arange(n) < 20, 0.0, -2.0)
    modes = ["sumo"] * 20 + ["seek"] * (n + 1 - 20)
    by_kind, _ = js.classify(modes, np.zeros(n + 1), _positions(ax), np.zeros(n + 1))
    assert by_kind == {"hand-over": 2}
