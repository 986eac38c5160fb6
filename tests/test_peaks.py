"""SPEC §14: every reported peak equals a dense evaluation of the plan's own trajectory.

The peaks of iamp/core/peaks.py come from the trajectory's polynomial pieces (input ends,
the speed's and y's stationary points, the pieces' slopes).  Here they are compared with
the trajectory evaluated on a dense grid that contains every piece end (and the left limit
there), over generated scenarios, bounds and planners.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.core.peaks import peaks_report
from iamp.core.physical import PhysicalLimits
from iamp.core.trajectory_pieces import breakpoints
from iamp.planners.examples import random_problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.qp import QPPlanner
from iamp.planners.qp.hold import HoldTrajectory

DENSE = 40_001


def _limits(draw: st.DrawFn, hold: str | None) -> PhysicalLimits:
    ax = (draw(st.floats(-9.0, -0.5)), draw(st.floats(0.5, 9.0)))
    ay = (draw(st.floats(-4.0, -0.3)), draw(st.floats(0.3, 4.0)))
    vx = (draw(st.floats(0.0, 15.0)), draw(st.floats(25.0, 45.0)))
    y = (draw(st.floats(-6.0, -0.5)), draw(st.floats(3.0, 8.0)))
    return PhysicalLimits(ax=ax, ay=ay, a_total=draw(st.floats(2.0, 12.0)), vx=vx, y=y,
                          jerk=None if hold == "zoh" else draw(st.floats(0.5, 30.0)))


@st.composite
def planned(draw: st.DrawFn) -> tuple[object, float, PhysicalLimits, str | None]:
    """A plan's trajectory (PMP or a small QP, unbounded: peaks of any size), its horizon and bounds."""
    seed = draw(st.integers(0, 10**6))
    kind = draw(st.sampled_from(["pmp", "pmp2", "foh", "zoh"]))
    problem = random_problem(seed, m=2 if kind == "pmp2" else 1)
    hold = kind if kind in ("foh", "zoh") else None
    lim = _limits(draw, hold)
    if hold is None:
        plan = PMPPlanner().plan(problem)
    else:
        plan = QPPlanner(steps=draw(st.integers(8, 30)), hold=hold).plan(problem)
    if not plan.ok:
        return None, problem.tf, lim, hold  # type: ignore[return-value]
    return plan.trajectory, problem.tf, lim, hold


