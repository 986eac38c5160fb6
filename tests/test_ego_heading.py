"""The ego's heading when iamp places it in SUMO (:meth:`Simulator.command`) and reads it back
(:meth:`Simulator.ego`), against a fake ``libsumo`` that keeps what it is told: a moving ego's front
bumper is half a length ahead along its velocity; a standing ego keeps its last heading (a residual
lateral speed once turned it by ~90° and moved its centre 2.4 m sideways when iamp took the wheel back
after an abort: the 341 m/s² "executed peaks" of the published campaign); a command read back gives
the same centre (hypothesis over states, standstill included). No SUMO needed."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.simulator import EGO, HEADING_MIN_SPEED, EgoState, Simulator


class _Vehicle:
    """The parts of ``libsumo.vehicle`` that ``command`` and ``ego`` use; it stores the pose."""

    def __init__(self) -> None:
        self.front = (0.0, 0.0)
        self.angle = 90.0  # SUMO: degrees clockwise from north; 90 = driving along +x
        self.speed = 0.0

    def moveToXY(self, vid, edge, lane, x, y, angle, keep):
        assert vid == EGO
        self.front, self.angle = (x, y), angle

    def setSpeedMode(self, vid, mode):
        pass

    def setSpeed(self, vid, v):
        self.speed = v

    def getPosition(self, vid):
        return self.front

    def getAngle(self, vid):
        return self.angle

    def getSpeed(self, vid):
        return self.speed

    def getLateralSpeed(self, vid):
        return 0.0

    def getAcceleration(self, vid):
        return 0.0


class _Libsumo:
    def __init__(self) -> None:
        self.vehicle = _Vehicle()


def _sim() -> Simulator:
    sim = Simulator(traffic="medium", seed=1)
    sim._ls = _Libsumo()
    return sim


def test_a_moving_ego_s_front_is_half_a_length_ahead_along_its_velocity():
    sim = _sim()
    sim.command(EgoState(x=600.0, vx=20.0, y=-2.0, vy=1.5, ax=0.0))
    psi = math.atan2(1.5, 20.0)
    fx, fy = sim._ls.vehicle.front
    assert fx == pytest.approx(600.0 + 2.4 * math.cos(psi), abs=1e-12)
    assert fy == pytest.approx(-2.0 + 2.4 * math.sin(psi), abs=1e-12)
    assert sim._ls.vehicle.angle == pytest.approx(90.0 - math.degrees(psi), abs=1e-12)


def test_a_standing_ego_keeps_its_heading_and_its_place():
    """The campaign's case: stopped by an abort (v_x = 0, v_y = -0.018 m/s), then driven again."""
    sim = _sim()
    sim.command(EgoState(x=677.0, vx=3.0, y=-9.36, vy=0.0, ax=0.0))  # moving along +x
    sim.command(EgoState(x=677.9, vx=0.0, y=-9.36, vy=-0.0176, ax=0.0))  # standing
    fx, fy = sim._ls.vehicle.front
    assert (fx, fy) == pytest.approx((677.9 + 2.4, -9.36), abs=1e-12)  # not (677.9, -11.76)
    back = sim.ego()
    assert (back.x, back.y) == pytest.approx((677.9, -9.36), abs=1e-9)


@settings(max_examples=300, deadline=None)
@given(st.floats(0.0, 40.0), st.floats(-3.0, 3.0), st.floats(-0.7, 0.7))
def test_a_command_read_back_gives_the_same_centre(vx, vy, heading):
    """Whatever the state (standstill included) and the heading SUMO had before, ``ego()`` after
    ``command(state)`` returns the commanded centre: no jump when iamp takes or keeps the wheel."""
    sim = _sim()
    sim._ls.vehicle.angle = 90.0 - math.degrees(heading)
    sim.ego()  # SUMO drove: its heading is the last one
    state = EgoState(x=650.0, vx=vx, y=-5.0, vy=vy, ax=0.0)
    sim.command(state)
    back = sim.ego()
    assert back.x == pytest.approx(650.0, abs=1e-9) and back.y == pytest.approx(-5.0, abs=1e-9)
    moving = math.hypot(vx, vy) >= HEADING_MIN_SPEED
    expected = math.atan2(vy, max(vx, 1e-6)) if moving else heading
    assert math.radians(90.0 - sim._ls.vehicle.angle) == pytest.approx(expected, abs=1e-9)
