r"""The leader-aware predictor: a calibrated car-following law along the leader's forecast, MTD elsewhere.

For a follower with a known leader (gap at ``t = 0`` below :data:`~iamp.prediction.leader.car_following.MAX_GAP_M`):

1. ``x_0``, ``v_0`` of the follower and ``x_{l,0}``, ``v_{l,0}`` of the leader from the same RTS
   smoother as every other method (:mod:`iamp.prediction.initial_state`);
2. the leader's forecast over ``[0, t_f]``: constant velocity ``x_{l,0} + v_{l,0} τ`` (or a
   trajectory the caller gives: the leader's recorded future for the oracle bound, the ego's
   plan in a merge, :func:`~iamp.prediction.leader.ego.predict_with_ego_leader`);
3. the follower's trajectory: the calibrated law integrated along that forecast
   (:func:`~iamp.prediction.leader.car_following.simulate`, step 0.1 s).

Without a known leader (or a leader beyond ``MAX_GAP_M``) the prediction **is** the fallback
single-vehicle model's (the MTD predictor, bit for bit).

The model file (``format: iamp-leader/1``, ``kind: "leader"``) holds the law, its parameters
and calibration summary, the leader-forecast rule and the fallback (``"builtin"`` or an embedded
MTD model); :func:`load_any_model` reads either kind and names the offending field otherwise.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict

import numpy as np
from numpy.typing import ArrayLike

from iamp.core.atomic import write_text as atomic_write_text
from iamp.core.scenario import History, VehicleSpec
from iamp.prediction._typing import FloatArray, IntArray, PathLike
from iamp.prediction.initial_state import DEFAULT_JERK_PSD, smooth_histories
from iamp.prediction.leader.car_following import (
    ACC_HALF_WINDOW_S,
    MAX_GAP_M,
    CarFollowingLaw,
    calibrate,
    calibrate_trajectories,
    simulate,
)
from iamp.prediction.leader.leaders import SAME_LANE_TOL_M, Leaders
from iamp.prediction.mtd.model import ModelFileError, ModelJSON, MTDModel
from iamp.prediction.predictor import Predictor
from iamp.prediction.tracks import Tracks

__all__ = [
    "DEFAULT_LEADER_FILE",
    "LEADER_FORMAT",
    "SIM_DT",
    "LeaderModel",
    "LeaderPredictor",
    "calibration_rows",
    "default_leader_model",
    "load_any_model",
    "predict_one",
    "predict_scenario",
    "scenario_leaders",
    "train_default_leader_model",
    "train_leader_model",
]

LEADER_FORMAT = "iamp-leader/1"
#: Step of the forward simulation [s].
SIM_DT = 0.1


class LeaderModelJSON(TypedDict):
    """A leader model file (:meth:`LeaderModel.to_dict`): the law, the leader's forecast, the fallback."""

    format: str
    kind: str
    law: str
    params: dict[str, float]
    fit: dict[str, object]
    leader_forecast: str
    max_gap_m: float
    jerk_psd: float
    fallback: str | ModelJSON  # "builtin": the shipped MTD model
    provenance: dict[str, object]


