r"""Car-following laws, their calibration on observed accelerations, and the batched forward simulation.

A law gives the follower's acceleration from its speed ``v``, the bumper-to-bumper gap ``s``
to its leader and the leader's speed ``v_l``.

IDM (Treiber, Hennecke & Helbing 2000), parameters ``θ = (a, b, v_0, T, s_0)``:

.. math::

    \dot v = a\Big[1 - (v/v_0)^4 - \big(s^*(v, Δv)/s\big)^2\Big], \qquad
    s^* = s_0 + \max\!\Big(0,\ vT + \frac{v\,Δv}{2\sqrt{ab}}\Big), \quad Δv = v - v_l .

In equilibrium (``Δv = 0``, ``\dot v = 0``) the gap is
``s_e(v) = s^*(v, 0) / \sqrt{1 - (v/v_0)^4}`` (:func:`idm_equilibrium_gap`).

Linear (Helly 1959), parameters ``θ = (c_v, c_s, T, s_0)``:

.. math::

    \dot v = c_v (v_l - v) + c_s \big(s - s_0 - T v\big),

zero at ``v_l = v``, ``s = s_0 + T v`` (the equilibrium gap).  It is linear in
``(c_v, c_s, -c_s T, -c_s s_0)``, so its least-squares fit is closed form.

Calibration (:func:`calibrate`): least squares of the law's acceleration against the observed
accelerations of every training row that has a leader within :data:`MAX_GAP_M` (the
accelerations are second differences of the positions over ``±`` :data:`ACC_HALF_WINDOW_S`,
the speeds first differences over the same window, the leader's alike at the same instants).
IDM by ``scipy.optimize.least_squares`` inside physical bounds; the linear law by ``lstsq``.

Simulation (:func:`simulate`): the law integrated forward at step ``dt`` along a given leader
trajectory (the leader's forecast, or its recorded future for the oracle bound), acceleration
clipped to ``[-B_MAX, A_MAX]`` m/s², speed clamped at 0, position never beyond the leader's
rear minus :data:`MIN_GAP_M`:

.. math::

    v_{k+1} = \max(v_k + \dot v_k\,dt,\ 0), \qquad x_{k+1} = x_k + \tfrac12 (v_k + v_{k+1})\,dt .

IDM's simulation is :func:`iamp.prediction.leader.kernel.idm_forward`, one function run compiled
by numba when it is importable and as Python otherwise (the same numbers bit for bit).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
from numpy.typing import ArrayLike

from iamp.prediction._typing import FloatArray
from iamp.prediction.leader.kernel import compiled, idm_forward

__all__ = ["ACC_HALF_WINDOW_S", "A_MAX", "B_MAX", "LAWS", "MAX_GAP_M", "MIN_GAP_M", "CarFollowingLaw",
           "accel", "calibrate", "calibrate_trajectories", "idm_equilibrium_gap", "linear_equilibrium_gap", "simulate"]

#: The laws :func:`calibrate` knows.
LAWS = ("idm", "linear")
#: Clip of the simulated acceleration [m/s²].
A_MAX, B_MAX = 3.0, 8.0
#: Smallest simulated gap [m].
MIN_GAP_M = 0.5
#: Leaders farther than this do not enter the calibration [m].
MAX_GAP_M = 80.0
#: Half-window of the finite differences of the calibration data [s].
ACC_HALF_WINDOW_S = 0.5

_IDM_NAMES = ("a", "b", "v0", "T", "s0")
_IDM_LO = np.array([0.1, 0.1, 5.0, 0.1, 0.0])
_IDM_HI = np.array([6.0, 10.0, 45.0, 4.0, 10.0])
_IDM_START = np.array([1.0, 1.5, 30.0, 1.2, 2.0])
_LIN_NAMES = ("c_v", "c_s", "T", "s0")


class LawJSON(TypedDict):
    """:meth:`CarFollowingLaw.to_dict`: the law's name, its parameters and how they were fitted."""

    law: str
    params: dict[str, float]
    fit: dict[str, object]


