"""The safety report's fast path (issue 32 item 3) returns the numbers of the full computation, bit
for bit: rows whose Bernstein coefficients prove no root near ``[0, 1]`` are not sent to the
companion-matrix eigenvalues (:func:`iamp.core.polyroots_kernel.root_degrees`), and every
vehicle's cut polynomials are solved in one call.  The full computation is the same code with the
filter disabled; the dense (1e-5 s) comparison of the reports is ``tests/test_safety.py``."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import iamp.core.polyroots as pr
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.safety import safety_report
from iamp.planners.qp.planner import HoldTrajectory


def _unfiltered(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(pr, "_SKIP_FAR", False)


def _skipped(C: np.ndarray) -> np.ndarray:
    """Whether the filter skips each row: a positive degree that the filter sets to 0."""
    C = np.ascontiguousarray(C, dtype=float)
    return (pr._degrees(C, 1e-6) == 0) & (pr._degrees(C, 1e-6, skip_far=False) > 0)


def _hex_roots(C: np.ndarray) -> list[tuple[int, str]]:
    rows, sig = pr.roots_in_unit_interval(C)
    return sorted((int(r), float(s).hex()) for r, s in zip(rows, sig))


def _report_hex(rep) -> list[object]:
    h = float.hex
    return [rep.exact] + [[v.name, [(h(a), h(b)) for a, b in v.intrusion], h(v.max_intrusion_m),
                           [(h(a), h(b)) for a, b in v.overlap], h(v.min_clearance_m)] for v in rep.vehicles]


def _polys(seed: int, n: int = 400, degree: int = 5) -> np.ndarray:
    """Rows that stress the filter: roots in, near and just outside [0, 1], double roots, complex
    pairs a hair off the real axis, tiny leading coefficients, mixed scales, constants."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        kind = i % 6
        d = int(rng.integers(1, degree + 1))
        if kind == 0:  # real roots anywhere near the window
            r = rng.uniform(-0.5, 1.5, d)
        elif kind == 1:  # a double root in or at the window's edge
            r = np.r_[np.repeat(rng.choice([rng.uniform(0, 1), 0.0, 1.0, 1 + 1e-9, -1e-9]), 2), rng.uniform(-3, 3, d)]
        elif kind == 2:  # complex pair with |Im| near the 1e-6 tolerance
            z = rng.uniform(-0.1, 1.1) + 1j * 10 ** rng.uniform(-8, -4)
            r = np.r_[z, np.conj(z), rng.uniform(2, 5, max(d - 2, 0))]
        elif kind == 3:  # roots just outside
            r = np.r_[rng.choice([-1, 1]) * 10 ** rng.uniform(-9, -3) + rng.choice([0.0, 1.0]), rng.uniform(3, 9, d)]
        elif kind == 4:  # no roots near: large constant offset
            r = rng.uniform(4, 30, d)
        else:  # tiny leading coefficient (the product polynomials of the report)
            c = rng.normal(0, 1, degree + 1) * 10.0 ** -np.arange(degree + 1) * rng.uniform(0.5, 3)
            c[0] += rng.normal(0, 3)
            rows.append(c)
            continue
        c = np.real(np.polynomial.polynomial.polyfromroots(r)) * 10 ** rng.uniform(-4, 4)
        c = c[:degree + 1]
        rows.append(np.r_[c, np.zeros(degree + 1 - c.size)])
    C = np.array(rows)
    C[::37] = 0.0
    C[5::41, 1:] = 0.0  # constants
    return C


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.sampled_from([3, 5, 7]))
def test_filtered_roots_equal_the_full_eigenvalue_roots_bit_for_bit(seed, degree):
    C = _polys(seed, degree=degree)
    fast = _hex_roots(C)
    with pytest.MonkeyPatch.context() as mp:
        _unfiltered(mp)
        full = _hex_roots(C)
    assert fast == full
    # and what the filter skips has no root found by the full computation
    skipped = np.flatnonzero(_skipped(C))
    assert not set(skipped) & {r for r, _ in full}


