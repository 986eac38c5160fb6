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
* **incentive** (discretionary changes): ``ã_e - a_e + p[(ã_f - a_f) + (ã_o - a_o)] >
  Δa_th`` (``o``: the ego's old follower; tilde: after the change).  For a mandatory change
  (the ego's lane ends; ``mandatory=True``) the incentive is waived, as MOBIL prescribes for
  a lane that must be left: only safety decides.

Parameters (:class:`IDM`, :class:`MOBIL`) are Treiber's highway values: ``v_0`` = the road's
speed limit, ``T = 1.5`` s, ``s_0 = 2`` m, ``a_max = 1.4`` m/s², ``b = 2`` m/s², ``δ = 4``;
``p = 0.25``, ``b_safe = 4`` m/s², ``Δa_th = 0.1`` m/s².

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
                  new_leader: Car | None, new_follower: Car | None, *, mandatory: bool) -> tuple[bool, str]:
    """MOBIL's decision for a change into ``(new_follower, new_leader)``: ``(accept, reason)``.

    ``reason`` is ``"accepted"``, ``"unsafe-follower"``, ``"unsafe-ego"``, ``"overlap"``
    (the ego's body would overlap a target-lane body) or ``"no-incentive"``.
    """
    for other in (new_leader, new_follower):
        if other is not None and abs(other.x - ego.x) < (other.length + ego.length) / 2:
            return False, "overlap"
    a_f_new = _acc(idm, new_follower, ego) if new_follower is not None else 0.0
    if new_follower is not None and a_f_new < -mobil.b_safe:
        return False, "unsafe-follower"
    a_e_new = _acc(idm, ego, new_leader)
    if a_e_new < -mobil.b_safe:
        return False, "unsafe-ego"
    if mandatory:
        return True, "accepted"
    a_e_old = _acc(idm, ego, old_leader)
    a_f_old = _acc(idm, new_follower, new_leader) if new_follower is not None else 0.0
    a_o_old = _acc(idm, old_follower, ego) if old_follower is not None else 0.0
    a_o_new = _acc(idm, old_follower, old_leader) if old_follower is not None else 0.0
    gain = a_e_new - a_e_old + mobil.politeness * ((a_f_new - a_f_old) + (a_o_new - a_o_old))
    return (True, "accepted") if gain > mobil.a_threshold else (False, "no-incentive")
