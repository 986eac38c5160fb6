r"""The exact peaks of a plan against its physical limits (SPEC §14).

Every planner's trajectory is piecewise polynomial (:mod:`iamp.core.trajectory_pieces`): on a
piece :math:`[a, b]`, :math:`h = b - a`, :math:`\sigma = (t - a)/h \in [0, 1]`, the position
per axis is the cubic :math:`s(\sigma) = c_0 + c_1\sigma + c_2\sigma^2 + c_3\sigma^3`, so

.. math::

    v = \frac{c_1 + 2c_2\sigma + 3c_3\sigma^2}{h}, \qquad
    u = \frac{2c_2 + 6c_3\sigma}{h^2}, \qquad \dot u = \frac{6c_3}{h^3} .

The peaks are exact, from these pieces:

* **inputs** ``ax``, ``ay``: ``u`` is linear on a piece, so its extremes are at the piece ends
  (the input's kinks; both one-sided values where it jumps, as with ZOH);
* **|u|** (``a_total``): :math:`|u(\sigma)|^2` is a convex quadratic on a piece, so its maximum
  is at a piece end too;
* **speed** ``vx``: a quadratic; the ends and the root of :math:`c_2 + 3c_3\sigma` in (0, 1);
* **lateral position** ``y``: a cubic; the ends and the real roots of
  :math:`c_1 + 2c_2\sigma + 3c_3\sigma^2` in (0, 1);
* **jerk**: :math:`\max |6 c_3/h^3|` over pieces and axes, or unbounded (``None``) where the
  input jumps between pieces (ZOH).

A trajectory whose pieces are unknown, or whose pieces fail the check (end state, and the
input at :math:`\sigma = 1/4, 3/4` against the linear model), is cut into pieces of
:data:`~iamp.core.trajectory_pieces.FALLBACK_PIECE_S` and the report says ``exact: false``.

A bound is ``ok`` when the peak lies within it up to :data:`BOUND_TOL_REL` times
``max(1, |bound|)`` (the solvers' feasibility accuracy); ``violation`` is how far beyond
it the peak lies (0 within).  Independently of any bound, a plan beyond what any car can do
(:math:`|u| > 9.81` m/s², or :math:`v_x < 0`) gets a warning.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from iamp.core.physical import ANY_CAR_ACCEL_MPS2, PhysicalLimits
from iamp.core.trajectory_pieces import FALLBACK_PIECE_S, PiecewiseTrajectory, breakpoints, taylor_pieces

FloatArray = NDArray[np.float64]

__all__ = ["BOUND_TOL_REL", "NAMES", "Peak", "PeaksReport", "peaks_report"]

#: A peak within ``bound ± BOUND_TOL_REL · max(1, |bound|)`` is within the bound: the relative
#: primal feasibility the QP backends reach (OSQP's KKT tolerance ``cmp_kkt_rel_osqp``).
BOUND_TOL_REL = 1e-7
#: Relative mismatch above which a trajectory's pieces are not trusted (as the safety report).
PIECE_CHECK_REL = 1e-8
#: Report order of the quantities.
NAMES = ("ax", "ay", "a_total", "vx", "y", "jerk")
_UNITS = {"ax": "m/s²", "ay": "m/s²", "a_total": "m/s²", "vx": "m/s", "y": "m", "jerk": "m/s³"}


@dataclass(frozen=True)
class Peak:
    """The extremes of one quantity on a plan, and its bound.

    Attributes
    ----------
    name : str
        One of :data:`NAMES`.
    peak : (lo, hi) or float or None
        The range (``ax``, ``ay``, ``vx``, ``y``) or the largest magnitude (``a_total`` = max
        |u|, ``jerk`` = max |du/dt| over both axes; ``None``: the input jumps, unbounded jerk).
    at : (t_lo, t_hi) or float or None
        Where the peak is reached.
    bound : (lo, hi) or float or None
    violation : float
        How far the peak lies beyond the bound (0 within it, ``inf`` for an unbounded jerk).
    """

    name: str
    peak: tuple[float, float] | float | None
    at: tuple[float, float] | float | None
    bound: tuple[float, float] | float | None = None
    violation: float = 0.0

    @property
    def ok(self) -> bool | None:
        """Within the bound (to :data:`BOUND_TOL_REL`); ``None`` without a bound."""
        if self.bound is None:
            return None
        scale = max(1.0, float(np.max(np.abs(np.atleast_1d(np.asarray(self.bound, dtype=float))))))
        return bool(self.violation <= BOUND_TOL_REL * scale)

    def to_json(self) -> dict[str, Any]:
        def conv(x: tuple[float, float] | float | None) -> list[float] | float | None:
            if x is None:
                return None
            if isinstance(x, tuple):
                return [float(x[0]), float(x[1])]
            return float(x)

        return {"peak": conv(self.peak), "bound": conv(self.bound), "ok": self.ok,
                "violation": float(self.violation) if np.isfinite(self.violation) else None, "at": conv(self.at)}

    def text(self) -> str:
        unit = _UNITS[self.name]
        label = {"a_total": "|u|", "jerk": "jerk"}.get(self.name, self.name)
        if self.peak is None:
            body = f"{label} unbounded (the input jumps)"
        elif isinstance(self.peak, tuple):
            body = f"{label} [{self.peak[0]:.3g}, {self.peak[1]:.3g}]"
        else:
            body = f"{label} {self.peak:.3g}"
        if self.bound is not None:
            b = f"[{self.bound[0]:g}, {self.bound[1]:g}]" if isinstance(self.bound, tuple) else f"{self.bound:g}"
            body += f" {'within' if self.ok else 'EXCEEDS'} {b}"
        return f"{body} {unit}"


@dataclass
class PeaksReport:
    """Every quantity's :class:`Peak` (bounded ones and, always, ``a_total`` and ``vx``).

    Attributes
    ----------
    peaks : dict
        name -> :class:`Peak`, in the order of :data:`NAMES`.
    warnings : list of str
        What no car can do (|u| > 9.81 m/s², v_x < 0), with or without limits.
    exact : bool
        True when the peaks come from the trajectory's own pieces (False: 1 ms fallback pieces).
    polygon_sides : int or None
        Set by a QP that imposed ``a_total`` as an inscribed polygon (reported, not used here).
    """

    peaks: dict[str, Peak]
    warnings: list[str] = field(default_factory=list)
    exact: bool = True
    polygon_sides: int | None = None

    @property
    def within(self) -> bool:
        """Every given bound holds."""
        return all(p.ok is not False for p in self.peaks.values())

    @property
    def exceeded(self) -> list[Peak]:
        return [p for p in self.peaks.values() if p.ok is False]

    def to_json(self) -> dict[str, Any]:
        """``{"ax": {"peak": [lo, hi], "bound": [lo, hi], "ok": true, ...}, ...}`` (SPEC §14)."""
        return {name: p.to_json() for name, p in self.peaks.items()}

    def line(self) -> str:
        """One text line: every reported peak, the bounds it is checked against."""
        return "; ".join(p.text() for p in self.peaks.values())


def _pieces(traj: PiecewiseTrajectory, tf: float) -> tuple[FloatArray, FloatArray, bool]:
    """Piece ends and the position coefficients ``(P, 2, 4)``; ``exact`` False on the fallback."""
    breaks = breakpoints(traj, tf)
    if breaks is not None and breaks.size >= 2:
        C, mismatch = taylor_pieces(traj, breaks)
        if mismatch <= PIECE_CHECK_REL and _inputs_linear(traj, breaks, C):
            return breaks, C, True
    n = max(1, int(np.ceil(tf / FALLBACK_PIECE_S)))
    breaks = np.linspace(0.0, tf, n + 1)
    C, _ = taylor_pieces(traj, breaks)
    return breaks, C, False


def _inputs_linear(traj: PiecewiseTrajectory, breaks: FloatArray, C: FloatArray) -> bool:
    """The input at σ = 1/4 and 3/4 of every piece matches the pieces' linear model."""
    a, h = breaks[:-1], np.diff(breaks)
    for s in (0.25, 0.75):
        u = np.asarray(traj.inputs(a + s * h), dtype=float)
        model = (2 * C[:, :, 2] + 6 * C[:, :, 3] * s) / (h**2)[:, None]
        scale = max(1.0, float(np.max(np.abs(u))))
        if float(np.max(np.abs(u - model))) > PIECE_CHECK_REL * 1e2 * scale:
            return False
    return True