def test_the_filter_skips_polynomials_far_from_zero_and_keeps_roots():
    C = np.array([[5.0, 1.0, -1.0, 0.5],       # > 4 on [0, 1]
                  [-5.0, 1.0, 1.0, 0.5],       # < 0 on [0, 1]
                  [-0.25, 0.0, 1.0, 0.0],      # root at 0.5
                  [1e-7, 0.0, 0.0, 0.0],       # a constant: never sent
                  [0.25, -1.0, 1.0, 0.0]])     # double root at 0.5
    assert pr._degrees(C, 1e-6, skip_far=False).tolist() == [3, 3, 2, 0, 2]
    assert _skipped(C).tolist() == [True, True, False, False, False]


def _hold_problem(seed: int, m: int) -> tuple[Problem, HoldTrajectory]:
    rng = np.random.default_rng(seed)
    tf, N = float(rng.uniform(3, 6)), int(rng.integers(5, 60))
    hold = "foh" if seed % 2 else "zoh"
    ego = EgoBoundary(tf=tf, x0=0.0, y0=-2.0, vx0=20.0, xf=100.0, yf=2.0, vxf=20.0, vy0=0.0, vyf=0.0)
    t = np.linspace(0.0, tf, N + 1)
    U = rng.normal(0, 2.0, size=(N if hold == "zoh" else N + 1, 2))
    X = np.zeros((N + 1, 4))
    X[0] = ego.initial
    for k in range(N):
        h = t[k + 1] - t[k]
        s, v = X[k, [0, 2]], X[k, [1, 3]]
        if hold == "zoh":
            sn, vn = s + h * v + h**2 / 2 * U[k], v + h * U[k]
        else:
            sn, vn = s + h * v + h**2 * (U[k] / 3 + U[k + 1] / 6), v + h / 2 * (U[k] + U[k + 1])
        X[k + 1] = [sn[0], vn[0], sn[1], vn[1]]
    traj = HoldTrajectory(t, X, U, hold)
    vs = []
    for i in range(m):  # vehicles placed on the ego's path: real intrusions and overlaps
        tc = rng.uniform(0.2, 0.8) * tf
        xc = traj.states(np.array([tc]))[0]
        c1 = rng.uniform(10, 25)
        c = (float(xc[0] - c1 * tc + rng.normal(0, 3)), c1, float(rng.normal(0, 0.5)), float(rng.normal(0, 0.05)))
        vs.append(SurroundingVehicle(x_poly=c, corner="front-lower", y=float(xc[2] + rng.normal(0, 1.5)),
                                     length=4.5, width=1.8, safety_x=float(rng.uniform(0, 8)),
                                     safety_y=float(rng.uniform(0, 1)), name=f"sv{i + 1}"))
    return Problem(ego, tuple(vs), "random"), traj


@pytest.mark.parametrize("seed", range(12))
def test_fast_report_equals_the_full_computation_bit_for_bit(seed, monkeypatch):
    problem, traj = _hold_problem(seed, m=1 + seed % 3)
    fast = _report_hex(safety_report(problem, traj))
    _unfiltered(monkeypatch)
    assert fast == _report_hex(safety_report(problem, traj))


def test_most_rows_of_an_avoidance_report_skip_the_eigenvalues():
    calls: list[tuple[int, int]] = []
    orig = pr._degrees

    def count(C, *a):
        out = orig(C, *a)
        calls.append((C.shape[0], int(np.sum((out == 0) & (orig(C, a[0], False) > 0)))))
        return out

    problem, traj = _hold_problem(1, m=3)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pr, "_degrees", count)
        safety_report(problem, traj)
    assert len(calls) == 1  # one root-finding call for the three vehicles
    rows, skipped = map(sum, zip(*calls))
    assert skipped > 0.6 * rows