@dataclass(frozen=True)
class LeaderModel:
    """A calibrated law plus the single-vehicle fallback (module docstring)."""

    law: CarFollowingLaw
    fallback: MTDModel | None = None  # None: the shipped MTD model
    jerk_psd: float = DEFAULT_JERK_PSD
    provenance: dict[str, object] = field(default_factory=dict)

    def to_dict(self) -> LeaderModelJSON:
        """JSON-ready description (``kind: "leader"``)."""
        return {"format": LEADER_FORMAT, "kind": "leader", **self.law.to_dict(),
                "leader_forecast": "constant velocity from the leader's smoothed history",
                "max_gap_m": MAX_GAP_M, "jerk_psd": self.jerk_psd,
                "fallback": "builtin" if self.fallback is None else self.fallback.to_dict(),
                "provenance": self.provenance}

    def save(self, path: PathLike) -> Path:
        """Write the model as JSON, atomically."""
        out = Path(path)
        atomic_write_text(out, json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n")
        return out

    @classmethod
    def from_dict(cls, d: object, source: str | None = None) -> LeaderModel:
        """Inverse of :meth:`to_dict`; :class:`ModelFileError` naming the field."""
        if not isinstance(d, dict):
            raise ModelFileError("must be a JSON object", None, source)
        if d.get("kind") != "leader":
            raise ModelFileError(f"is {d.get('kind')!r}, expected 'leader'", "kind", source)
        if d.get("format") != LEADER_FORMAT:
            raise ModelFileError(f"unsupported format {d.get('format')!r} (expected {LEADER_FORMAT!r})", "format",
                                 source)
        try:
            law = CarFollowingLaw.from_dict(d)
        except (ValueError, TypeError) as exc:
            raise ModelFileError(str(exc), "params", source) from None
        fb = d.get("fallback", "builtin")
        fallback = None if fb == "builtin" else MTDModel.from_dict(fb, source=f"{source}: fallback")
        q = d.get("jerk_psd", DEFAULT_JERK_PSD)
        if not isinstance(q, (int, float)) or not q > 0:
            raise ModelFileError(f"must be a positive number (got {q!r})", "jerk_psd", source)
        return cls(law, fallback, float(q), dict(d.get("provenance") or {}))


#: Package-data file of the shipped leader model (``prediction/data/``).
DEFAULT_LEADER_FILE = "leader_default.json"


def default_leader_model() -> LeaderModel:
    """The shipped leader model (calibrated on the shipped SUMO data, :func:`train_default_leader_model`)."""
    from importlib import resources

    name = f"iamp.prediction/data/{DEFAULT_LEADER_FILE}"
    ref = resources.files("iamp.prediction").joinpath("data", DEFAULT_LEADER_FILE)
    if not ref.is_file():
        raise ModelFileError("the shipped leader model is missing (iamp.prediction.leader.model."
                             "train_default_leader_model('package') rebuilds it)", None, name)
    try:
        d = json.loads(ref.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"is not valid JSON ({exc})", None, name) from None
    return LeaderModel.from_dict(d, name)


def train_default_leader_model(path: PathLike | None = None) -> LeaderModel:
    """Calibrate the shipped leader model on the shipped SUMO data's training tracks (train ∪ val).

    Leaders derived from lane and position; the IDM calibrated on trajectories (windows every
    5 s to bound the cost); fallback: the shipped MTD model.  ``path="package"`` writes
    ``prediction/data/leader_default.json``.
    """
    from iamp.prediction.leader.leaders import derive_leaders
    from iamp.prediction.tracks import load_shipped_dataset
    from iamp.prediction.tracks.split import split_tracks

    tracks = load_shipped_dataset()
    _, _, test, rest = split_tracks(tracks)
    leaders = derive_leaders(rest)
    model = train_leader_model(rest, leaders, "idm", None, {
        "trained_by": "iamp.prediction.leader.model.train_default_leader_model",
        "dataset": "shipped SUMO highway data (prediction/data/sumo_highway.npz), train + validation tracks",
        "n_test_tracks_held_out": int(test.n_tracks)}, stride_s=5.0)
    if path is not None:
        if str(path) == "package":
            path = Path(__file__).resolve().parent / "data" / DEFAULT_LEADER_FILE
        model.save(path)
    return model


def load_any_model(path: PathLike) -> MTDModel | LeaderModel:
    """Read a model file of either kind (``kind`` absent or ``"mtd"``: MTD; ``"leader"``)."""
    p = Path(path)
    try:
        d = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"cannot be read ({exc.__class__.__name__}: {exc})", None, str(p)) from None
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"is not valid JSON ({exc})", None, str(p)) from None
    kind = d.get("kind", "mtd") if isinstance(d, dict) else None
    if kind == "leader":
        return LeaderModel.from_dict(d, str(p))
    if kind == "mtd":
        return MTDModel.from_dict(d, str(p))
    raise ModelFileError(f"unknown model kind {kind!r} (expected 'mtd' or 'leader')", "kind", str(p))


# ---------------------------------------------------------------------------------------
# calibration data
# ---------------------------------------------------------------------------------------

def _central(values: FloatArray, h: int, dt: float, order: int) -> FloatArray:
    """First (``order=1``) or second derivative by central differences over ``±h`` samples (NaN at ends)."""
    out = np.full(values.size, np.nan)
    if values.size > 2 * h:
        if order == 1:
            out[h:-h] = (values[2 * h:] - values[:-2 * h]) / (2 * h * dt)
        else:
            out[h:-h] = (values[2 * h:] - 2 * values[h:-h] + values[:-2 * h]) / (h * dt) ** 2
    return out


