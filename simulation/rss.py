r"""Responsibility-Sensitive Safety (RSS): the closed loop's judge (SPEC §17).

Shalev-Shwartz, Shammah, Shashua, *On a Formal Model of Safe and Scalable Self-driving Cars*,
arXiv:1708.06374 (2017).  Two cars driving in the same direction on a straight road (``x``
along the road, ``y`` to the left), with bodies, longitudinal speeds ``v`` and lateral speeds.

* **Safe longitudinal distance** (the rear car ``r`` behind the front car ``f``)

  .. math::  d_{lon} = \Big[v_r\rho + \tfrac12 a_{acc}\rho^2 + \frac{(v_r + \rho a_{acc})^2}{2 b_{min}}
             - \frac{v_f^2}{2 b_{max}}\Big]_+ :

  the rear car accelerates at most ``a_acc`` during its response time ``ρ`` and then brakes at
  least ``b_min``; the front car brakes at most ``b_max``.
* **Safe lateral distance** (``u_1, u_2``: each car's lateral speed *toward the other*)

  .. math::  d_{lat} = \mu + \big[o(u_1) + o(u_2)\big]_+, \qquad
             o(u) = u\rho + \tfrac12\alpha\rho^2 + \frac{\max(u + \rho\alpha, 0)^2}{2\beta} :

  each car moves toward the other with lateral acceleration at most ``α`` during ``ρ`` and
  then brakes laterally with at least ``β`` until its lateral speed is zero; ``μ`` is the
  lateral fluctuation margin.  The braking term counts only a speed still *toward* the
  other after ``ρ`` (the paper writes the square of a speed it assumes non-negative; the
  reference implementation ``ad-rss`` does the same as here).  ``ad-rss`` adds ``μ`` inside
  the positive part (a zero distance when both move apart); the paper, and this module, add
  it outside, so that touching bodies are never laterally safe.  Both agree whenever the
  bracket is non-negative (``tests/test_rss.py`` checks it against ``ad-rss`` when installed).
* The distances are the gaps between the bodies along and across the road; a pair is
  **longitudinally (laterally) safe** when that gap is positive and at least ``d_lon``
  (``d_lat``).  A time is **dangerous** for the pair when it is neither.
* **Dangerous threshold (blame) time** ``t_b``: the last non-dangerous time before a run of
  dangerous times.  A run already dangerous when the pair is first seen has no ``t_b``; it
  is judged from its first time with both responses required (the strict reading).
* **Proper response** during ``(t_b, t]``, for the dimensions that were *safe* at ``t_b``
  (the danger came from the other one):

  - longitudinal: the rear car accelerates at most ``a_acc`` until ``t_b + ρ``, then brakes
    with at least ``b_min`` until it stands; the front car brakes at most ``b_max``;
  - lateral: each car's lateral speed toward the other grows at most with ``α`` until
    ``t_b + ρ``, then falls with at least ``β`` until it is zero, and stays zero (within the
    fluctuation ``μ/ρ``).

  A step's action is the change of a car's speed over one period, ``(v_k - v_{k-1})/Δt``
  (what SUMO reports as its acceleration), checked with the tolerance :data:`ACCEL_TOL`.
* **Blame**: a car is responsible at time ``t`` of a dangerous run when it violated its
  proper response at some time in ``(t_b, t]``; a contact is the fault of each car
  responsible at its time (both may be).

The monitor (:mod:`iamp.simulation.monitor`) applies this to every (ego, neighbour) pair of an
executed episode.  :class:`RssParameters` holds the numbers; its defaults are the reference
implementation's defaults for vehicles (see :data:`SOURCE`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.core.errors import ScenarioError

FloatArray = npt.NDArray[np.float64]

#: Where the default numbers come from.
SOURCE = ("formulas: Shalev-Shwartz, Shammah, Shashua, On a Formal Model of Safe and Scalable Self-driving Cars, "
          "arXiv:1708.06374; values: the default vehicle dynamics of the reference implementation ad-rss as "
          "integrated in CARLA (LibCarla rss/RssCheck.cpp, GetDefaultVehicleDynamics: accel_max 3.5, brake_min 4, "
          "brake_max 8 m/s^2, lateral accel_max 0.2, lateral brake_min 0.8 m/s^2, lateral fluctuation margin "
          "0.1 m) except the response time: 0.5 s for every vehicle (ad-rss's 1 s is a human perception-reaction "
          "time; here every vehicle acts every 0.1 s: SUMO's action step and the ego's control period, so 0.5 s "
          "is five periods); one set for the judge and the closed loop's verification (simulation/failsafe.py)")
#: Tolerance on a step's acceleration when checking a proper response [m/s²].
ACCEL_TOL = 0.05


@dataclass(frozen=True)
class RssParameters:
    """The RSS parameters of the judge (module docstring).

    Parameters
    ----------
    response_time_s : float
        ``ρ`` [s], every vehicle's response time.
    accel_max : float
        ``a_acc`` [m/s²], the largest longitudinal acceleration during ``ρ``.
    brake_min : float
        ``b_min`` [m/s²], the braking a responding rear car applies at least.
    brake_max : float
        ``b_max`` [m/s²], the hardest braking of a front car (at least ``brake_min``).
    lat_accel_max : float
        ``α`` [m/s²], the largest lateral acceleration toward the other during ``ρ``.
    lat_brake_min : float
        ``β`` [m/s²], the lateral braking a responding car applies at least.
    lat_margin_m : float
        ``μ`` [m], the lateral fluctuation margin (non-negative).

    Raises
    ------
    iamp.ScenarioError
        A parameter that is not finite, not positive (``μ``: negative), or ``brake_max < brake_min``.
    """

    response_time_s: float = 0.5
    accel_max: float = 3.5
    brake_min: float = 4.0
    brake_max: float = 8.0
    lat_accel_max: float = 0.2
    lat_brake_min: float = 0.8
    lat_margin_m: float = 0.1

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            v = float(value)
            if not math.isfinite(v) or v < 0 or (v == 0 and name != "lat_margin_m"):
                raise ScenarioError(f"must be a positive number (got {value!r})", f"rss.{name}")
        if self.brake_max < self.brake_min:
            raise ScenarioError(f"must be at least brake_min = {self.brake_min:g} (got {self.brake_max:g})",
                                "rss.brake_max")

    def as_dict(self) -> dict[str, Any]:
        """The parameters and their :data:`SOURCE` (for the manifest and the episode JSON)."""
        return {**asdict(self), "source": SOURCE}

    @functools.cached_property
    def scalar_terms(self) -> tuple[float, float, float, float, float] | None:
        """The longitudinal distance's parameter terms (:func:`_rss_terms`) when its four parameters are
        floats, computed once per parameter set (the loop asks for thousands of distances per episode);
        None otherwise (:func:`safe_longitudinal_float` then takes the array path, as before)."""
        args = (self.response_time_s, self.accel_max, self.brake_min, self.brake_max)
        return _rss_terms(*args) if all(type(z) is float for z in args) else None


DEFAULT = RssParameters()



def _rss_terms(rho: float, a_acc: float, b_min: float, b_max: float) -> tuple[float, float, float, float, float]:
    """The parts of :func:`_rss_scalar` that depend on the parameters only: ``ρ``, ``ρ a_acc``,
    ``½ a_acc ρ²`` (``ρ²`` as ``ρ·ρ``), ``2 b_min``, ``2 b_max`` (the same floats whether computed once per
    parameter set, :attr:`RssParameters.scalar_terms`, or once per call)."""
    return rho, rho * a_acc, 0.5 * a_acc * (rho * rho), 2.0 * b_min, 2.0 * b_max


def _rss_of_terms(v_r: float, v_f: float, rho: float, rho_a: float, half_a_rho2: float, two_b_min: float,
                  two_b_max: float) -> float:
    """:func:`_rss_scalar` of two speeds with the parameters' terms (:func:`_rss_terms`) given.

    Each ``max(z, 0.0)`` is written ``0.0 if 0.0 > z else z``: the builtin's rule (the first argument
    unless the second is larger), so ``-0.0`` and ``nan`` come through as they do from ``max`` and
    ``np.maximum``, without the call."""
    vr = 0.0 if 0.0 > v_r else v_r
    vf = 0.0 if 0.0 > v_f else v_f
    v_rho = vr + rho_a
    if 0.0 > v_rho:
        v_rho = 0.0
    d = vr * rho + half_a_rho2 + v_rho**2 / two_b_min - vf**2 / two_b_max
    return 0.0 if 0.0 > d else d


def _rss_scalar(v_r: float, v_f: float, rho: float, a_acc: float, b_min: float, b_max: float) -> float:
    """:func:`rss_distance` of six floats (the tactical layer asks thousands of times per episode):
    the same IEEE operations in the same order as the array expression on 0-d inputs, where
    ``np.maximum`` returns numpy scalars whose ``**2`` is C ``pow`` while the 0-d ``rho**2`` is ``rho*rho``."""
    return _rss_of_terms(v_r, v_f, *_rss_terms(rho, a_acc, b_min, b_max))


def rss_distance(v_r: npt.ArrayLike, v_f: npt.ArrayLike, rho: npt.ArrayLike, a_acc: npt.ArrayLike,
                 b_min: npt.ArrayLike, b_max: npt.ArrayLike) -> FloatArray:
    """RSS's safe longitudinal distance with its parameters as plain arguments, elementwise.

    The one implementation of SPEC §17's formula: the judge (:func:`safe_longitudinal_distance`,
    one :class:`RssParameters` for every vehicle) and the closed loop's verification
    (:mod:`iamp.simulation.failsafe`, values per role: the ego's own response time, a fail-safe
    deceleration that may exceed the front's admissible braking) both call it.

    Parameters
    ----------
    v_r, v_f : array_like
        Speeds of the rear and the front vehicle [m/s] (negative speeds count as 0).
    rho : array_like
        The rear vehicle's response time [s].
    a_acc : array_like
        Its largest acceleration during the response time [m/s²] (a negative value: it brakes
        already; its speed after the response time is then not below 0).
    b_min : array_like
        The braking the rear applies at least after it [m/s², > 0].
    b_max : array_like
        The braking the front applies at most [m/s², > 0].

    Returns
    -------
    numpy.ndarray
        ``[v_r ρ + ½ a_acc ρ² + max(v_r + ρ a_acc, 0)²/(2 b_min) − v_f²/(2 b_max)]_+`` [m].
    """
    if all(isinstance(z, float) for z in (v_r, v_f, rho, a_acc, b_min, b_max)):
        return np.asarray(_rss_scalar(float(v_r), float(v_f), float(rho), float(a_acc),  # type: ignore[arg-type]
                                      float(b_min), float(b_max)), dtype=float)  # type: ignore[arg-type]
    vr = np.maximum(np.asarray(v_r, dtype=float), 0.0)
    vf = np.maximum(np.asarray(v_f, dtype=float), 0.0)
    rho_, a = np.asarray(rho, dtype=float), np.asarray(a_acc, dtype=float)
    v_rho = np.maximum(vr + rho_ * a, 0.0)
    d = vr * rho_ + 0.5 * a * rho_**2 + v_rho**2 / (2.0 * np.asarray(b_min, dtype=float)) \
        - vf**2 / (2.0 * np.asarray(b_max, dtype=float))
    return np.asarray(np.maximum(d, 0.0), dtype=float)


def safe_longitudinal_float(v_rear: float, v_front: float, p: RssParameters = DEFAULT) -> float:
    """``float(safe_longitudinal_distance(v_rear, v_front, p))`` of two speeds (the same float; the
    tactical layer's many scalar questions skip the array wrapping).

    Parameters
    ----------
    v_rear, v_front : float
        Longitudinal speeds [m/s].
    p : RssParameters

    Returns
    -------
    float
        The RSS distance [m].
    """
    terms = p.scalar_terms
    if terms is not None and type(v_rear) is float and type(v_front) is float:
        return _rss_of_terms(v_rear, v_front, *terms)
    rho, a_acc, b_min, b_max = p.response_time_s, p.accel_max, p.brake_min, p.brake_max
    if isinstance(v_rear, float) and isinstance(v_front, float) and isinstance(rho, float) \
            and isinstance(a_acc, float) and isinstance(b_min, float) and isinstance(b_max, float):
        return _rss_scalar(float(v_rear), float(v_front), float(rho), float(a_acc), float(b_min), float(b_max))
    return float(rss_distance(v_rear, v_front, rho, a_acc, b_min, b_max))


def safe_longitudinal_distance(v_rear: npt.ArrayLike, v_front: npt.ArrayLike,
                               p: RssParameters = DEFAULT) -> FloatArray:
    """RSS's safe longitudinal distance of a rear car behind a front car, same direction.

    Parameters
    ----------
    v_rear, v_front : array_like
        Longitudinal speeds [m/s] (non-negative), broadcast together.
    p : RssParameters
        The parameters of every vehicle.

    Returns
    -------
    numpy.ndarray
        ``[v_r ρ + ½ a_acc ρ² + (v_r + ρ a_acc)²/(2 b_min) − v_f²/(2 b_max)]_+`` [m]
        (:func:`rss_distance` with ``p``'s values).
    """
    return rss_distance(v_rear, v_front, p.response_time_s, p.accel_max, p.brake_min, p.brake_max)


#: How far beyond its RSS distance a vehicle is still followed by the closed loop [m]
#: (:func:`within_rss_reach`): at the judge's 0.1 s steps a closing speed of 20 m/s takes one
#: second to cover it.
RSS_REACH_MARGIN_M = 20.0


def longitudinal_room(dx: float, other_length: float, other_vx: float, ego_vx: float, ego_length: float,
                      p: RssParameters = DEFAULT) -> tuple[float, float]:
    """The bumper gap between the ego and a vehicle ``dx`` ahead of it (centres; negative:
    behind) and the pair's RSS longitudinal distance: the rear car (the ego when the other is
    ahead) at its speed, the front at its own (:func:`safe_longitudinal_float`) [m]."""
    gap = abs(float(dx)) - (float(other_length) + float(ego_length)) / 2
    d = (safe_longitudinal_float(float(ego_vx), float(other_vx), p) if dx > 0
         else safe_longitudinal_float(float(other_vx), float(ego_vx), p))
    return gap, d


def within_rss_reach(dx: float, other_length: float, other_vx: float, ego_vx: float, ego_length: float,
                     p: RssParameters = DEFAULT, margin: float = RSS_REACH_MARGIN_M) -> bool:
    """Whether a vehicle ``dx`` ahead of the ego (centres; negative: behind) is within its RSS
    longitudinal distance of the ego plus ``margin`` (:func:`longitudinal_room`).  A
    fixed sensing range misses a fast car approaching from behind, or a slow one ahead of a fast
    ego, whose RSS distance exceeds it (130-190 m at closing speeds of 5-17 m/s), and the judge
    holds the ego responsible for a lane change in front of it or for not braking behind it.

    Parameters
    ----------
    dx : float
        The other's centre minus the ego's along the road [m].
    other_length, ego_length : float
        Body lengths [m].
    other_vx, ego_vx : float
        Longitudinal speeds [m/s].
    p : RssParameters
    margin : float
        [m].

    Returns
    -------
    bool
    """
    gap, d = longitudinal_room(dx, other_length, other_vx, ego_vx, ego_length, p)
    return gap <= d + margin


def _lateral_reach_of(u: Any, rho: Any, alpha: Any, beta: Any, maximum: Callable[[Any, float], Any]) -> Any:
    """``o(u) = u ρ + ½ α ρ² + max(u + ρ α, 0)²/(2 β)``: the one expression of :func:`lateral_reach` (arrays,
    ``maximum = np.maximum``) and :func:`safe_lateral_float` (floats, ``maximum = max``: the same float, the
    builtin keeping the first argument unless the second is larger, as ``np.maximum`` does with ``-0.0``
    and ``nan``; a numpy scalar's ``**2`` is C ``pow``, as a Python float's is)."""
    after = maximum(u + rho * alpha, 0.0)
    return u * rho + 0.5 * alpha * rho**2 + after**2 / (2 * beta)


def lateral_reach(u_toward: npt.ArrayLike, p: RssParameters = DEFAULT) -> FloatArray:
    """How far a car moves toward the other under the worst lateral response, ``o(u)``.

    Parameters
    ----------
    u_toward : array_like
        Lateral speed toward the other car [m/s] (negative: moving away).
    p : RssParameters

    Returns
    -------
    numpy.ndarray
        ``u ρ + ½ α ρ² + max(u + ρ α, 0)²/(2 β)`` [m] (negative when it moves away).
    """
    u = np.asarray(u_toward, dtype=float)
    return np.asarray(_lateral_reach_of(u, p.response_time_s, p.lat_accel_max, p.lat_brake_min, np.maximum),
                      dtype=float)


def safe_lateral_distance(u1_toward: npt.ArrayLike, u2_toward: npt.ArrayLike,
                          p: RssParameters = DEFAULT) -> FloatArray:
    """RSS's safe lateral distance ``μ + [o(u_1) + o(u_2)]_+`` of two cars side by side.

    Parameters
    ----------
    u1_toward, u2_toward : array_like
        Each car's lateral speed toward the other [m/s].
    p : RssParameters

    Returns
    -------
    numpy.ndarray
        The distance [m], at least ``μ``.
    """
    return np.asarray(p.lat_margin_m + np.maximum(lateral_reach(u1_toward, p) + lateral_reach(u2_toward, p), 0.0),
                      dtype=float)


def safe_lateral_float(u1_toward: float, u2_toward: float, p: RssParameters = DEFAULT) -> float:
    """``float(safe_lateral_distance(u1_toward, u2_toward, p))`` of two speeds (the same float; the loop's
    many scalar questions skip the array wrapping: two Python floats go through :func:`_lateral_reach_of`
    with the builtin ``max``, anything else through :func:`safe_lateral_distance`).

    Parameters
    ----------
    u1_toward, u2_toward : float
        Each car's lateral speed toward the other [m/s].
    p : RssParameters

    Returns
    -------
    float
        The distance [m], at least ``μ``.
    """
    if type(u1_toward) is float and type(u2_toward) is float:
        rho, alpha, beta = p.response_time_s, p.lat_accel_max, p.lat_brake_min
        try:
            o = _lateral_reach_of(u1_toward, rho, alpha, beta, max) + _lateral_reach_of(u2_toward, rho, alpha, beta,
                                                                                          max)
        except OverflowError:  # a Python float's square beyond the range raises; numpy's is inf, as before
            return float(safe_lateral_distance(u1_toward, u2_toward, p))
        return float(p.lat_margin_m + max(o, 0.0))
    return float(safe_lateral_distance(u1_toward, u2_toward, p))


def body_extents(length: npt.ArrayLike, width: npt.ArrayLike, heading: npt.ArrayLike
                 ) -> tuple[FloatArray, FloatArray]:
    """Half extents along ``x`` and ``y`` of a ``length × width`` rectangle turned by ``heading``.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``(L/2 |cos ψ| + W/2 |sin ψ|, L/2 |sin ψ| + W/2 |cos ψ|)`` [m].
    """
    L, W, psi = (np.asarray(a, dtype=float) for a in (length, width, heading))
    c, s = np.abs(np.cos(psi)), np.abs(np.sin(psi))
    return np.asarray(L / 2 * c + W / 2 * s, dtype=float), np.asarray(L / 2 * s + W / 2 * c, dtype=float)


@dataclass(frozen=True)
class Motion:
    """One vehicle over the logged steps (``nan`` where it was not observed).

    ``x, y`` centre [m]; ``vx, vy`` velocity [m/s]; ``hx, hy`` half extents of its body along
    ``x`` and ``y`` (:func:`body_extents`) [m].
    """

    x: FloatArray
    y: FloatArray
    vx: FloatArray
    vy: FloatArray
    hx: FloatArray
    hy: FloatArray


@dataclass(frozen=True)
class PairJudgement:
    """RSS over time for the pair (ego, other); arrays over the logged steps.

    ``dangerous``; ``blame_k`` (the step of the dangerous threshold time of the current run,
    ``-1`` when the run began at the pair's first common step, ``-2`` when not dangerous);
    ``response`` (``"longitudinal"``, ``"lateral"`` or ``"both"``, ``""`` when not
    dangerous); ``ego_responsible`` and ``other_responsible`` (violated the proper response
    at some step of ``(t_b, t]``); the gaps and safe distances behind it.
    """

    dangerous: npt.NDArray[np.bool_]
    blame_k: npt.NDArray[np.int64]
    response: list[str]
    ego_responsible: npt.NDArray[np.bool_]
    other_responsible: npt.NDArray[np.bool_]
    lon_gap: FloatArray
    lat_gap: FloatArray
    d_lon: FloatArray
    d_lat: FloatArray


def _complies(resp: str, k: int, kb: int, dt: float, rear: bool, left: bool, m: Motion, p: RssParameters) -> bool:
    """Did the car follow its proper response over the period ``(k-1, k]`` of a run with
    threshold step ``kb`` (``rear``: it is the rear car; ``left``: it is the left car)?"""
    tau = (k - 1 - kb) * dt  # time since t_b at the start of the period
    early = tau < p.response_time_s - 1e-9
    if resp in ("longitudinal", "both"):
        v0, v1 = float(m.vx[k - 1]), float(m.vx[k])
        if rear:
            bound = v0 + (p.accel_max + ACCEL_TOL) * dt if early else max(0.0, v0 - (p.brake_min - ACCEL_TOL) * dt)
            if v1 > bound + 1e-9:
                return False
        elif v1 < max(0.0, v0 - (p.brake_max + ACCEL_TOL) * dt) - 1e-9:
            return False
    if resp in ("lateral", "both"):
        sign = -1.0 if left else 1.0  # toward the other: right (−y) for the left car
        u0, u1 = sign * float(m.vy[k - 1]), sign * float(m.vy[k])
        rest = p.lat_margin_m / p.response_time_s  # a lateral speed within μ per ρ is fluctuation
        step = (p.lat_accel_max + ACCEL_TOL) * dt if early else -(p.lat_brake_min - ACCEL_TOL) * dt
        if u1 > max(u0 + step, rest) + 1e-9:
            return False
    return True


def _fill_sides(side: np.ndarray) -> np.ndarray:
    """``side`` (``-1``, ``0``, ``+1`` per step) with each ``0`` replaced by the nearest later
    nonzero entry, else the nearest earlier one, else left ``0``."""
    idx = np.arange(side.size)
    nz = side != 0
    nxt = np.where(nz, idx, side.size)
    nxt = np.minimum.accumulate(nxt[::-1])[::-1]  # index of the next nonzero (size: none)
    prv = np.maximum.accumulate(np.where(nz, idx, -1))  # index of the previous nonzero (-1: none)
    out: np.ndarray = np.where(nz, side, np.where(nxt < side.size, side[np.minimum(nxt, side.size - 1)],
                                                  np.where(prv >= 0, side[np.maximum(prv, 0)], 0.0)))
    return out


def _ego_left(dy: np.ndarray, level: float) -> np.ndarray:
    """Whether the ego is the left car (larger ``y``) of the pair, from ``dy = y_other - y_ego``.

    Where the two centres are level (``|dy| <= level``; the judge passes RSS's lateral
    fluctuation margin ``μ``: e.g. both on one lane's centre, a few millimetres apart) left and
    right are undefined and a sideways move either way opens the gap; the roles there are those
    of the nearest later step where the two are more than ``level`` apart (the side they
    separate to), else of the nearest earlier one; a pair never that far apart takes the sign
    of ``dy`` itself (the nearest step where it is not 0, later first), and else the ego is the
    right car.  Without this a level pair made the ego "the right car" and its move to the left
    counted as moving toward the other: at ``dy == 0`` (fixed in 66128b0), and as long as the
    lane keeping's drift of a few millimetres put the ego to the right of a follower in its lane
    (slow-leader LOS E seed 69: 12.6 s at fault for a lane change away from it).
    """
    dy = np.nan_to_num(dy, nan=0.0)
    exact = _fill_sides(np.sign(dy))
    apart = _fill_sides(np.where(np.abs(dy) > level, np.sign(dy), 0.0))
    out: np.ndarray = np.where(apart != 0, apart, exact) < 0
    return out


def judge_pair(ego: Motion, other: Motion, dt: float, p: RssParameters = DEFAULT) -> PairJudgement:
    """Dangerous times, threshold times, proper responses and blame of one pair (module docstring).

    Parameters
    ----------
    ego, other : Motion
        The two vehicles over the same steps (``nan`` where ``other`` was not seen).
    dt : float
        The period [s].
    p : RssParameters

    Returns
    -------
    PairJudgement
    """
    n = ego.x.size
    dx, dy = other.x - ego.x, other.y - ego.y
    lon_gap = np.abs(dx) - (ego.hx + other.hx)
    lat_gap = np.abs(dy) - (ego.hy + other.hy)
    ego_front = dx < 0
    v_rear = np.where(ego_front, other.vx, ego.vx)
    v_front = np.where(ego_front, ego.vx, other.vx)
    d_lon = safe_longitudinal_distance(np.nan_to_num(v_rear), np.nan_to_num(v_front), p)
    ego_left = _ego_left(dy, p.lat_margin_m)
    u_ego = np.where(ego_left, -ego.vy, ego.vy)  # toward the other
    u_oth = np.where(ego_left, other.vy, -other.vy)
    d_lat = safe_lateral_distance(np.nan_to_num(u_ego), np.nan_to_num(u_oth), p)
    seen = np.isfinite(dx) & np.isfinite(dy) & np.isfinite(other.vx) & np.isfinite(other.vy)
    with np.errstate(invalid="ignore"):
        lon_safe = (lon_gap > 0) & (lon_gap >= d_lon)
        lat_safe = (lat_gap > 0) & (lat_gap >= d_lat)
    dangerous = seen & ~lon_safe & ~lat_safe
    blame_k = np.full(n, -2, dtype=np.int64)
    response = [""] * n
    ego_resp = np.zeros(n, dtype=bool)
    oth_resp = np.zeros(n, dtype=bool)
    k = 0
    while k < n:
        if not dangerous[k]:
            k += 1
            continue
        kb = k - 1 if k > 0 and seen[k - 1] else -1
        if kb >= 0:
            resp = "both" if (lon_safe[kb] and lat_safe[kb]) else ("longitudinal" if lon_safe[kb] else "lateral")
        else:
            resp = "both"
        ref = kb if kb >= 0 else k  # the roles (rear/front, left/right) at the threshold time
        ego_rear, ego_is_left = bool(not ego_front[ref]), bool(ego_left[ref])
        e_bad = o_bad = False
        start = k
        while k < n and dangerous[k]:
            if k > start or kb >= 0:
                if k >= 1 and not _complies(resp, k, max(kb, start - 1), dt, ego_rear, ego_is_left, ego, p):
                    e_bad = True
                if k >= 1 and np.isfinite(other.vx[k - 1]) and \
                        not _complies(resp, k, max(kb, start - 1), dt, not ego_rear, not ego_is_left, other, p):
                    o_bad = True
            blame_k[k] = kb
            response[k] = resp
            ego_resp[k], oth_resp[k] = e_bad, o_bad
            k += 1
    return PairJudgement(dangerous, blame_k, response, ego_resp, oth_resp, lon_gap, lat_gap, d_lon, d_lat)
