"""Named, shared example problems (used by the tests, the comparison and the benchmarks).

* :func:`paper_problem` — the paper's scenarios 1–3 with vehicle 1 as a polynomial
  (SPEC §8 defaults; scenario 1 at a constant 18 m/s, 2 and 3 with the documented
  polynomials of the built-in ``paper-N-poly`` files).
* :func:`random_problem` — seeded random lane changes, to either side, with non-zero lateral
  boundary speeds, cubic vehicle trajectories, one to four vehicles.
* :func:`two_minima_problem` — one vehicle whose ``J(t)`` has two local minima, the global
  one *not* the one nearest the middle of the horizon.
* :func:`overtake_problem` and :func:`overtake_three_problem` — the bounded avoidance plans of
  ``iamp bench`` (one vehicle that the free optimum would cut; three vehicles), under the
  passenger car's limits.
* :func:`boxed_problem` — a problem with an input box at a fraction of its unbounded plan's peaks.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle

LANE_WIDTH = 3.75
DEFAULT_GEOMETRY: dict[str, Any] = {"length": 4.8, "width": 1.8, "safety_x": 5.0, "safety_y": 0.5}


def paper_problem(k: int) -> Problem:
    """The paper's scenario ``k`` (1, 2, 3) with vehicle 1 given as a polynomial."""
    from iamp.core.scenario import load_scenario

    problem, _ = load_scenario(f"paper-{k}-poly").to_problem()
    return problem


def builtin_problem(name: str) -> Problem:
    from iamp.core.scenario import load_scenario

    problem, _ = load_scenario(name).to_problem()
    return problem


def random_problem(seed: int, m: int = 1, side: int | None = None) -> Problem:
    """A seeded random lane change with ``m`` (1 to 4) vehicles.

    ``side`` = +1 changes lane towards +y, −1 towards −y (mirrored corners); default: drawn.
    Vehicle 1 is in the target lane behind the ego (``front`` corner); vehicle 2 is ahead in
    the current lane (``rear`` corner); vehicle 3 is ahead in the target lane (``rear``
    corner, near side); vehicle 4 behind in the current lane (``front`` corner, far side).
    The draws for vehicles 1 and 2 do not depend on ``m``.
    """
    rng = np.random.default_rng(seed)
    if side is None:
        side = int(rng.choice([-1, 1]))
    tf = rng.uniform(4.0, 7.0)
    vx0 = rng.uniform(15.0, 30.0)
    vxf = vx0 + rng.uniform(-3.0, 3.0)
    y0 = rng.uniform(-0.3, 0.3)
    yf = y0 + side * LANE_WIDTH + rng.uniform(-0.2, 0.2)
    ego = EgoBoundary(tf=tf, x0=0.0, y0=y0, vx0=vx0, xf=0.5 * (vx0 + vxf) * tf + rng.uniform(-10, 10),
                      yf=yf, vxf=vxf, vy0=rng.uniform(-0.5, 0.5), vyf=rng.uniform(-0.5, 0.5))
    near, far = ("lower", "upper") if side > 0 else ("upper", "lower")
    vehicles = [SurroundingVehicle(
        x_poly=(rng.uniform(-30, -5), rng.uniform(vx0 - 6, vx0 + 2), rng.uniform(-1, 1), rng.uniform(-0.1, 0.1)),
        corner=f"front-{near}", y=yf, name="sv1", **DEFAULT_GEOMETRY)]
    if m >= 2:
        vehicles.append(SurroundingVehicle(
            x_poly=(rng.uniform(25, 50), rng.uniform(vx0 - 8, vx0 - 2), rng.uniform(-0.5, 0.5),
                    rng.uniform(-0.05, 0.05)),
            corner=f"rear-{far}", y=y0, name="sv2", **DEFAULT_GEOMETRY))
    if m >= 3:
        vehicles.append(SurroundingVehicle(
            x_poly=(rng.uniform(40, 80), rng.uniform(vx0 - 4, vx0 + 2), rng.uniform(-0.5, 0.5),
                    rng.uniform(-0.05, 0.05)),
            corner=f"rear-{near}", y=yf, name="sv3", **DEFAULT_GEOMETRY))
    if m >= 4:
        vehicles.append(SurroundingVehicle(
            x_poly=(rng.uniform(-45, -20), rng.uniform(vx0 - 2, vx0 + 4), rng.uniform(-0.5, 0.5),
                    rng.uniform(-0.05, 0.05)),
            corner=f"front-{far}", y=y0, name="sv4", **DEFAULT_GEOMETRY))
    if not 1 <= m <= 4:
        raise ValueError("random_problem builds one to four vehicles")
    return Problem(ego, tuple(vehicles), f"random-{seed}-m{m}-side{side:+d}")


