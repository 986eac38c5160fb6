"""The several-vehicle infeasibility cover's shortcuts give what the long way gives (issue 32).

:func:`iamp.planners.pmp.bounded._cover_infeasible` (``m >= 2``) now

* reads the corners from the vehicles' coefficients with ``_polyval`` (numpy's ``polyval``
  operation for operation) instead of an array from ``problem.corners`` per box, and
* tries :func:`~iamp.planners.pmp.bounded.solve_bounded_fixed` at a centre only where both axis
  solves just converged (it solves the same axes from the same start, so elsewhere it raises);
* solves both axes of every box of a level in one kernel call
  (:func:`~iamp.planners.pmp.saturated_kernel.cover_points`, compiled or not: the same numbers).

The long way below is the loop as it was before; the certificate (verdict, feasible contact
times, boxes, solves) must be the same, field for field.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.planners.examples import random_problem
from iamp.planners.pmp import compiled, jit
from iamp.planners.pmp import saturated_kernel as sk
from iamp.planners.pmp.bounded import (
    InfeasibilityCertificate,
    _box_rate,
    _cover_infeasible,
    _derivative,
    _polyval,
    input_box,
    solve_bounded_fixed,
)
from iamp.planners.pmp.saturated import MAX_NEWTON, AxisInfeasible, AxisNoConvergence, solve_axis


def _long_way(problem, max_solves: int) -> InfeasibilityCertificate:  # type: ignore[no-untyped-def]
    m, ego, T = problem.m, problem.ego, float(problem.tf)
    (lx, hx), (ly, hy) = input_box(problem)
    axes_data = ((ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx), (ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy))
    ders = [_derivative([float(c) for c in np.asarray(v.x_poly, dtype=float)]) for v in problem.vehicles]
    per_axis = 8 if m == 2 else 4
    edges = [T * j / per_axis for j in range(per_axis + 1)]
    stack = deque((np.array([edges[j] for j in idx]), np.array([edges[j + 1] for j in idx]))
                  for idx in np.ndindex(*([per_axis] * m)))
    solves = boxes = 0
    while stack:
        a, b = stack.popleft()
        t = 0.5 * (a + b)
        half = 0.5 * (b - a)
        times = [float(x) for x in t]
        C = problem.corners(t)
        covered = False
        if len(set(times)) == m:
            for k, (s0, v0, sf, vf, lo, hi) in enumerate(axes_data):
                solves += 1
                try:
                    solve_axis(times, T, s0, v0, sf, vf, [float(c) for c in C[:, k]], lo, hi)
                except AxisInfeasible as exc:
                    if exc.lam_phys is None or exc.margin_phys is None:
                        continue
                    rate = sum(half[i] * abs(exc.lam_phys[i])
                               * _box_rate(ders[i] if k == 0 else [0.0], axes_data[k], float(a[i]), float(b[i]))
                               for i in range(m))
                    if exc.margin_phys > rate * (1 + 1e-9):
                        covered = True
                        break
                    continue
                except AxisNoConvergence:
                    continue
            if covered:
                boxes += 1
                continue
            try:
                solve_bounded_fixed(problem, t)
                return InfeasibilityCertificate(False, t, boxes, solves)
            except (AxisInfeasible, AxisNoConvergence):
                pass
        if solves > max_solves or float(np.max(b - a)) < 1e-9 * T:
            return InfeasibilityCertificate(False, None, boxes, solves)
        i = int(np.argmax(b - a))
        mid_b, mid_a = b.copy(), a.copy()
        mid_b[i] = mid_a[i] = t[i]
        stack += [(a, mid_b), (mid_a, b)]
    return InfeasibilityCertificate(True, None, boxes, solves)


def _same(x: InfeasibilityCertificate, y: InfeasibilityCertificate) -> bool:
    if (x.certified, x.boxes, x.solves, x.vehicle) != (y.certified, y.boxes, y.solves, y.vehicle):
        return False
    if x.feasible_t is None or y.feasible_t is None:
        return x.feasible_t is None and y.feasible_t is None
    return [float(v).hex() for v in x.feasible_t] == [float(v).hex() for v in y.feasible_t]


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 400), m=st.sampled_from([2, 3]), scale=st.sampled_from([0.2, 0.4, 1.0, 10.0]))
def test_the_cover_equals_the_long_way(seed: int, m: int, scale: float) -> None:
    box = PhysicalLimits(ax=(PASSENGER_CAR.ax[0] * scale, PASSENGER_CAR.ax[1] * scale),
                         ay=(PASSENGER_CAR.ay[0] * scale, PASSENGER_CAR.ay[1] * scale))
    problem = random_problem(seed, m=m).with_limits(box)
    assert _same(_cover_infeasible(problem, 300), _long_way(problem, 300))


def test_the_three_outcomes_equal_the_long_way() -> None:
    """A certified cover, a spent budget and a feasible centre (the shortcut's early return)."""
    seen = set()
    for seed in range(8):
        for scale in (0.2, 1.0, 10.0):
            box = PhysicalLimits(ax=(PASSENGER_CAR.ax[0] * scale, PASSENGER_CAR.ax[1] * scale),
                                 ay=(PASSENGER_CAR.ay[0] * scale, PASSENGER_CAR.ay[1] * scale))
            problem = random_problem(seed, m=2).with_limits(box)
            got = _cover_infeasible(problem, 200)
            assert _same(got, _long_way(problem, 200))
            seen.add((got.certified, got.feasible_t is not None))
    assert seen == {(True, False), (False, False), (False, True)}


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 400), m=st.sampled_from([2, 3]), u=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3))
def test_the_corners_are_problem_corners_bit_for_bit(seed: int, m: int, u: list[float]) -> None:
    problem = random_problem(seed, m=m)
    t = np.asarray(u[:m]) * problem.tf
    ref = problem.corners(t)
    for i, v in enumerate(problem.vehicles):
        pos = [float(c) for c in np.asarray(v.x_poly, dtype=float)]
        assert (_polyval(pos, float(t[i])) + float(v.offset_x)).hex() == float(ref[i, 0]).hex()
        assert float(v.corner_y).hex() == float(ref[i, 1]).hex()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 400), m=st.sampled_from([2, 3]), scale=st.sampled_from([0.2, 0.5, 1.0, 10.0]),
       u=st.lists(st.floats(0.0, 1.0), min_size=12, max_size=12))
