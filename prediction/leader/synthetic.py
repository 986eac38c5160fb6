r"""I-80-like recorded traffic, generated: heterogeneous human-like car following in NGSIM's CSV layout.

No I-80 recording ships with the project, so the leader-aware predictor is also evaluated on traffic
generated to have the properties that matter for it in NGSIM I-80 (Emeryville, 4:00-4:15 pm: a
~500 m section, six lanes, the onset of congestion with stop-and-go waves, 10 Hz video positions):

* **lanes** ``lanes`` independent single-lane streams (no lane changes: a stated limitation; the
  leader of a vehicle is its predecessor in its lane for its whole track);
* **traffic state in time**: beyond :data:`BOTTLENECK_M` (50 m downstream of the section) each
  lane's speed is limited by a profile: free flow ``V_FREE`` until 20-40 s, then a congested mean
  ``V_CONG`` with stop-and-go oscillations (amplitude ``A_WAVE``, period ``P_WAVE``) plus an
  Ornstein-Uhlenbeck disturbance, then a partial recovery to 12 m/s from 300-340 s; the queue spills
  back through the section, so it sees free flow, the transition and (mostly) stop-and-go;
* **demand** at the upstream end: Poisson arrivals at ``q_in`` vehicles/s per lane, inserted at up to
  18 m/s when the gap to the last vehicle allows, else queued;
* **drivers** (each its own): IDM (module :mod:`.car_following`) with parameters drawn uniformly
  (``a`` 1.0-2.0 m/s², ``b`` 1.5-2.5 m/s², ``v_0`` 20-27 m/s, ``T`` 1.2-1.9 s, ``s_0`` 1.5-3 m),
  a reaction delay 0.2-0.5 s (the leader's state that long ago, extrapolated at its speed then), and
  an Ornstein-Uhlenbeck acceleration noise (σ 0.15 m/s², correlation time 2 s): not the law the
  predictor calibrates, as real drivers are not;
* **measurement**: the recorded front-bumper position carries white noise (σ 0.25 m) plus a
  correlated error (Ornstein-Uhlenbeck, σ 0.35 m, correlation time 0.5 s), the kind of raw video
  noise that makes NGSIM's accelerations from positions useless without smoothing; ``v_Vel`` and
  ``v_Acc`` are central differences of the noisy positions, as in the raw data.

Only rows whose front bumper lies in the recorded section ``[SECTION_M]`` are written (one track
per vehicle; ``Preceding`` = the lane predecessor's ``Vehicle_ID`` or 0 for the first vehicle of a
lane, which drives the free road).  Units and columns are NGSIM's (feet, ft/s,
ft/s², 18 columns), so ``--format ngsim`` reads the file.
"""

from __future__ import annotations

import gzip
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from iamp.core.atomic import atomic_open
from iamp.prediction._typing import FloatArray

__all__ = ["A_WAVE", "BOTTLENECK_M", "P_WAVE", "SECTION_M", "V_CONG", "V_FREE", "Traffic", "i80_like",
           "write_ngsim_csv"]

#: Recorded section [m] (front-bumper position along the road).
SECTION_M = (300.0, 800.0)
#: Bottleneck speed limit in free flow, the congested mean and the stop-and-go amplitude [m/s], its period [s].
V_FREE, V_CONG, A_WAVE, P_WAVE = 30.0, 4.0, 1.5, 60.0
#: Start of the bottleneck (a speed-limited zone without end) [m].
BOTTLENECK_M = 850.0
_FT = 0.3048
_LENGTH_M = 4.6
_LANE_W_M = 3.7


@dataclass(frozen=True)
class Traffic:
    """Generated traffic: true states and recorded positions at every step.

    Attributes
    ----------
    dt : float
    x_true, x_rec : (K, N) front-bumper positions [m] (NaN before insertion)
    v_true : (K, N) speeds [m/s]
    lane : (N,) int, leader : (N,) int (-1: the virtual head)
    """

    dt: float
    x_true: FloatArray
    x_rec: FloatArray
    v_true: FloatArray
    lane: np.ndarray
    leader: np.ndarray