def two_minima_problem() -> Problem:
    """One vehicle whose ``J(t)`` has two local minima; the global one is the one farther
    from ``t_f/2`` (checked by the tests, not assumed).

    Vehicle 1 starts fast (32.9 m/s) and brakes, then recovers (a cubic), so the
    corner's offset from the ego's unconstrained path has two dips: local minima of ``J``
    near ``t = 0.81`` (global) and ``t = 2.51`` s, the latter nearer ``t_f/2 = 3``.
    """
    ego = EgoBoundary(tf=6.0, x0=0.0, y0=0.0, vx0=20.0, xf=120.0, yf=3.75, vxf=20.0)
    veh = SurroundingVehicle(x_poly=TWO_MINIMA_POLY, corner="front-lower", y=3.75, name="sv1", **DEFAULT_GEOMETRY)
    return Problem(ego, (veh,), "two-minima")


TWO_MINIMA_POLY = (-14.12, 32.86, -3.57, 0.35)


def overtake_problem(limits: bool = True) -> Problem:
    """The ego overtakes a vehicle in the target lane whose safety box the free optimum would cut
    (the avoidance rows bind), under the passenger car's limits (its lateral bound binds too)."""
    from iamp.core.physical import PASSENGER_CAR

    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=118.0, yf=3.75, vxf=24.0)
    v = SurroundingVehicle(x_poly=(5.0, 20.0), corner="front-lower", y=3.75, name="sv1", **DEFAULT_GEOMETRY)
    return Problem(ego, (v,), "overtake", limits=PASSENGER_CAR if limits else None)


def overtake_three_problem(limits: bool = True) -> Problem:
    """:func:`overtake_problem` with two more vehicles in the current lane: a slow one ahead
    (``rear-upper``; it binds: the ego must leave the lane earlier) and a fast one behind
    (``front-upper``)."""
    one = overtake_problem(limits)
    v2 = SurroundingVehicle(x_poly=(30.0, 10.0), corner="rear-upper", y=-2.0, name="sv2", **DEFAULT_GEOMETRY)
    v3 = SurroundingVehicle(x_poly=(-20.0, 26.0), corner="front-upper", y=-2.0, name="sv3", **DEFAULT_GEOMETRY)
    return Problem(one.ego, (one.vehicles[0], v2, v3), "overtake-three", limits=one.limits)


def boxed_problem(problem: Problem, frac: float) -> Problem:
    """``problem`` with a symmetric input box at ``frac`` of its unbounded PMP plan's peaks.

    ``a_x, a_y ∈ [-frac·max|u_x|, frac·max|u_x|] × [-frac·max|u_y|, frac·max|u_y|]``, the peaks
    read on 401 points of the certified unbounded plan: with ``frac < 1`` the box is active and,
    close to 1, a plan within it exists (the bounded PMP's several-vehicle cases of ``iamp bench``
    and its tests).

    Parameters
    ----------
    problem : Problem
        Without limits; its unbounded PMP plan must be ``optimal``.
    frac : float
        Fraction of the peaks, in ``(0, 1]`` for an active box.

    Returns
    -------
    Problem
        The same problem with ``PhysicalLimits(ax=..., ay=...)``.

    Raises
    ------
    ValueError
        The unbounded plan is not ``optimal``.
    """
    from iamp.core.physical import PhysicalLimits
    from iamp.planners.pmp import PMPPlanner

    base = PMPPlanner().plan(problem, diagnostics=False)
    if base.status != "optimal":
        raise ValueError(f"{problem.name}: the unbounded PMP plan is {base.status}, not optimal")
    mx, my = np.abs(base.require_trajectory().inputs(np.linspace(0.0, problem.tf, 401))).max(axis=0)
    return problem.with_limits(PhysicalLimits(ax=(-frac * mx, frac * mx), ay=(-frac * my, frac * my)))
