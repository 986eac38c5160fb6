"""IDM's forward simulation is written once (issue 32: one implementation per algorithm):
:func:`iamp.prediction.leader.kernel.idm_forward`, run compiled by numba when it is importable and
as Python otherwise.  Both give the same numbers bit for bit, and they are the numbers of the numba
kernel that it replaced (commit 15351b0's ``simulate_idm_kernel``, which the closed-loop campaigns
of that commit ran with), so no prediction depends on whether numba is installed."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.prediction.leader import kernel
from iamp.prediction.leader.car_following import MIN_GAP_M, CarFollowingLaw, simulate

IDM = CarFollowingLaw("idm", {"a": 1.2, "b": 1.8, "v0": 30.0, "T": 1.3, "s0": 2.0})

#: sha256 of ``x.tobytes() + v.tobytes()`` of ``simulate(IDM, *_inputs(seed), 0.1)`` computed with
#: the replaced numba kernel (``iamp.prediction.leader.kernel.simulate_idm_kernel`` at 15351b0)
REPLACED_KERNEL = {
    0: "65c122a0ac59597201e1250d5ec866cc4851d077de0af8dc41b9801d3cdd8268",
    1: "cbd012dbed6d13eb806e2cda39606b94b262da2d1ebabecba57caf6daf88da5b",
    2: "b0c8dad175d868b8e2b1a6576fc45a635c5f9f26525316568c9c86c19e9669a9",
}


def _inputs(seed: int) -> tuple[np.ndarray, ...]:
    """Leaders that brake hard and stop (seed 1: the gap cap binds at 95 nodes, 131 speeds are 0),
    followers fast and close."""
    rng = np.random.default_rng(seed)
    B, M1 = 12, 51
    vl = np.maximum(np.cumsum(rng.normal(-0.3, 2.0, (B, M1)), axis=1) + rng.uniform(0, 25, (B, 1)), 0.0)
    vl[0] = 0.0  # a standing leader
    xl = rng.uniform(5, 40, (B, 1)) + np.concatenate(
        [np.zeros((B, 1)), np.cumsum(0.5 * (vl[:, 1:] + vl[:, :-1]) * 0.1, axis=1)], axis=1)
    x0, v0 = rng.uniform(-10, 5, B), rng.uniform(0, 35, B)
    v0[1] = 0.0
    return x0, v0, xl, vl, rng.uniform(4.0, 9.0, B)


def _digest(x: np.ndarray, v: np.ndarray) -> str:
    return hashlib.sha256(x.tobytes() + v.tobytes()).hexdigest()


@pytest.fixture
def python_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """``simulate`` as without numba: the same function run as Python."""
    monkeypatch.setattr(kernel, "_COMPILED", [None])


@pytest.mark.parametrize("seed", sorted(REPLACED_KERNEL))
def test_python_run_reproduces_the_replaced_kernel(seed: int, python_only: None) -> None:
    x0, v0, xl, vl, off = _inputs(seed)
    x, v = simulate(IDM, x0, v0, xl, vl, off, 0.1)
    assert _digest(x, v) == REPLACED_KERNEL[seed]


needs_numba = pytest.mark.skipif(kernel.compiled() is None, reason="numba is not installed")


@needs_numba
@pytest.mark.parametrize("seed", sorted(REPLACED_KERNEL))
def test_compiled_run_reproduces_the_replaced_kernel(seed: int) -> None:
    x0, v0, xl, vl, off = _inputs(seed)
    x, v = simulate(IDM, x0, v0, xl, vl, off, 0.1)
    assert _digest(x, v) == REPLACED_KERNEL[seed]


@needs_numba
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), a=st.floats(0.1, 6.0), b=st.floats(0.1, 10.0), v0=st.floats(5.0, 45.0),
       T=st.floats(0.0, 4.0), s0=st.floats(0.0, 10.0), dt=st.sampled_from([0.05, 0.1, 0.2]))
def test_compiled_equals_python_bit_for_bit(seed: int, a: float, b: float, v0: float, T: float, s0: float,
                                            dt: float) -> None:
    """Generated laws, leaders and followers (standing, braking, closer than the smallest gap):
    the compiled function and the same function run as Python write the same bytes (signed
    zeros included)."""
    rng = np.random.default_rng(seed)
    B, M1 = 4, 31
    vl = np.maximum(np.cumsum(rng.normal(-0.5, 3.0, (B, M1)), axis=1) + rng.uniform(0, 30, (B, 1)), 0.0)
    xl = rng.uniform(-2, 30, (B, 1)) + np.cumsum(vl * dt, axis=1)
    x = np.zeros((B, M1))
    v = np.zeros((B, M1))
    x[:, 0], v[:, 0] = rng.uniform(-20, 5, B), np.maximum(rng.uniform(-1, 40, B), 0.0)
    off = rng.uniform(3.0, 10.0, B)
    xs, vs = x.reshape(-1).tolist(), v.reshape(-1).tolist()
    args = (a, b, v0, T, s0)
    kernel.idm_forward(*args, xs, vs, xl.reshape(-1).tolist(), vl.reshape(-1).tolist(), off.tolist(), B, M1, dt,
                       3.0, 8.0, MIN_GAP_M)
    run = kernel.compiled()
    assert run is not None
    run(*args, x.reshape(-1), v.reshape(-1), xl.reshape(-1), vl.reshape(-1), off, B, M1, dt, 3.0, 8.0, MIN_GAP_M)
    assert np.array(xs).tobytes() == x.reshape(-1).tobytes()
    assert np.array(vs).tobytes() == v.reshape(-1).tobytes()


def test_python_run_keeps_the_gap_and_stops(python_only: None) -> None:
    """Without numba: a follower at 30 m/s 20 m behind a standing leader stops at the smallest gap
    (never beyond the leader's rear minus MIN_GAP_M, never reversing)."""
    M1 = 101
    x, v = simulate(IDM, [0.0], [30.0], np.full((1, M1), 25.0), np.zeros((1, M1)), 5.0, 0.1)
    assert np.all(v >= 0.0) and v[0, -1] == 0.0
    assert np.all(np.diff(x[0]) >= 0.0)
    assert x[0].max() <= 25.0 - 5.0 - MIN_GAP_M
