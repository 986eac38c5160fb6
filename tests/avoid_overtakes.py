"""Shared by the avoidance search tests: the generated overtake (the ego changes lane from
y = -2 to 3.75 m and ends ``gap`` m ahead of a vehicle of the target lane driving at ``speed``)."""

from __future__ import annotations

from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle


def generated_overtake(xf: float, gap: float, speed: float, limits: bool, vxf: float = 24.0) -> Problem:
    """The overtake with end position ``xf``, gap ``gap`` [m] ahead of the vehicle's corner at
    ``t_f`` = 5 s, the vehicle's speed ``speed`` and, with ``limits``, the passenger car's limits."""
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(xf - gap - 5.0 * speed, speed), corner="front-lower", y=3.75, length=4.8,
                           width=1.8, safety_x=5.0, safety_y=0.5, name="sv1")
    p = Problem(ego, (v,), "generated overtake")
    return p.with_limits(PASSENGER_CAR) if limits else p