def _head_speed(t: FloatArray, t_congest: float, t_recover: float, phase: float, ou: FloatArray) -> FloatArray:
    """The bottleneck's speed limit in time (module docstring)."""
    cong = V_CONG + A_WAVE * np.sin(2 * np.pi * t / P_WAVE + phase) + ou
    rec = 12.0 + ou
    w1 = np.clip((t - t_congest) / 20.0, 0.0, 1.0)
    w2 = np.clip((t - t_recover) / 30.0, 0.0, 1.0)
    v = (1 - w1) * V_FREE + w1 * ((1 - w2) * cong + w2 * rec)
    out: FloatArray = np.clip(v, 0.0, 32.0)
    return out


def _ou(rng: np.random.Generator, K: int, n: int, sigma: float, tau: float, dt: float) -> FloatArray:
    """``n`` stationary Ornstein-Uhlenbeck paths of ``K`` steps (std ``sigma``, correlation time ``tau``)."""
    phi = np.exp(-dt / tau)
    z = rng.standard_normal((K, n)) * sigma * np.sqrt(1 - phi ** 2)
    out = np.empty((K, n))
    out[0] = rng.standard_normal(n) * sigma
    for k in range(1, K):
        out[k] = phi * out[k - 1] + z[k]
    return out


def i80_like(seed: int = 0, *, lanes: int = 4, duration_s: float = 420.0, q_in: float = 0.5,
             dt: float = 0.1) -> Traffic:
    """Generate the traffic of the module docstring (deterministic in ``seed``)."""
    rng = np.random.default_rng(seed)
    K = int(round(duration_s / dt)) + 1
    t: FloatArray = np.asarray(dt * np.arange(K), dtype=np.float64)
    nmax = int(lanes * (q_in * duration_s * 1.5 + 20))
    x = np.full((K, nmax), np.nan)
    v = np.full((K, nmax), np.nan)
    lane = np.full(nmax, -1)
    leader = np.full(nmax, -1)
    a_ = rng.uniform(1.0, 2.0, nmax)
    b_ = rng.uniform(1.5, 2.5, nmax)
    v0 = rng.uniform(20.0, 27.0, nmax)
    T = rng.uniform(1.2, 1.9, nmax)
    s0 = rng.uniform(1.5, 3.0, nmax)
    delay = np.round(rng.uniform(0.2, 0.5, nmax) / dt).astype(int)
    noise = _ou(rng, K, nmax, 0.15, 2.0, dt)
    # the bottleneck's speed limit per lane (downstream of the section)
    vb = np.stack([_head_speed(t, rng.uniform(20, 40), rng.uniform(300, 340), rng.uniform(0, 2 * np.pi),
                               _ou(rng, K, 1, 1.0, 5.0, dt)[:, 0]) for _ in range(lanes)], axis=1)
    last = [-1] * lanes  # last inserted vehicle per lane
    next_arrival = rng.exponential(1 / q_in, lanes)
    n = 0
    active = np.zeros(nmax, dtype=bool)
    for k in range(K - 1):
        # insertion at x = 0 (queued arrivals wait for a gap)
        for ln in range(lanes):
            if t[k] < next_arrival[ln] or n >= nmax:
                continue
            j = last[ln]
            vin = 18.0 if j < 0 else min(float(v[k, j]), 18.0)
            if j >= 0 and x[k, j] - _LENGTH_M < s0[n] + vin * T[n] + 2.0:
                continue
            x[k, n], v[k, n], lane[n], leader[n] = 0.0, vin, ln, j
            active[n] = True
            last[ln] = n
            n += 1
            next_arrival[ln] = t[k] + rng.exponential(1 / q_in)
        idx = np.flatnonzero(active)
        if idx.size == 0:
            continue
        kd = np.maximum(k - delay[idx], 0)
        ld = leader[idx]
        has = ld >= 0
        lx = np.where(has, x[kd, np.maximum(ld, 0)], np.inf)
        lv = np.where(has, v[kd, np.maximum(ld, 0)], 0.0)
        # a leader inserted after the delayed instant: use its current state
        lx = np.where(np.isnan(lx), x[k, np.maximum(ld, 0)], lx)
        lv = np.where(np.isnan(lv), v[k, np.maximum(ld, 0)], lv)
        # the driver extrapolates the delayed leader position by the delayed speed (perceived gap)
        lx = lx + lv * (k - kd) * dt
        vk, xk = v[k, idx], x[k, idx]
        s = np.minimum(np.maximum(lx - _LENGTH_M - xk, 0.1), 1e4)
        star = s0[idx] + np.maximum(0.0, vk * T[idx] + vk * (vk - lv) / (2 * np.sqrt(a_[idx] * b_[idx])))
        acc = a_[idx] * (1 - (vk / v0[idx]) ** 4 - (star / s) ** 2) + noise[k, idx]
        # beyond BOTTLENECK_M the speed is limited to the bottleneck's (relaxation, 2 s)
        past = xk > BOTTLENECK_M
        acc = np.where(past, np.minimum(acc, np.clip((vb[k, lane[idx]] - vk) / 2.0, -4.0, 2.0)), acc)
        acc = np.clip(acc, -9.0, 3.0)
        vn = np.maximum(vk + acc * dt, 0.0)
        xn = xk + 0.5 * (vk + vn) * dt
        # no overlap with the true (current) leader
        # no overlap with the leader's new position (leaders are inserted, and stored, before followers)
        pos = np.full(n, -1)
        pos[idx] = np.arange(idx.size)
        lp = pos[np.maximum(ld, 0)]
        cur = np.where(has, xn[lp], np.inf) - _LENGTH_M - 0.5
        over = xn > cur
        vn = np.where(over, np.minimum(vn, np.where(has, vn[lp], vn)), vn)
        xn = np.minimum(xn, cur)
        x[k + 1, idx], v[k + 1, idx] = xn, np.where(np.isnan(vn), 0.0, vn)
    x, v, lane, leader = x[:, :n], v[:, :n], lane[:n], leader[:n]
    meas = 0.25 * rng.standard_normal(x.shape) + _ou(rng, K, n, 0.35, 0.5, dt)
    return Traffic(dt, x, x + meas, v, lane, leader)