def _range_at(values: FloatArray, times: FloatArray) -> tuple[tuple[float, float], tuple[float, float]]:
    lo, hi = int(np.argmin(values)), int(np.argmax(values))
    return (float(values[lo]), float(values[hi])), (float(times[lo]), float(times[hi]))


def _range_violation(peak: tuple[float, float], bound: tuple[float, float]) -> float:
    return max(0.0, bound[0] - peak[0], peak[1] - bound[1])


def peaks_report(trajectory: PiecewiseTrajectory, tf: float, limits: PhysicalLimits | None = None) -> PeaksReport:
    """The exact peaks of ``trajectory`` on ``[0, tf]`` against ``limits`` (module docstring).

    Parameters
    ----------
    trajectory : PiecewiseTrajectory
        ``states(t)``, ``inputs(t)`` and where its pieces are (``breakpoints()``,
        ``t_nodes`` or ``contact_times``).
    tf : float
    limits : PhysicalLimits, optional

    Returns
    -------
    PeaksReport
        With an entry for every bound given, and always ``a_total`` (max |u|) and ``vx``.
    """
    lim = limits if limits is not None else PhysicalLimits()
    breaks, C, exact = _pieces(trajectory, tf)
    a, b, h = breaks[:-1], breaks[1:], np.diff(breaks)
    h2 = (h**2)[:, None]
    u0 = 2 * C[:, :, 2] / h2  # (P, 2) at the piece starts
    u1 = (2 * C[:, :, 2] + 6 * C[:, :, 3]) / h2  # at the piece ends
    ut = np.concatenate((a, b))
    U = np.concatenate([u0, u1])  # (2P, 2)
    out: dict[str, Peak] = {}
    for axis, name in enumerate(("ax", "ay")):
        bound = getattr(lim, name)
        if bound is not None:
            pk, at = _range_at(U[:, axis], ut)
            out[name] = Peak(name, pk, at, bound, _range_violation(pk, bound))
    mag = np.hypot(U[:, 0], U[:, 1])
    k = int(np.argmax(mag))
    amax = float(mag[k])
    out["a_total"] = Peak("a_total", amax, float(ut[k]), lim.a_total,
                          max(0.0, amax - lim.a_total) if lim.a_total is not None else 0.0)
    # speed v_x: the ends and the interior stationary point of each quadratic piece
    c1, c2, c3 = C[:, 0, 1], C[:, 0, 2], C[:, 0, 3]
    vt = [a, b]
    vv = [c1 / h, (c1 + 2 * c2 + 3 * c3) / h]
    with np.errstate(divide="ignore", invalid="ignore"):
        s_star = np.where(c3 != 0, -c2 / (3 * c3), -1.0)
    inside = (s_star > 0) & (s_star < 1)
    ss = s_star[inside]
    vt.append(a[inside] + ss * h[inside])
    vv.append((c1[inside] + 2 * c2[inside] * ss + 3 * c3[inside] * ss**2) / h[inside])
    vpk, vat = _range_at(np.concatenate(vv), np.concatenate(vt))
    out["vx"] = Peak("vx", vpk, vat, lim.vx, _range_violation(vpk, lim.vx) if lim.vx is not None else 0.0)
    if lim.y is not None:
        Y = C[:, 1, :]
        yt = [a, b]
        yv = [Y[:, 0], Y.sum(axis=1)]
        # roots of c1 + 2 c2 σ + 3 c3 σ² in (0, 1)
        qa, qb, qc = 3 * Y[:, 3], 2 * Y[:, 2], Y[:, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            disc = qb**2 - 4 * qa * qc
            sq = np.sqrt(np.maximum(disc, 0.0))
            quad = np.abs(qa) > 1e-300
            r1 = np.where(quad, (-qb + sq) / (2 * qa), np.where(qb != 0, -qc / qb, -1.0))
            r2 = np.where(quad, (-qb - sq) / (2 * qa), -1.0)
        for r in (r1, r2):
            ok = (disc >= 0) | ~quad
            sel = ok & np.isfinite(r) & (r > 0) & (r < 1)
            rs = r[sel]
            yt.append(a[sel] + rs * h[sel])
            Ys = Y[sel]
            yv.append(Ys[:, 0] + Ys[:, 1] * rs + Ys[:, 2] * rs**2 + Ys[:, 3] * rs**3)
        ypk, yat = _range_at(np.concatenate(yv), np.concatenate(yt))
        out["y"] = Peak("y", ypk, yat, lim.y, _range_violation(ypk, lim.y))
    if lim.jerk is not None:
        jumps = np.abs(u1[:-1] - u0[1:])
        scale = max(1.0, float(np.max(np.abs(U))))
        if jumps.size and float(np.max(jumps)) > 1e-9 * scale:
            j = int(np.argmax(np.max(jumps, axis=1)))
            out["jerk"] = Peak("jerk", None, float(b[j]), lim.jerk, float("inf"))
        else:
            jerk = np.abs(6 * C[:, :, 3] / (h**3)[:, None])
            p = int(np.argmax(np.max(jerk, axis=1)))
            jmax = float(np.max(jerk))
            out["jerk"] = Peak("jerk", jmax, float(0.5 * (a[p] + b[p])), lim.jerk, max(0.0, jmax - lim.jerk))
    ordered = {n: out[n] for n in NAMES if n in out}
    warnings: list[str] = []
    if amax > ANY_CAR_ACCEL_MPS2:
        warnings.append(f"|u| reaches {amax:.3g} m/s² at t = {out['a_total'].at:.3g} s: beyond what any car can do "
                        f"({ANY_CAR_ACCEL_MPS2:g} m/s²)")
    if vpk[0] < -BOUND_TOL_REL:
        warnings.append(f"v_x reaches {vpk[0]:.3g} m/s at t = {vat[0]:.3g} s: the plan drives backwards")
    return PeaksReport(ordered, warnings, exact)