def _dense(traj: object, tf: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    br = breakpoints(traj, tf)
    assert br is not None
    t = np.unique(np.r_[np.linspace(0.0, tf, DENSE), br])
    X = traj.states(t)  # type: ignore[attr-defined]
    U = traj.inputs(t)  # type: ignore[attr-defined]
    left = br[1:]  # left limits of the input at the piece ends (ZOH jumps there)
    UL = traj.inputs(np.maximum(left - 1e-12 * max(1.0, tf), 0.0))  # type: ignore[attr-defined]
    return t, X, np.vstack([U, UL]), br


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(planned())
def test_every_peak_equals_a_dense_evaluation(case: tuple[object, float, PhysicalLimits, str | None]) -> None:
    traj, tf, lim, hold = case
    if traj is None:
        return
    rep = peaks_report(traj, tf, lim)  # type: ignore[arg-type]
    assert rep.exact
    t, X, U, _br = _dense(traj, tf)
    scale_u = max(1.0, float(np.max(np.abs(U))))
    # inputs: exact at the piece ends, which the dense set holds (with their left limits)
    for axis, name in enumerate(("ax", "ay")):
        lo, hi = rep.peaks[name].peak  # type: ignore[misc]
        assert lo == pytest.approx(U[:, axis].min(), abs=1e-9 * scale_u)
        assert hi == pytest.approx(U[:, axis].max(), abs=1e-9 * scale_u)
    assert rep.peaks["a_total"].peak == pytest.approx(float(np.max(np.hypot(U[:, 0], U[:, 1]))), abs=1e-9 * scale_u)
    # speed and y: the dense max can only fall short of the exact one by the curvature over
    # half a dense step, |du/dt| (dt/2)^2 / 2 for the speed, |u| (dt/2)^2 / 2 for y
    dt = tf / (DENSE - 1)
    jmax = max(1.0, float(np.max(np.abs(np.diff(U[: t.size], axis=0)) / np.maximum(np.diff(t), 1e-300)[:, None])))
    for name, col, curv in (("vx", 1, jmax), ("y", 2, scale_u)):
        lo, hi = rep.peaks[name].peak  # type: ignore[misc]
        slack = curv * dt**2 / 8 + 1e-9 * max(1.0, float(np.max(np.abs(X[:, col]))))
        assert X[:, col].min() - slack <= lo <= X[:, col].min() + 1e-9 * max(1.0, abs(lo))
        assert X[:, col].max() - 1e-9 * max(1.0, abs(hi)) <= hi <= X[:, col].max() + slack
        # and the peak is the trajectory's value where it says it is
        t_lo, t_hi = rep.peaks[name].at  # type: ignore[misc]
        at = traj.states(np.array([t_lo, t_hi]))[:, col]  # type: ignore[attr-defined]
        np.testing.assert_allclose(at, [lo, hi], rtol=1e-9, atol=1e-9)
    # jerk: the slope of u on every dense interval (each lies inside one piece)
    if "jerk" in rep.peaks:
        pk = rep.peaks["jerk"]
        Ud = U[: t.size]
        if hold == "zoh":
            assert pk.peak is None and pk.ok is False
        else:
            # intervals of a dense point and a piece end a rounding error apart carry only
            # rounding in u: the slope is measured on intervals longer than 1e-6 dt
            dts = np.diff(t)
            long = dts > 1e-6 * dt
            slopes = np.abs(np.diff(Ud, axis=0))[long] / dts[long][:, None]
            assert pk.peak == pytest.approx(float(slopes.max()), rel=1e-6, abs=1e-6)
    # ok is the comparison of peak and bound
    for p in rep.peaks.values():
        if p.bound is None or p.peak is None:
            continue
        if isinstance(p.bound, tuple):
            inside = p.bound[0] - 1e-6 <= p.peak[0] and p.peak[1] <= p.bound[1] + 1e-6  # type: ignore[index]
            exact_in = p.bound[0] <= p.peak[0] and p.peak[1] <= p.bound[1]  # type: ignore[index]
        else:
            inside = p.peak <= p.bound + 1e-6  # type: ignore[operator]
            exact_in = p.peak <= p.bound  # type: ignore[operator]
        if exact_in:
            assert p.ok
        if not inside:
            assert p.ok is False and p.violation > 1e-6


def test_peaks_without_limits_always_report_acceleration_and_speed() -> None:
    plan = PMPPlanner().plan(random_problem(5))
    rep = plan.peaks
    assert rep is not None and set(rep.peaks) == {"a_total", "vx"}
    js = plan.to_json()["limits"]
    assert set(js) == {"a_total", "vx"} and js["a_total"]["bound"] is None and js["a_total"]["ok"] is None


def test_warning_beyond_any_car() -> None:
    """paper-3's unbounded PMP plan asks for 23.6 m/s² (> 9.81): a warning even without limits;
    a trajectory driving backwards is flagged too."""
    from iamp.prediction.resolve import load_problem

    _, p, _ = load_problem("paper-3")
    plan = PMPPlanner().plan(p)
    rep = plan.peaks
    assert rep is not None and rep.peaks["a_total"].peak > 23.0  # type: ignore[operator]
    assert any("any car" in w for w in rep.warnings)
    # a straight braking from v = 1 m/s at u = -2 m/s² (ZOH, two 1 s intervals): v = 1, -1, -3
    t = np.linspace(0.0, 2.0, 3)
    X = np.array([[0.0, 1.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [-2.0, -3.0, 0.0, 0.0]])
    traj = HoldTrajectory(t, X, np.array([[-2.0, 0.0], [-2.0, 0.0]]), "zoh")
    rep2 = peaks_report(traj, 2.0)
    assert rep2.peaks["vx"].peak == (-3.0, 1.0)
    assert any("backwards" in w for w in rep2.warnings)
    assert math.isclose(rep2.peaks["a_total"].peak, 2.0)  # type: ignore[arg-type]


def test_unknown_pieces_fall_back_and_say_so() -> None:
    """A trajectory that does not say where its pieces are is cut into 1 ms pieces (exact: false)."""

    class Smooth:
        def states(self, t: np.ndarray) -> np.ndarray:
            t = np.asarray(t, dtype=float)
            return np.stack([np.sin(t), np.cos(t), 0 * t, 0 * t], axis=1)

        def inputs(self, t: np.ndarray) -> np.ndarray:
            t = np.asarray(t, dtype=float)
            return np.stack([-np.sin(t), 0 * t], axis=1)

    rep = peaks_report(Smooth(), 3.0, PhysicalLimits(ax=(-0.5, 0.5)))
    assert not rep.exact
    assert rep.peaks["ax"].peak[0] == pytest.approx(-1.0, abs=1e-6)  # type: ignore[index]
    assert rep.peaks["ax"].ok is False