def calibration_rows(tracks: Tracks, leaders: Leaders) -> dict[str, FloatArray]:
    """``v, s, vl, a`` of every row with a leader (module docstring of :mod:`.car_following`)."""
    h = max(int(round(ACC_HALF_WINDOW_S / tracks.dt)), 1)
    n = len(tracks)
    v = np.full(n, np.nan)
    a = np.full(n, np.nan)
    cuts = np.flatnonzero(np.diff(tracks.track_id)) + 1
    starts = np.concatenate(([0], cuts))
    for s0, xs in zip(starts, np.split(tracks.x, cuts)):
        v[s0:s0 + xs.size] = _central(xs, h, tracks.dt, 1)
        a[s0:s0 + xs.size] = _central(xs, h, tracks.dt, 2)
    frame = np.round(tracks.t / tracks.dt).astype(np.int64)
    rows = _row_lookup(tracks, frame)
    lr = rows(leaders.leader, frame)
    ok = (leaders.leader >= 0) & (lr >= 0)
    L = leaders.lengths()
    i = np.flatnonzero(ok)
    j = lr[ok]
    s = tracks.x[j] - tracks.x[i] - 0.5 * (L[i] + L[j])
    return {"v": v[i], "s": s, "vl": v[j], "a": a[i]}


def _row_lookup(tracks: Tracks, frame: IntArray) -> Callable[[IntArray, IntArray], IntArray]:
    key = tracks.track_id * 100_000_000 + frame
    order = np.argsort(key, kind="stable")
    sk = key[order]

    def rows(tid: IntArray, fr: IntArray) -> IntArray:
        k = np.asarray(tid, dtype=np.int64) * 100_000_000 + fr
        pos = np.clip(np.searchsorted(sk, k), 0, max(sk.size - 1, 0))
        out: IntArray = np.where((tid >= 0) & (sk[pos] == k), order[pos], -1)
        return out

    return rows


#: How the law is calibrated by default (:func:`train_leader_model`).
CALIBRATION = "trajectory"
#: The leader trajectory the trajectory calibration follows by default.
CALIBRATION_LEADER = "cv"


def train_leader_model(tracks: Tracks, leaders: Leaders, law: str = "idm", fallback: MTDModel | None = None,
                       provenance: Mapping[str, object] | None = None, *, calibration: str = CALIBRATION,
                       leader: str = CALIBRATION_LEADER, stride_s: float = 1.0) -> LeaderModel:
    """Calibrate ``law`` on the rows / windows of ``tracks`` that have a leader.

    ``calibration="acceleration"``: least squares on observed accelerations
    (:func:`~iamp.prediction.leader.car_following.calibrate`).  ``"trajectory"`` (default): that fit
    refined on the 3 s + 5 s windows of ``tracks`` with a known leader
    (:func:`~iamp.prediction.leader.car_following.calibrate_trajectories`), the simulated follower
    starting from the smoothed initial state and following the leader's constant-velocity
    forecast (``leader="cv"``, default: the law is calibrated for the prediction it makes) or its
    recorded future (``leader="recorded"``: the behavioural law).
    """
    from iamp.prediction.windows import make_windows

    from .windows import leader_windows

    if calibration not in ("acceleration", "trajectory"):
        raise ValueError(f"calibration must be 'acceleration' or 'trajectory' (got {calibration!r})")
    if leader not in ("cv", "recorded"):
        raise ValueError(f"leader must be 'cv' or 'recorded' (got {leader!r})")
    if not np.any(leaders.leader >= 0):
        raise ValueError(f"no vehicle has a known leader, so no car-following law can be calibrated (leaders: "
                         f"{leaders.source})")
    d = calibration_rows(tracks, leaders)
    cf = calibrate(law, d["v"], d["s"], d["vl"], d["a"])
    q = float(fallback.settings.get("jerk_psd", DEFAULT_JERK_PSD)) if fallback is not None else DEFAULT_JERK_PSD
    if calibration == "trajectory":
        win = make_windows(tracks, stride_s=stride_s)
        lw = leader_windows(tracks, leaders, win)
        k = lw.known
        if int(np.sum(k)) < 5:
            raise ValueError(f"too few windows with a known leader to calibrate on trajectories ({int(np.sum(k))}; "
                             f"leaders: {leaders.source})")
        sm = smooth_histories(win.t_hist, win.X_hist[k], q)
        x0, v0 = sm.x[:, -1], np.maximum(sm.v[:, -1], 0.0)
        x_true = np.concatenate([win.X_hist[k][:, -1:], win.X_fut[k]], axis=1)
        tn = SIM_DT * np.arange(x_true.shape[1])
        if leader == "recorded":
            xl = np.concatenate([lw.XL_hist[k][:, -1:], lw.XL_fut[k]], axis=1)
            vl = np.gradient(xl, tn, axis=1)
        else:
            sl = smooth_histories(win.t_hist, lw.XL_hist[k], q)
            vl0 = np.maximum(sl.v[:, -1], 0.0)
            xl = sl.x[:, -1:] + vl0[:, None] * tn[None, :]
            vl = np.repeat(vl0[:, None], tn.size, axis=1)
        near = (xl[:, 0] - x0 - lw.offset[k]) < MAX_GAP_M
        cf = calibrate_trajectories(cf, x0[near], v0[near], xl[near], vl[near], lw.offset[k][near], x_true[near],
                                    SIM_DT)
        cf = CarFollowingLaw(cf.name, cf.params, {**cf.fit, "leader_trajectory": leader})
    prov = {"n_tracks": int(tracks.n_tracks), "leader_source": leaders.source,
            "leader_known_fraction": leaders.known_fraction, "calibration": calibration, **(provenance or {})}
    return LeaderModel(cf, fallback, q, prov)