def write_ngsim_csv(path: str | os.PathLike[str], traffic: Traffic) -> Path:
    """Write the recorded section of ``traffic`` as an NGSIM CSV (gzip when the name ends in ``.gz``).

    One row per vehicle and frame with the front bumper in :data:`SECTION_M`; ``Vehicle_ID`` = index + 1.
    """
    lo, hi = SECTION_M
    tr = traffic
    lines = ["Vehicle_ID,Frame_ID,Total_Frames,Global_Time,Local_X,Local_Y,Global_X,Global_Y,v_length,v_Width,"
             "v_Class,v_Vel,v_Acc,Lane_ID,Preceding,Following,Space_Headway,Time_Headway"]
    xr = tr.x_rec
    vel = np.gradient(xr, tr.dt, axis=0)
    acc = np.gradient(vel, tr.dt, axis=0)
    for i in range(xr.shape[1]):
        rows = np.flatnonzero((tr.x_true[:, i] >= lo) & (tr.x_true[:, i] <= hi))
        if rows.size < 2:
            continue
        rows = np.arange(rows[0], rows[-1] + 1)
        lat = (tr.lane[i] + 0.5) * _LANE_W_M / _FT
        prec = tr.leader[i] + 1 if tr.leader[i] >= 0 else 0
        for k in rows:
            lines.append(f"{i + 1},{k + 1},{rows.size},{(k + 1) * 100},{lat:.3f},{xr[k, i] / _FT:.3f},0,0,"
                         f"{_LENGTH_M / _FT:.3f},6.000,2,{vel[k, i] / _FT:.3f},{acc[k, i] / _FT:.3f},"
                         f"{tr.lane[i] + 1},{prec},0,0,0")
    data = ("\n".join(lines) + "\n").encode()
    p = Path(path)
    if p.name.endswith(".gz"):
        data = gzip.compress(data, mtime=0)
    with atomic_open(p, "wb", encoding=None) as fh:
        fh.write(data)
    return p
