"""The steered solution (SPEC §16b, issue 33 item 3): a road-frame plan converted to CommonRoad's
kinematic single-track model ``KS`` (:mod:`iamp.commonroad.ks`) that the drivability checker's own
``KS`` feasibility test accepts, written with its benchmark ID.

The synthetic tests need the ``[commonroad]`` extra only (a lane change on a fitted road, no data);
the US-101 ones also the shared scenarios, and skip with the reason where either is absent.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import numpy.typing as npt
import pytest
from conftest import HAVE_COMMONROAD, data_path, needs_commonroad, needs_commonroad_data
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from iamp.commonroad.frame import RoadFrame

DATA = data_path("commonroad", "US101")
HAVE_EXTRA = HAVE_COMMONROAD
needs_extra = needs_commonroad
needs_data = needs_commonroad_data("commonroad", "US101")


class LaneChange:
    """A road-frame plan: speed ``v0 + a t``, a quintic lateral move of ``dy`` over ``T``."""

    def __init__(self, v0: float, a: float, dy: float, T: float) -> None:
        self.v0, self.a, self.dy, self.T = v0, a, dy, T

    def states(self, t: npt.ArrayLike) -> npt.NDArray[np.float64]:
        t = np.asarray(t, dtype=float)
        r = np.clip(t / self.T, 0.0, 1.0)
        y = self.dy * (10 * r**3 - 15 * r**4 + 6 * r**5)
        vy = self.dy * (30 * r**2 - 60 * r**3 + 30 * r**4) / self.T
        return np.column_stack([self.v0 * t + 0.5 * self.a * t * t, self.v0 + self.a * t, y, vy])

    def inputs(self, t: npt.ArrayLike) -> npt.NDArray[np.float64]:
        t = np.asarray(t, dtype=float)
        return np.zeros((len(t), 2))


def _problem(angle: float, bend: float, v0: float) -> SimpleNamespace:
    """What :func:`iamp.commonroad.ks.track` reads of a CommonRoadProblem: a fitted road frame,
    ``dt`` and the planning problem's initial state (centre at the frame's origin, along the road)."""
    u = np.linspace(-20.0, 400.0, 120)
    w = bend * 1e-4 * u**2
    c, s = math.cos(angle), math.sin(angle)
    frame = RoadFrame.fit(np.c_[u * c - w * s, u * s + w * c])
    p0 = frame.to_world(0.0, 0.0)[0]
    init = SimpleNamespace(position=p0, orientation=float(frame.heading(0.0)), velocity=v0)
    return SimpleNamespace(frame=frame, dt=0.1, planning_problem=SimpleNamespace(initial_state=init))


def _checker_accepts(states: list[object], vehicle_type: int) -> bool:
    from commonroad.common.solution import VehicleType
    from commonroad.scenario.trajectory import Trajectory
    from commonroad_dc.feasibility.feasibility_checker import trajectory_feasibility
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleDynamics

    dyn = VehicleDynamics.KS(VehicleType(vehicle_type))
    ok, _ = trajectory_feasibility(Trajectory(0, states), dyn, 0.1)
    return bool(ok)


@needs_extra
@settings(max_examples=4, deadline=None, derandomize=True)
@example(angle=0.3, bend=0.5, v0=2.0, a=0.0, dy=0.5, T=3.0, vtype=2)  # 1.17 m off with the centre's heading
@given(angle=st.floats(-math.pi, math.pi), bend=st.floats(-1.0, 1.0), v0=st.floats(1.0, 30.0),
       a=st.floats(-1.0, 1.0), dy=st.floats(-4.0, 4.0), T=st.floats(3.0, 6.0), vtype=st.sampled_from([1, 2, 3]))
def test_ks_tracks_a_lane_change_and_the_checker_accepts_every_step(angle: float, bend: float, v0: float, a: float,
                                                                  dy: float, T: float, vtype: int) -> None:
    """A lane change of up to 4 m in 3-6 s at 1-30 m/s, peak heading off the road at most 20 deg, on a
    road of any heading and gentle bend:
    every KS step is the checker's own simulation (odeint) of an input inside the type's bounds and
    friction circle, the checker's ``trajectory_feasibility`` accepts the whole trajectory, the
    first state is the planning problem's, and the centre stays within 5 cm of the plan (at low
    speed only with the rear axle's heading integrated: the centre's own heading put the rear axle
    1.17 m off on the explicit example)."""
    from commonroad.common.solution import VehicleType
    from commonroad.scenario.state import KSState
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleDynamics, VehicleParameterMapping

    from iamp.commonroad.ks import track

    # the claim's domain: the car keeps moving forward (at least 1 m/s over the whole plan; a plan
    # whose speed v0 + a t turns negative drives backwards, which a KS car tracking forward cannot),
    # and the lane change's peak heading off the road, atan(1.875 dy / (T v)) for the quintic
    # profile at its lowest speed v, is at most 0.35 rad (20 deg): a 1 m shift in 3 s at 1 m/s
    # (32 deg) is beyond a steered car's tracking to 5 cm (hypothesis found 0.59 m there)
    v_low = min(v0, v0 + a * (T + 1.0))
    assume(v_low >= 1.0 and 1.875 * abs(dy) / (T * v_low) <= 0.35)
    cr = _problem(angle, bend, v0)
    steps = int(round((T + 1.0) / 0.1))
    ks = track(cr, LaneChange(v0, a, dy, T), steps, vtype)  # type: ignore[arg-type]
    p = VehicleParameterMapping.from_vehicle_type(VehicleType(vtype))
    dyn = VehicleDynamics.KS(VehicleType(vtype))
    assert np.all(np.abs(ks.inputs[:, 0]) <= p.steering.v_max)
    assert np.all(np.abs(ks.inputs[:, 1]) <= p.longitudinal.a_max)
    for k in range(steps):
        assert not dyn.violates_friction_circle(ks.states[k], ks.inputs[k])
        assert np.allclose(dyn.forward_simulation(ks.states[k], ks.inputs[k], 0.1), ks.states[k + 1], atol=1e-9)
    assert np.allclose(ks.centre[0], cr.planning_problem.initial_state.position, atol=1e-9)
    assert ks.states[0, 3] == v0 and ks.states[0, 4] == pytest.approx(cr.planning_problem.initial_state.orientation)
    assert ks.deviation_m < 0.05
    states = [KSState(time_step=k, position=ks.centre[k], steering_angle=float(ks.states[k, 2]),
                      velocity=float(ks.states[k, 3]), orientation=float(ks.states[k, 4])) for k in range(steps + 1)]
    assert _checker_accepts(states, vtype)


@needs_extra
def test_unknown_vehicle_type_is_refused() -> None:
    from iamp.commonroad.ks import track
    from iamp.core.errors import ScenarioError

    with pytest.raises(ScenarioError, match="vehicle type 4"):
        track(_problem(0.0, 0.0, 10.0), LaneChange(10.0, 0.0, 0.0, 3.0), 10, 4)  # type: ignore[arg-type]


@needs_data
@pytest.mark.slow  # 30-40 s each on a loaded 2-core machine; the fast end-to-end KS test is in test_commonroad_bench
@pytest.mark.parametrize("name", ["USA_US101-17_1_T-1", "USA_US101-24_1_T-1"])
def test_plan_cli_writes_a_valid_ks_solution(name: str, tmp_path: Path) -> None:
    """``iamp commonroad plan --vehicle-model KS`` on US-101 problems (one with a vehicle imposed,
    one with the largest tracking deviation measured): the written solution is a ``KS`` trajectory
    with benchmark ID ``KS2:TR1:<scenario>:2020a`` and ``iamp commonroad check`` (every check of
    the drivability checker, the KS feasibility test among them) says valid."""
    out = tmp_path / "sol.xml"
    base = [sys.executable, "-W", "ignore", "-m", "iamp", "commonroad"]
    r = subprocess.run([*base, "plan", str(DATA / f"{name}.xml"), "--vehicle-model", "KS", "--cost-function", "TR1",
                        "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr[-2000:]
    text = out.read_text()
    assert f'benchmark_id="KS2:TR1:{name}:2020a"' in text and "<ksTrajectory" in text
    c = subprocess.run([*base, "check", str(DATA / f"{name}.xml"), str(out)], capture_output=True, text=True,
                       timeout=600)
    assert c.returncode == 0, c.stdout
    assert "kinematically_feasible     pass" in c.stdout and "valid_solution (raw)       yes" in c.stdout