# ---------------------------------------------------------------------------------------
# prediction
# ---------------------------------------------------------------------------------------

class LeaderPredictor:
    """Batched leader-aware prediction (module docstring).

    Parameters
    ----------
    model : LeaderModel
    name : str
    """

    def __init__(self, model: LeaderModel, name: str = "leader"):
        self.model = model
        self.name = name
        self.fallback = Predictor(model.fallback, "fallback") if model.fallback is not None else Predictor.default()

    @classmethod
    def from_file(cls, path: PathLike) -> LeaderPredictor:
        """A predictor from a ``kind: "leader"`` model file."""
        m = load_any_model(path)
        if not isinstance(m, LeaderModel):
            raise ModelFileError("is an MTD model; a leader model (kind 'leader') is needed here", "kind", str(path))
        return cls(m, str(path))

    def _nodes(self, tf: float) -> FloatArray:
        M = max(int(math.ceil(tf / SIM_DT - 1e-9)), 1)
        t: FloatArray = np.asarray(SIM_DT * np.arange(M + 1), dtype=np.float64)
        return t

    def leader_forecast_cv(self, t_hist: FloatArray, XL_hist: FloatArray, tf: float) -> tuple[FloatArray, FloatArray]:
        """The leaders' constant-velocity forecasts ``(xl, vl)`` at the simulation nodes over ``[0, tf]``."""
        sm = smooth_histories(np.asarray(t_hist, dtype=float), np.atleast_2d(XL_hist), self.model.jerk_psd)
        t = self._nodes(tf)
        v = np.maximum(sm.v[:, -1], 0.0)
        xl: FloatArray = sm.x[:, -1:] + v[:, None] * t[None, :]
        return xl, np.repeat(v[:, None], t.size, axis=1)

    def predict_batch(self, t_hist: FloatArray, X_hist: FloatArray, query: FloatArray, tf: float, *,
                      XL_hist: FloatArray | None = None, has_leader: ArrayLike | None = None,
                      offset: ArrayLike = 4.5,
                      leader_future: tuple[FloatArray, FloatArray] | None = None) -> FloatArray:
        """Positions at ``query`` of ``B`` followers sharing the history times ``t_hist``.

        Parameters
        ----------
        t_hist : numpy.ndarray, shape (K,)
        X_hist : numpy.ndarray, shape (B, K)
            Followers' observed positions (centres).
        query : numpy.ndarray, shape (Q,)
            Times in ``[0, tf]``.
        tf : float
        XL_hist : numpy.ndarray, shape (B, K), optional
            Leaders' observed positions at ``t_hist`` (same frame); rows without a leader are ignored.
        has_leader : array of bool, shape (B,), optional
            Default: ``XL_hist`` given and finite.
        offset : float or array (B,)
            ``(L_leader + L_follower) / 2`` [m].
        leader_future : (xl, vl), each (B, M + 1) at the nodes ``0, 0.1, ..`` s, optional
            The leaders' trajectories to follow instead of their CV forecast (oracle, ego's plan).

        Returns
        -------
        numpy.ndarray, shape (B, Q)
        """
        t_hist = np.asarray(t_hist, dtype=float)
        X_hist = np.atleast_2d(np.asarray(X_hist, dtype=float))
        B = X_hist.shape[0]
        q = np.asarray(query, dtype=float)
        out = self.fallback.predict_batch(t_hist, X_hist, q, tf)
        if XL_hist is None and leader_future is None:
            return out
        if has_leader is None:
            hl = np.ones(B, dtype=bool) if XL_hist is None else np.all(np.isfinite(np.atleast_2d(XL_hist)), axis=1)
        else:
            hl = np.asarray(has_leader, dtype=bool).copy()
        off = np.broadcast_to(np.asarray(offset, dtype=float), (B,))
        sm = smooth_histories(t_hist, X_hist, self.model.jerk_psd)
        x0, v0 = sm.x[:, -1], np.maximum(sm.v[:, -1], 0.0)
        if leader_future is not None:
            xl, vl = (np.atleast_2d(np.asarray(z, dtype=float)) for z in leader_future)
        else:
            assert XL_hist is not None
            XL = np.where(np.isfinite(XL_hist), XL_hist, 0.0)
            xl, vl = self.leader_forecast_cv(t_hist, XL, tf)
        gap0 = xl[:, 0] - x0 - off
        use = hl & np.isfinite(gap0) & (gap0 < MAX_GAP_M)
        if not np.any(use):
            return out
        t = self._nodes(tf)
        if xl.shape[1] != t.size:
            raise ValueError(f"leader_future must have {t.size} nodes (0..{t[-1]:g} s by {SIM_DT:g} s)")
        xs, _ = simulate(self.model.law, x0[use], v0[use], xl[use], vl[use], off[use], SIM_DT)
        out[use] = np.stack([np.interp(q, t, row) for row in xs])
        return out


