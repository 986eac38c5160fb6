"""The bounds every input must respect: one documented table, used by the scenario and
problem validation and by the command line.

The planners solve a problem in double precision.  A value far outside what a road vehicle
can do (``x_f = 1e308``, a polynomial whose ``x_s(t)`` reaches ``1e300``, a horizon of a
million seconds) does not describe a lane change, and it turns the linear algebra into
overflow and cancellation: a "solution" with residuals of ``1e26``.  Such inputs are refused
up front, naming the field, instead of being planned.

=========================  ===================================  =================================
entry                      bound                                why
=========================  ===================================  =================================
``position_max_m``         ``|x|, |y| <= 1e5`` m                positions (ego, vehicles, histories)
``speed_max_mps``          ``|v| <= 1e3`` m/s                   ego speeds and ``|ẋ_s(t)|``
``tf_min_s``/``max``       ``1e-2 <= t_f <= 1e3`` s             horizon
``size_max_m``             ``L, W, S_x, S_y <= 1e3`` m          vehicle geometry
``poly_max_terms``         ``len(x_poly) <= 64``                degree 63
``vehicles_max``           ``m <= 8``                           contact times solved jointly
``steps_max``              ``N <= 20000``                       output samples / QP grid
``qp_work_max``            ``candidates · N <= 1e6``            QP contact-time sweep
``history_samples_max``    ``<= 100000`` samples                one observed history
``history_span_max_s``     ``t[0] >= -1e3`` s                   its length
``history_step_min_s``     ``t[k+1] - t[k] >= 1e-4`` s          its sampling
``model_dt_min/max_s``     ``1e-3 <= Δt <= 10`` s               a predictor model's time step
``prediction_steps_max``   ``t_f / Δt <= 20000``                predicted samples per vehicle
=========================  ===================================  =================================

The polynomial bound is checked by *evaluating* ``x_s(t)`` and ``ẋ_s(t)`` on ``[0, t_f]``
(a dense grid plus the real stationary points), not by the size of the coefficients: a
25-term Taylor series or a trailing ``1e-300`` term is legal as long as the trajectory it
describes is.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Sequence
from typing import Final

import numpy as np
import numpy.typing as npt

LIMITS: Final[dict[str, float]] = {
    "position_max_m": 1e5,
    "speed_max_mps": 1e3,
    "tf_min_s": 1e-2,
    "tf_max_s": 1e3,
    "size_max_m": 1e3,
    "poly_max_terms": 64,
    # the global contact-time search grows exponentially with m; its box budget bounds the
    # time (pure numpy path, loaded 2-core machine: m = 4 10-20 s, m = 5-8 10-18 s, status
    # `local` beyond m = 3 when the budget runs out; compiled search 0.5-3.6 s); the paper
    # uses m <= 2
    "vehicles_max": 8,
    "steps_max": 20_000,
    # perm(N−1, m)·N: the two-vehicle OSQP sweep at the default N = 100 (9.7e5) took 45 s here,
    # one vehicle at N = 400 (1.6e5) 5 s with Clarabel; N = 5000 (2.5e7) would take hours
    "qp_work_max": 1_000_000,
    "history_samples_max": 100_000,
    "history_span_max_s": 1e3,
    "history_step_min_s": 1e-4,
    "model_dt_min_s": 1e-3,
    "model_dt_max_s": 10.0,
    "prediction_steps_max": 20_000,
}

#: Points of the evaluation grid of a polynomial over ``[0, t_f]`` (plus its stationary points).
POLY_GRID: Final = 2049


def limit(name: str) -> float:
    """Look up a bound by name (``KeyError`` names the missing entry)."""
    return LIMITS[name]


def exact(value: float) -> str:
    """The value as given, not rounded: the shortest text that reads back as the same float
    (``-100000.1``, not ``%g``'s ``-100000``; ``5`` for 5.0).  A refusal must show the
    offending value itself (issue 22 item 13)."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def bound_message(value: float, lo: float | None, hi: float | None, unit: str = "") -> str | None:
    """``None`` if ``lo <= value <= hi`` (either side optional), else the refusal text."""
    u = f" {unit}" if unit else ""
    if lo is not None and hi is not None and not (lo <= value <= hi):
        return f"must lie in [{lo:g}, {hi:g}]{u} (got {exact(value)})"
    if lo is not None and value < lo:
        return f"must be >= {lo:g}{u} (got {exact(value)})"
    if hi is not None and value > hi:
        return f"must be <= {hi:g}{u} (got {exact(value)})"
    return None


def abs_message(value: float, bound: float, unit: str = "") -> str | None:
    """``None`` if ``|value| <= bound``, else the refusal text."""
    if abs(value) <= bound:
        return None
    u = f" {unit}" if unit else ""
    return f"|value| must be <= {bound:g}{u} (got {exact(value)})"


#: One bound check of :func:`first_refusal`: ``(field, value, lo, hi, unit)`` (either side ``None``).
BoundCheck = tuple[str, float, "float | None", "float | None", str]
#: One magnitude check of :func:`first_refusal`: ``(field, value, bound, unit)``.
AbsCheck = tuple[str, float, float, str]


def first_refusal(bounds: Sequence[BoundCheck] = (), absolutes: Sequence[AbsCheck] = ()) -> tuple[str, str] | None:
    """``(field, refusal text)`` of the first failing check — the bound checks in order
    (:func:`bound_message`), then the magnitude checks (:func:`abs_message`) — or ``None``.

    An object validates all its fields against the table in this one call (``scripts/walk.py``:
    building a problem does not go back and forth between :mod:`iamp.core.problem` and this module
    once per field).
    """
    for field, value, lo, hi, unit in bounds:
        msg = bound_message(value, lo, hi, unit)
        if msg is not None:
            return field, msg
    for field, value, bound, unit in absolutes:
        msg = abs_message(value, bound, unit)
        if msg is not None:
            return field, msg
    return None


def _stationary_points(coeffs: npt.NDArray[np.float64], tf: float) -> npt.NDArray[np.float64]:
    """Real roots in ``[0, t_f]`` of the derivative of ``Σ c_k t^k`` (best effort)."""
    if coeffs.size < 3:
        return np.empty(0)
    with np.errstate(all="ignore"):
        d = np.polynomial.polynomial.polyder(coeffs)
    nz = np.flatnonzero(d)
    if nz.size == 0:
        return np.empty(0)
    d = d[: nz[-1] + 1]
    if d.size < 2:
        return np.empty(0)
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            r = np.polynomial.polynomial.polyroots(d)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        return np.empty(0)
    r = r[np.isfinite(r)]
    real = r.real[np.abs(r.imag) <= 1e-9 * np.maximum(1.0, np.abs(r.real))]
    return np.asarray(real[(real >= 0.0) & (real <= tf)], dtype=float)


def polynomial_message(coeffs: Sequence[float], tf: float) -> str | None:
    """``None`` if ``x_s(t) = Σ c_k t^k`` keeps ``|x_s| <= position_max_m`` and
    ``|ẋ_s| <= speed_max_mps`` on ``[0, t_f]``; else the refusal text (with the time).

    Evaluated on a grid of :data:`POLY_GRID` points of ``[0, t_f]`` and at the real roots
    of ``ẋ_s`` in that interval, in double precision; an overflow counts as out of bounds.
    The answer is a function of the coefficients, ``t_f`` and the two bounds only, and is
    remembered for the last :data:`POLY_CACHE` of them (the closed loop builds many problems
    with the same predicted vehicles).
    """
    c = np.asarray(coeffs, dtype=float)
    n_max = int(LIMITS["poly_max_terms"])
    if c.size > n_max:
        return f"has {c.size} coefficients; at most {n_max} are accepted (degree {n_max - 1})"
    if c.ndim != 1:
        return _polynomial_message(c, float(tf))
    return _polynomial_message_cached(tuple(c.tolist()), float(tf), float(LIMITS["position_max_m"]),
                                      float(LIMITS["speed_max_mps"]))


#: How many ``(coefficients, t_f)`` answers :func:`polynomial_message` remembers.
POLY_CACHE = 4096


@functools.lru_cache(maxsize=POLY_CACHE)
def _polynomial_message_cached(c: tuple[float, ...], tf: float, pmax: float, vmax: float) -> str | None:
    # ``pmax``/``vmax`` are part of the key: the answer changes with LIMITS
    return _polynomial_message(np.asarray(c, dtype=float), tf)


def _polynomial_message(c: npt.NDArray[np.float64], tf: float) -> str | None:
    t = np.concatenate([np.linspace(0.0, tf, POLY_GRID), _stationary_points(c, tf)])
    with np.errstate(all="ignore"):
        dc = np.polynomial.polynomial.polyder(c) if c.size > 1 else np.zeros(1)
        x = np.polynomial.polynomial.polyval(t, c)
        v = np.polynomial.polynomial.polyval(np.linspace(0.0, tf, POLY_GRID), dc)
    pmax, vmax = LIMITS["position_max_m"], LIMITS["speed_max_mps"]
    bad = ~(np.abs(x) <= pmax)
    if bad.any():
        k = int(np.argmax(bad))
        return (f"gives |x_s(t)| > {pmax:g} m on [0, tf] (x_s({t[k]:.6g}) = {x[k]:.6g}); "
                "positions must stay within the bound")
    badv = ~(np.abs(v) <= vmax)
    if badv.any():
        k = int(np.argmax(badv))
        tk = tf * k / (POLY_GRID - 1)
        return f"gives |dx_s/dt| > {vmax:g} m/s on [0, tf] (at t = {tk:.6g} s: {v[k]:.6g} m/s)"
    return None


def qp_work(m: int, steps: int) -> int:
    """Grid-sweep size of the QP: ``perm(N − 1, m) · N`` (candidate QPs times their size)."""
    return math.perm(steps - 1, m) * steps if steps - 1 >= m else 0


def qp_work_message(m: int, steps: int) -> str | None:
    """``None`` if the QP sweep of ``m`` vehicles on ``N = steps`` is within ``qp_work_max``."""
    if steps < m + 1:
        return f"must be at least {m + 1} for {m} vehicle(s) with the QP (got {steps})"
    work, cap = qp_work(m, steps), int(LIMITS["qp_work_max"])
    if work > cap:
        return (f"N = {steps} with {m} vehicle(s) means a sweep of {math.perm(steps - 1, m)} QPs of N = {steps} "
                f"(work {work:.3g} > limit {cap:.3g}); choose a smaller N")
    return None


def prediction_message(tf: float, dt: float) -> str | None:
    """``None`` if a model step ``dt`` is within bounds and ``t_f/dt`` predicted samples are allowed."""
    msg = bound_message(dt, LIMITS["model_dt_min_s"], LIMITS["model_dt_max_s"], "s")
    if msg is not None:
        return msg
    n = tf / dt
    if n > LIMITS["prediction_steps_max"]:
        return (f"tf / dt = {n:.3g} predicted samples exceeds {LIMITS['prediction_steps_max']:g}; "
                "use a model with a larger dt or a shorter horizon")
    return None
