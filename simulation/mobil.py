r"""The classic baseline: IDM car following and MOBIL gap acceptance (Treiber, Hennecke, Helbing
2000; Kesting, Treiber, Helbing 2007), with the decision layer's lateral profile.

IDM (the acceleration of a vehicle at speed ``v`` behind a leader at speed ``v_l`` with a
bumper-to-bumper gap ``s``):

.. math::  a = a_{max}\Big[1 - \big(\tfrac{v}{v_0}\big)^{\delta} - \big(\tfrac{s^*}{s}\big)^2\Big],
           \qquad s^* = s_0 + \max\Big(0,\ vT + \frac{v\,(v - v_l)}{2\sqrt{a_{max} b}}\Big),

free road: the last term is absent.  MOBIL accepts a change into the gap ``(f, l)`` when

* **safety**: the new follower's IDM acceleration behind the ego, ``ã_f``, is at least
  ``-b_safe``, and the ego's own IDM acceleration behind ``l``, ``ã_e``, is at least
  ``-b_safe``;
* **incentive**: ``ã_e - a_e + p[(ã_f - a_f) + (ã_o - a_o)] > Δa_th - a_bias``
  (``o``: the ego's old follower; tilde: after the change; ``a_bias`` the bias toward the
  target lane, 0 for a discretionary change).

**A mandatory change** (the ego's lane ends; ``mandatory=True``) as Treiber and Kesting model an
on-ramp or a lane drop (*Traffic Flow Dynamics*, Springer 2013, §14.4; their on-ramp
simulator, traffic-simulation.de, ``onramp.js``/``models.js``): the lane's end is a standing
virtual obstacle for the ego's IDM in its old lane (so ``a_e`` falls toward the end and the
incentive grows), the bias toward the target lane is large (``a_bias = 42`` m/s² with ``p = 0``
and ``Δa_th = 0``: their ``MOBIL_mandat_bias``, ``MOBIL_mandat_p``, ``MOBIL_mandat_bThr``), so
safety decides, with the speed-dependent safe-braking bound of their simulator,
``b_safe(v) = b_safe + (b_safe,max - b_safe)(1 - v/v_0)`` (``MOBIL_bSafe = 4`` m/s² at
``v_0``, ``MOBIL_bSafeMax = 17`` m/s² at standstill; we cap it at 9 m/s², the emergency
deceleration of SUMO's drivers, which no IDM follower can exceed here).

Parameters (:class:`IDM`, :class:`MOBIL`) are Treiber's highway values: ``v_0`` = the road's
speed limit, ``T = 1.5`` s, ``s_0 = 2`` m, ``a_max = 1.4`` m/s², ``b = 2`` m/s², ``δ = 4``;
``p = 0.25``, ``b_safe = 4`` m/s², ``Δa_th = 0.1`` m/s² (discretionary).

Once accepted, the lane change is driven with the **same lateral profile** the iamp planners'
plans use for an unconstrained change — the minimum-energy cubic from ``(y_0, v_{y,0})`` to
``(y_f, 0)`` over ``horizon_s`` — while the longitudinal motion follows IDM behind the nearer of
the current-lane leader (until the ego's centre is in the target lane) and the target-lane
leader, clipped to the passenger car's ``a_x`` range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class IDM:
    """IDM parameters (module docstring)."""

    v0: float = 33.33
    T: float = 1.5
    s0: float = 2.0
    a_max: float = 1.4
    b: float = 2.0
    delta: float = 4.0

    def accel(self, v: float, gap: float | None = None, v_leader: float | None = None) -> float:
        """IDM acceleration; ``gap=None``: free road."""
        free = 1.0 - (max(v, 0.0) / self.v0) ** self.delta
        if gap is None or v_leader is None:
            return float(self.a_max * free)
        s_star = self.s0 + max(0.0, v * self.T + v * (v - v_leader) / (2.0 * math.sqrt(self.a_max * self.b)))
        s = max(gap, 1e-3)
        return float(self.a_max * (free - (s_star / s) ** 2))


@dataclass(frozen=True)
class MOBIL:
    """MOBIL parameters (module docstring)."""

    politeness: float = 0.25
    b_safe: float = 4.0
    a_threshold: float = 0.1
    #: Mandatory changes (module docstring): speed-dependent bound up to ``b_safe_max`` (capped at
    #: ``b_safe_cap``), bias, politeness and threshold.
    b_safe_max: float = 17.0
    b_safe_cap: float = 9.0
    mandatory_bias: float = 42.0
    mandatory_politeness: float = 0.0
    mandatory_threshold: float = 0.0

    def safe_braking(self, v: float, v0: float, mandatory: bool) -> float:
        """``b_safe`` (discretionary) or ``min(b_safe(v), b_safe_cap)`` (mandatory)."""
        if not mandatory:
            return self.b_safe
        frac = min(max(v / max(v0, 1e-6), 0.0), 1.0)
        return min(self.b_safe + (self.b_safe_max - self.b_safe) * (1.0 - frac), self.b_safe_cap)


@dataclass(frozen=True)
class Car:
    """A vehicle on one lane: centre ``x``, speed ``v``, length."""

    x: float
    v: float
    length: float


def gap_between(back: Car, front: Car) -> float:
    """Bumper-to-bumper gap from ``back`` to ``front``."""
    return front.x - back.x - (front.length + back.length) / 2


def _acc(idm: IDM, car: Car, leader: Car | None) -> float:
    if leader is None:
        return idm.accel(car.v)
    return idm.accel(car.v, gap_between(car, leader), leader.v)


def mobil_accepts(idm: IDM, mobil: MOBIL, ego: Car, old_leader: Car | None, old_follower: Car | None,
                  new_leader: Car | None, new_follower: Car | None, *, mandatory: bool,
                  lane_end: float | None = None, biased: bool = False) -> tuple[bool, str]:
    """MOBIL's decision for a change into ``(new_follower, new_leader)``: ``(accept, reason)``.

    ``reason`` is ``"accepted"``, ``"unsafe-follower"``, ``"unsafe-ego"``, ``"overlap"``
    (the ego's body would overlap a target-lane body) or ``"no-incentive"``.  With ``biased``
    a mandatory change is judged as the module docstring says (speed-dependent ``b_safe``,
    bias, the lane's end ``lane_end`` a standing obstacle in the old lane); without it the
    incentive of a mandatory change is waived and ``b_safe`` is constant (the loop before
    issue 30).
    """
    for other in (new_leader, new_follower):
        if other is not None and abs(other.x - ego.x) < (other.length + ego.length) / 2:
            return False, "overlap"
    b_safe = mobil.safe_braking(ego.v, idm.v0, mandatory and biased)
    a_f_new = _acc(idm, new_follower, ego) if new_follower is not None else 0.0
    if new_follower is not None and a_f_new < -b_safe:
        return False, "unsafe-follower"
    a_e_new = _acc(idm, ego, new_leader)
    if a_e_new < -b_safe:
        return False, "unsafe-ego"
    if mandatory and not biased:
        return True, "accepted"
    if lane_end is not None:
        end = Car(lane_end, 0.0, 0.0)
        if old_leader is None or end.x < old_leader.x:
            old_leader = end
    p = mobil.mandatory_politeness if mandatory else mobil.politeness
    threshold = (mobil.mandatory_threshold - mobil.mandatory_bias) if mandatory else mobil.a_threshold
    a_e_old = _acc(idm, ego, old_leader)
    a_f_old = _acc(idm, new_follower, new_leader) if new_follower is not None else 0.0
    a_o_old = _acc(idm, old_follower, ego) if old_follower is not None else 0.0
    a_o_new = _acc(idm, old_follower, old_leader) if old_follower is not None else 0.0
    gain = a_e_new - a_e_old + p * ((a_f_new - a_f_old) + (a_o_new - a_o_old))
    return (True, "accepted") if gain > threshold else (False, "no-incentive")