def scenario_leaders(vehicles: Sequence[VehicleSpec]) -> dict[int, int]:
    """Leader index of every history vehicle of a scenario: the nearest history vehicle ahead at ``t = 0``
    whose ``|y - y_i|`` is below :data:`SAME_LANE_TOL_M` (half a 3.5-m lane)."""
    out: dict[int, int] = {}
    have = [(i, v, v.history) for i, v in enumerate(vehicles) if v.history is not None]
    for i, v, hv in have:
        x_i = float(hv.x[-1])
        best = None
        for j, w, hw in have:
            if j == i or abs(float(w.y) - float(v.y)) >= SAME_LANE_TOL_M:
                continue
            dx = float(hw.x[-1]) - x_i
            if dx > 0 and (best is None or dx < best[0]):
                best = (dx, j)
        if best is not None:
            out[i] = best[1]
    return out


def predict_one(predictor: LeaderPredictor, history: History, tf: float, *, leader_history: History | None = None,
                offset: float = 4.5) -> tuple[tuple[float, ...], FloatArray, FloatArray]:
    """One vehicle's leader-aware prediction ``(x_poly, t, x)`` (the closed loop's per-neighbour call).

    ``history`` and ``leader_history`` have ``.t`` and ``.x`` (e.g. :class:`iamp.core.scenario.History`);
    the leader's is interpolated onto the follower's times and counts as unknown unless it covers
    them.  Without a known leader: the fallback MTD predictor's own prediction and cubic.
    ``offset`` = ``(L_leader + L_follower)/2`` [m].
    """
    th = np.asarray(history.t, dtype=float)
    xh = np.asarray(history.x, dtype=float)
    if leader_history is not None:
        lt = np.asarray(leader_history.t, dtype=float)
        if lt[0] <= th[0] + 1e-9 and lt[-1] >= th[-1] - 1e-9:
            t = predictor._nodes(tf)
            t[-1] = tf
            xl = np.interp(th, lt, np.asarray(leader_history.x, dtype=float))[None, :]
            x: FloatArray = predictor.predict_batch(th, xh[None, :], t, tf, XL_hist=xl, offset=offset)[0]
            c, *_ = np.linalg.lstsq(np.vander(t, 4, increasing=True), x, rcond=None)
            return tuple(float(z) for z in c), t, x
    p = predictor.fallback.predict(history, tf)
    return tuple(float(z) for z in p.x_poly), np.asarray(p.t, dtype=float), np.asarray(p.x, dtype=float)


def predict_scenario(predictor: LeaderPredictor, vehicles: Sequence[VehicleSpec],
                     tf: float) -> dict[int, tuple[tuple[float, ...],
                                                                                          FloatArray, FloatArray]]:
    """Leader-aware predictions ``{index: (x_poly, t, x)}`` of a scenario's history vehicles.

    The leader of a vehicle is :func:`scenario_leaders`'s; each vehicle is :func:`predict_one`'s
    (a leader whose history does not cover the follower's counts as unknown; without a known
    leader the fallback MTD predictor's own prediction and cubic, identical to planning without a
    leader model).  ``x_poly``: the least-squares cubic over ``[0, tf]`` (SPEC §7).
    """
    lead = scenario_leaders(vehicles)
    out = {}
    for i, v in enumerate(vehicles):
        if v.history is None:
            continue
        j = lead.get(i)
        out[i] = predict_one(predictor, v.history, tf, leader_history=None if j is None else vehicles[j].history,
                             offset=0.5 * (float(v.length) + float(vehicles[j].length)) if j is not None else 4.5)
    return out