def test_cover_points_compiled_is_the_python_source(seed: int, m: int, scale: float, u: list[float]) -> None:
    """The kernel's numba twin gives the Python function's numbers bit for bit (four choices of
    contact times per example, a repeated one among them)."""
    if not jit.available():
        pytest.skip("numba is not installed")
    box = PhysicalLimits(ax=(PASSENGER_CAR.ax[0] * scale, PASSENGER_CAR.ax[1] * scale),
                         ay=(PASSENGER_CAR.ay[0] * scale, PASSENGER_CAR.ay[1] * scale))
    problem = random_problem(seed, m=m).with_limits(box)
    T = float(problem.tf)
    (lx, hx), (ly, hy) = input_box(problem)
    ego = problem.ego
    data = [float(x) for x in (ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx, ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy)]
    times: list[float] = []
    corners: list[float] = []
    for p in range(4):
        t = [T * x for x in u[3 * p:3 * p + m]]
        C = problem.corners(np.asarray(t))
        times += t
        corners += [float(c) for c in C[:, 0]] + [float(c) for c in C[:, 1]]
    ref = sk.cover_points(times, corners, m, T, T**2, T**3, data, 1e-12, MAX_NEWTON)
    got = jit.twin(sk.cover_points)(np.asarray(times), np.asarray(corners), m, T, T**2, T**3, np.asarray(data),
                                    1e-12, MAX_NEWTON)
    assert [float(x).hex() for x in got] == [float(x).hex() for x in ref]


def test_the_compiled_cover_equals_the_long_way() -> None:
    """With the compiled axis solve loaded (as ``iamp bench`` and the closed loop have it)."""
    if not compiled.load_axis():
        pytest.skip("numba is not installed")
    for seed in range(4):
        for scale in (0.2, 10.0):
            box = PhysicalLimits(ax=(PASSENGER_CAR.ax[0] * scale, PASSENGER_CAR.ax[1] * scale),
                                 ay=(PASSENGER_CAR.ay[0] * scale, PASSENGER_CAR.ay[1] * scale))
            problem = random_problem(seed, m=2).with_limits(box)
            assert _same(_cover_infeasible(problem, 200), _long_way(problem, 200))