@dataclass(frozen=True)
class CarFollowingLaw:
    """A calibrated law: ``name`` in :data:`LAWS` and its parameters (module docstring).

    Attributes
    ----------
    name : str
    params : dict of str to float
        IDM: ``a, b, v0, T, s0``; linear: ``c_v, c_s, T, s0``.
    fit : dict
        Calibration summary (rows, RMS residual, RMS of the data).
    """

    name: str
    params: dict[str, float]
    fit: dict[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.name not in LAWS:
            raise ValueError(f"law must be one of {', '.join(LAWS)} (got {self.name!r})")
        need = _IDM_NAMES if self.name == "idm" else _LIN_NAMES
        missing = [k for k in need if k not in self.params]
        if missing:
            raise ValueError(f"{self.name} law lacks parameter(s) {', '.join(missing)}")
        p = {k: float(self.params[k]) for k in need}
        if not all(np.isfinite(list(p.values()))):
            raise ValueError(f"{self.name} parameters must be finite")
        if self.name == "idm" and not (p["a"] > 0 and p["b"] > 0 and p["v0"] > 0 and p["T"] >= 0 and p["s0"] >= 0):
            raise ValueError("IDM needs a, b, v0 > 0 and T, s0 >= 0")
        object.__setattr__(self, "params", p)

    def to_dict(self) -> LawJSON:
        """JSON-ready ``{"law", "params", "fit"}``."""
        return {"law": self.name, "params": dict(self.params), "fit": self.fit}

    @classmethod
    def from_dict(cls, d: object) -> CarFollowingLaw:
        """Inverse of :meth:`to_dict` (``ValueError`` on a bad description)."""
        if not isinstance(d, dict) or "law" not in d or not isinstance(d.get("params"), dict):
            raise ValueError("a law is an object with 'law' and 'params'")
        return cls(str(d["law"]), {str(k): float(v) for k, v in d["params"].items()}, dict(d.get("fit") or {}))

    def equilibrium_gap(self, v: ArrayLike) -> FloatArray:
        """Gap at which a follower at speed ``v`` behind a leader at the same speed keeps ``v``."""
        if self.name == "idm":
            return idm_equilibrium_gap(self.params, v)
        return linear_equilibrium_gap(self.params, v)


def idm_equilibrium_gap(p: dict[str, float], v: ArrayLike) -> FloatArray:
    r"""``s_e(v) = (s_0 + vT)/\sqrt{1 - (v/v_0)^4}`` (``inf`` for ``v >= v_0``)."""
    speed = np.asarray(v, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 1.0 - (speed / p["v0"]) ** 4
        out: FloatArray = np.where(d > 0, (p["s0"] + speed * p["T"]) / np.sqrt(np.where(d > 0, d, 1.0)), np.inf)
    return out


def linear_equilibrium_gap(p: dict[str, float], v: ArrayLike) -> FloatArray:
    """``s_e(v) = s_0 + T v``."""
    out: FloatArray = p["s0"] + p["T"] * np.asarray(v, dtype=float)
    return out


def _idm(theta: FloatArray, v: FloatArray, s: FloatArray, vl: FloatArray) -> FloatArray:
    a, b, v0, T, s0 = theta
    dv = v - vl
    star = s0 + np.maximum(0.0, v * T + v * dv / (2.0 * np.sqrt(a * b)))
    out: FloatArray = a * (1.0 - (np.maximum(v, 0.0) / v0) ** 4 - (star / np.maximum(s, 0.1)) ** 2)
    return out


def accel(law: CarFollowingLaw, v: ArrayLike, s: ArrayLike, vl: ArrayLike) -> FloatArray:
    """The law's acceleration (unclipped) at speed ``v``, gap ``s`` and leader speed ``vl``."""
    v, s, vl = (np.asarray(z, dtype=float) for z in (v, s, vl))
    p = law.params
    if law.name == "idm":
        return _idm(np.array([p[k] for k in _IDM_NAMES]), v, s, vl)
    out: FloatArray = p["c_v"] * (vl - v) + p["c_s"] * (s - p["s0"] - p["T"] * v)
    return out


def calibrate(name: str, v: FloatArray, s: FloatArray, vl: FloatArray, a_obs: FloatArray) -> CarFollowingLaw:
    """Least-squares fit of a law to observed accelerations (module docstring).

    Parameters
    ----------
    name : {"idm", "linear"}
    v, s, vl, a_obs : numpy.ndarray, shape (N,)
        Follower speed, gap, leader speed and observed follower acceleration per row.
    """
    v, s, vl, a_obs = (np.asarray(z, dtype=float) for z in (v, s, vl, a_obs))
    ok = np.isfinite(v) & np.isfinite(s) & np.isfinite(vl) & np.isfinite(a_obs) & (s > 0) & (s < MAX_GAP_M)
    v, s, vl, a_obs = v[ok], s[ok], vl[ok], a_obs[ok]
    if v.size < 10:
        raise ValueError(f"too few rows with a leader to calibrate the {name} law ({v.size})")
    if name == "idm":
        from scipy.optimize import least_squares

        res = least_squares(lambda th: _idm(th, v, s, vl) - a_obs, _IDM_START, bounds=(_IDM_LO, _IDM_HI),
                            loss="soft_l1", f_scale=1.0, max_nfev=200)
        params = dict(zip(_IDM_NAMES, (float(x) for x in res.x)))
        law = CarFollowingLaw("idm", params)
    elif name == "linear":
        A = np.stack([vl - v, s, v, np.ones_like(v)], axis=1)
        c, *_ = np.linalg.lstsq(A, a_obs, rcond=None)
        c_v, c_s = float(c[0]), float(c[1])
        if c_s <= 1e-9:
            raise ValueError(f"the linear law's gap gain came out {c_s:.3g} <= 0: the data show no car following")
        law = CarFollowingLaw("linear", {"c_v": c_v, "c_s": c_s, "T": float(-c[2] / c_s), "s0": float(-c[3] / c_s)})
    else:
        raise ValueError(f"law must be one of {', '.join(LAWS)} (got {name!r})")
    r = accel(law, v, s, vl) - a_obs
    fit = {"rows": int(v.size), "rms_residual_mps2": float(np.sqrt(np.mean(r * r))),
           "rms_data_mps2": float(np.sqrt(np.mean(a_obs * a_obs))), "criterion": "least squares on accelerations"
           + (" (soft-L1 loss, scale 1 m/s^2)" if name == "idm" else "")}
    return CarFollowingLaw(law.name, law.params, fit)


def simulate(law: CarFollowingLaw, x0: ArrayLike, v0: ArrayLike, xl: FloatArray, vl: FloatArray, offset: ArrayLike,
             dt: float) -> tuple[FloatArray, FloatArray]:
    """Follower positions and speeds at the nodes ``k dt``, ``k = 0..M``, along leader trajectories.

    Parameters
    ----------
    law : CarFollowingLaw
    x0, v0 : array_like, shape (B,)
        Follower centre position and speed at ``t = 0``.
    xl, vl : numpy.ndarray, shape (B, M + 1)
        Leader centre positions and speeds at the nodes.
    offset : array_like, shape (B,)
        Half the sum of the two lengths: gap ``s = xl - x - offset``.
    dt : float

    Returns
    -------
    x, v : numpy.ndarray, shape (B, M + 1)
    """
    xl = np.atleast_2d(np.asarray(xl, dtype=float))
    vl = np.atleast_2d(np.asarray(vl, dtype=float))
    B, M1 = xl.shape
    x = np.empty((B, M1))
    v = np.empty((B, M1))
    x[:, 0] = np.broadcast_to(np.asarray(x0, dtype=float), (B,))
    v[:, 0] = np.maximum(np.broadcast_to(np.asarray(v0, dtype=float), (B,)), 0.0)
    off = np.broadcast_to(np.asarray(offset, dtype=float), (B,))
    if law.name == "idm":
        p = law.params
        args = (p["a"], p["b"], p["v0"], p["T"], p["s0"])
        run = compiled()
        if run is not None:
            xf, vf = x.reshape(-1), v.reshape(-1)  # views: written in place
            run(*args, xf, vf, np.ascontiguousarray(xl).reshape(-1), np.ascontiguousarray(vl).reshape(-1),
                np.ascontiguousarray(off), B, M1, float(dt), A_MAX, B_MAX, MIN_GAP_M)
        else:  # the same function as Python, on lists of floats: the same numbers
            xs, vs = x.reshape(-1).tolist(), v.reshape(-1).tolist()
            idm_forward(*args, xs, vs, xl.reshape(-1).tolist(), vl.reshape(-1).tolist(), off.tolist(), B, M1,
                        float(dt), A_MAX, B_MAX, MIN_GAP_M)
            x, v = np.array(xs).reshape(B, M1), np.array(vs).reshape(B, M1)
        return x, v
    for k in range(M1 - 1):
        s = xl[:, k] - x[:, k] - off
        a = np.clip(accel(law, v[:, k], s, vl[:, k]), -B_MAX, A_MAX)
        vn = np.maximum(v[:, k] + a * dt, 0.0)
        xn = x[:, k] + 0.5 * (v[:, k] + vn) * dt
        cap = xl[:, k + 1] - off - MIN_GAP_M
        over = xn > cap
        if np.any(over):
            xn = np.where(over, np.maximum(cap, x[:, k]), xn)
            vn = np.where(over, np.minimum(vn, np.maximum(vl[:, k + 1], 0.0)), vn)
        x[:, k + 1], v[:, k + 1] = xn, vn
    return x, v


def calibrate_trajectories(start: CarFollowingLaw, x0: FloatArray, v0: FloatArray, xl: FloatArray, vl: FloatArray,
                           offset: FloatArray, x_true: FloatArray, dt: float) -> CarFollowingLaw:
    r"""Refine a law on trajectories: least squares of the simulated positions against the recorded ones.

    Minimises ``Σ_w Σ_k (x_{w,k}(θ) - x^{rec}_{w,k})²`` over the windows ``w`` and nodes ``k``
    (:func:`simulate` along the given leader trajectories ``xl``, ``vl``), starting from ``start``
    (IDM inside the bounds of :func:`calibrate`; the linear law with ``c_v, c_s >= 0``).
    The calibration that matches the prediction task: a law that fits one-step accelerations
    need not predict 5 s well (on US-101 the acceleration fit of IDM runs into its bounds).
    """
    from scipy.optimize import least_squares

    names = _IDM_NAMES if start.name == "idm" else _LIN_NAMES
    th0 = np.array([start.params[k] for k in names])
    if start.name == "idm":
        lo, hi = _IDM_LO, _IDM_HI
    else:
        lo = np.array([0.0, 0.0, -5.0, -20.0])
        hi = np.array([5.0, 5.0, 10.0, 100.0])
    th0 = np.clip(th0, lo + 1e-9, hi - 1e-9)

    def resid(th: FloatArray) -> FloatArray:
        law = CarFollowingLaw(start.name, dict(zip(names, (float(z) for z in th))))
        xs, _ = simulate(law, x0, v0, xl, vl, offset, dt)
        r: FloatArray = (xs - x_true).ravel()
        return r

    res = least_squares(resid, th0, bounds=(lo, hi), x_scale="jac", max_nfev=300)
    law = CarFollowingLaw(start.name, dict(zip(names, (float(z) for z in res.x))))
    r0, r1 = resid(th0), resid(res.x)
    fit = {**{f"acceleration_fit_{k}": v for k, v in start.fit.items()},
           "trajectory_windows": int(np.atleast_2d(x0).size),
           "trajectory_rms_m_start": float(np.sqrt(np.mean(r0 * r0))),
           "trajectory_rms_m": float(np.sqrt(np.mean(r1 * r1))),
           "criterion": "least squares on positions over the windows (start: least squares on accelerations)"}
    return CarFollowingLaw(law.name, law.params, fit)
