r"""Evaluation that shows the interaction: leader windows, the split by traffic state and by leader, CIs.

Leader of a window: the follower's leader at ``t = 0`` (:class:`~iamp.prediction.leader.leaders.Leaders`),
*known* when that leader's track covers the whole 3-s history ``[t_0 - 3, t_0]`` (its observed past is
what a predictor may use).  Its recorded future (for the oracle bound only) is used where its track
covers ``[t_0, t_0 + 5]``; otherwise the oracle continues the recording at the leader's last recorded
speed (counted in ``leader_future_extended``).

Traffic state of a window: **congested** when the follower's smoothed speed at ``t = 0`` is below
:data:`CONGESTED_BELOW_MPS` (60 km/h, the usual speed threshold between free-flow and congested
freeway operation), else **free**.

Intervals: percentile 95 % intervals of a **track bootstrap** (tracks resampled with replacement,
each window weighted by its track's multiplicity; ``B`` resamples) of each method's RMSE at every
horizon, its ADE and FDE, and of their differences to constant velocity.
"""

from __future__ import annotations

import numpy as np

from iamp.prediction._typing import BoolArray, FloatArray, IntArray, PathLike
from iamp.prediction.leader.leaders import Leaders
from iamp.prediction.leader.windows import LeaderWindows, leader_windows
from iamp.prediction.mtd.model import MTDModel
from iamp.prediction.tracks import Tracks
from iamp.prediction.windows import HORIZONS, Windows

from .records import BootstrapTable, InteractionSection, MethodRow

__all__ = ["CONGESTED_BELOW_MPS", "LeaderWindows", "bootstrap_table", "errors", "leader_windows", "subset_tables"]

#: Speed [m/s] below which a window counts as congested (60 km/h).
CONGESTED_BELOW_MPS = 60.0 / 3.6




def errors(pred: FloatArray, X_fut: FloatArray, t_fut: FloatArray) -> dict[str, FloatArray]:
    """Per window: squared errors at the horizons ``(W, H)``, mean ``|e|`` and ``|e(5 s)|``."""
    err = pred - X_fut
    cols = [int(np.argmin(np.abs(t_fut - h))) for h in HORIZONS]
    return {"sq": err[:, cols] ** 2, "ade": np.mean(np.abs(err), axis=1), "fde": np.abs(err[:, -1])}


def _ci(x: FloatArray) -> list[float]:
    lo, hi = np.quantile(x, [0.025, 0.975])
    return [float(lo), float(hi)]


def bootstrap_table(errs: dict[str, dict[str, FloatArray]], track_id: IntArray, seed: int = 0,
                    resamples: int = 1000, reference: str = "cv") -> BootstrapTable:
    """Every method's RMSE per horizon, ADE, FDE with track-bootstrap 95 % intervals, and its difference to CV."""
    _, code = np.unique(track_id, return_inverse=True)
    T = int(code.max()) + 1 if code.size else 0
    out: BootstrapTable = {"windows": int(track_id.size), "tracks": T}
    if T == 0:
        return out
    rng = np.random.default_rng(seed)
    wts = rng.multinomial(T, np.full(T, 1.0 / T), size=resamples).astype(float)

    def tsum(x: FloatArray) -> FloatArray:
        v = x.reshape(x.shape[0], -1)
        acc = np.zeros((T, v.shape[1]))
        np.add.at(acc, code, v)
        return acc

    n_w = wts @ tsum(np.ones(track_id.size))
    n_w = np.maximum(n_w, 1e-12)
    boot: dict[str, tuple[FloatArray, FloatArray, FloatArray]] = {}
    for name, e in errs.items():
        boot[name] = (np.sqrt(wts @ tsum(e["sq"]) / n_w), (wts @ tsum(e["ade"]) / n_w)[:, 0],
                      (wts @ tsum(e["fde"]) / n_w)[:, 0])
    methods: dict[str, MethodRow] = {}
    ref = errs.get(reference)
    for name, e in errs.items():
        rm = np.sqrt(np.mean(e["sq"], axis=0))
        row: MethodRow = {
            "rmse_m": [float(v) for v in rm], "rmse_ci95": [_ci(boot[name][0][:, h]) for h in range(rm.size)],
            "ade_m": float(np.mean(e["ade"])), "ade_ci95": _ci(boot[name][1]),
            "fde_m": float(np.mean(e["fde"])), "fde_ci95": _ci(boot[name][2])}
        if ref is not None and name != reference:
            rref = np.sqrt(np.mean(ref["sq"], axis=0))
            b0 = boot[reference]
            row["diff_to_cv"] = {
                "rmse_m": [float(a - b) for a, b in zip(rm, rref)],
                "rmse_ci95": [_ci(boot[name][0][:, h] - b0[0][:, h]) for h in range(rm.size)],
                "rmse_5s_rel": float(rm[-1] / rref[-1] - 1.0),
                "rmse_5s_rel_ci95": _ci(boot[name][0][:, -1] / b0[0][:, -1] - 1.0),
                "fde_m": float(np.mean(e["fde"]) - np.mean(ref["fde"])), "fde_ci95": _ci(boot[name][2] - b0[2])}
        methods[name] = row
    out["methods"] = methods
    return out


def subset_tables(errs: dict[str, dict[str, FloatArray]], track_id: IntArray, masks: dict[str, BoolArray],
                  seed: int = 0, resamples: int = 1000) -> dict[str, BootstrapTable]:
    """:func:`bootstrap_table` of every named subset of the windows (empty subsets: only the counts)."""
    out: dict[str, BootstrapTable] = {}
    for name, m in masks.items():
        sub = {k: {f: v[m] for f, v in e.items()} for k, e in errs.items()}
        out[name] = bootstrap_table(sub, track_id[m], seed, resamples)
    return out


def _rows_mask(full: Tracks, part: Tracks) -> BoolArray:
    """Rows of ``full`` that are in ``part`` (a row subset), by ``(track_id, frame)``."""
    def key(tb: Tracks) -> IntArray:
        out: IntArray = tb.track_id * 100_000_000 + np.round(tb.t / tb.dt).astype(np.int64)
        return out

    return np.isin(key(full), key(part))


def interaction_section(data: PathLike, fmt: str, tracks: Tracks, test: Tracks, train: Tracks | None, win: Windows,
                        mtd: MTDModel, preds: dict[str, FloatArray], *, leader_model: str | None, split: str | None,
                        seed: int, resamples: int) -> tuple[InteractionSection, dict[str, FloatArray]]:
    """The leader-aware rows and the ``interaction`` section of ``evaluate-predictor`` (module docstring).

    Returns ``(section, extra predictions)``: ``extra`` holds ``"leader"`` (the leader-aware
    predictor with the leader's CV forecast), which joins the §13 tables; the section holds the
    tables of every method overall, per traffic state and per leader known/unknown, with the
    oracle bound ``"leader-oracle"``: a law along the leader's *recorded* future (smoothed over its
    past and future together); in a split the law is calibrated along the recorded leader futures
    of the training part (what the follower did given what its leader did), else the evaluated
    model's law.
    """
    from iamp.prediction.initial_state import smooth_histories
    from iamp.prediction.leader.leaders import leaders_for
    from iamp.prediction.leader.model import LeaderPredictor, default_leader_model, train_leader_model
    from iamp.prediction.windows import FUTURE_S

    leaders = leaders_for(data, fmt, tracks)
    if split is None:
        lm = (LeaderPredictor.from_file(leader_model).model if leader_model is not None else default_leader_model())
        note = leader_model if leader_model is not None else "builtin (calibrated on the shipped SUMO data)"
    else:
        assert train is not None
        m = _rows_mask(tracks, train)
        lt = Leaders(leaders.leader[m], leaders.length[m], leaders.source)
        lm = train_leader_model(train, lt, fallback=mtd)
        note = f"calibrated on the {split} split's training part ({train.n_tracks} tracks)"
    lp = LeaderPredictor(lm, "leader")
    lw = leader_windows(tracks, leaders, win)
    extra = {"leader": lp.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S, XL_hist=lw.XL_hist,
                                        has_leader=lw.known, offset=lw.offset)}
    # the oracle: the leader's recorded past and future, smoothed as one sequence (an oracle may look
    # ahead; raw positions differentiated would feed the law the video noise), and in a split the law
    # calibrated along recorded leader futures (the behavioural law) instead of along CV forecasts
    t_all = np.concatenate([win.t_hist, win.t_fut])
    xl_all = np.nan_to_num(np.concatenate([lw.XL_hist, lw.XL_fut], axis=1))
    sm_l = smooth_histories(t_all, xl_all, lm.jerk_psd)
    K = win.t_hist.size
    xl, vl = sm_l.x[:, K - 1:], np.maximum(sm_l.v[:, K - 1:], 0.0)
    lo = lm
    if split is not None:
        assert train is not None
        lo = train_leader_model(train, lt, fallback=mtd, leader="recorded")
        note_oracle = "the law calibrated along the recorded leader futures of the training part"
    else:
        note_oracle = "the evaluated leader model's law"
    oracle = LeaderPredictor(lo, "oracle").predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S,
                                                         leader_future=(xl, vl), XL_hist=lw.XL_hist,
                                                         has_leader=lw.known, offset=lw.offset)
    allp = {**preds, **extra, "leader-oracle": oracle}
    errs = {k: errors(p, win.X_fut, win.t_fut) for k, p in allp.items()}
    sm = smooth_histories(win.t_hist, win.X_hist, lm.jerk_psd)
    v0 = np.maximum(sm.v[:, -1], 0.0)
    cong = v0 < CONGESTED_BELOW_MPS
    masks = {"all": np.ones(win.n, dtype=bool), "free": ~cong, "congested": cong,
             "leader_known": lw.known, "leader_unknown": ~lw.known}
    section: InteractionSection = {
        "leader_source": leaders.source, "leader_rows_known": leaders.known_fraction,
        "windows_leader_known": int(np.sum(lw.known)), "windows_leader_rejected": int(np.sum(lw.rejected)),
        "leader_future_extended": int(np.sum(lw.future_extended)),
        "congested_below_mps": CONGESTED_BELOW_MPS, "windows_congested": int(np.sum(cong)),
        "leader_model": {"note": note, **lm.law.to_dict()},
        "oracle": ("leader-oracle: a car-following law along the leader's recorded future, smoothed over past and "
                   f"future ({note_oracle}; a bound, not a predictor)"),
        "oracle_law": lo.law.to_dict(),
        "tables": subset_tables(errs, win.track_id, masks, seed, resamples),
    }
    return section, extra
