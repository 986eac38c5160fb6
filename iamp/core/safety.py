r"""Where a plan is unsafe (SPEC §9), computed exactly from its piecewise-polynomial trajectory.

For vehicle :math:`i` write the ego's offset from the vehicle's centre

.. math::  d_x(t) = s_x(t) - x_{s,i}(t), \qquad d_y(t) = s_y(t) - y_{s,i},

and the half-sizes of its safety region and of the bodies' overlap box

.. math::

    A_x = L_i/2 + S_{x,i}, \quad A_y = W_i/2 + S_{y,i}, \qquad
    B_x = (L_e + L_i)/2, \quad B_y = (W_e + W_i)/2 ,

with the ego body :math:`L_e \times W_e` (``[ego] length``, ``width``; default 4.8 × 1.8 m).

* **intrusion**: the ego's point inside the safety region by more than
  :math:`\delta` = :data:`INTRUSION_TOL_M` (1 mm), i.e. the *depth*
  :math:`D(t) = \min(A_x - |d_x|,\ A_y - |d_y|) > \delta`;
* **overlap**: the bodies overlap, :math:`|d_x| < B_x` and :math:`|d_y| < B_y`;
* **max_intrusion_m**: :math:`\max(0, \max_t D(t))`;
* **min_clearance_m**: :math:`\min_t \operatorname{dist}(s(t), \text{region})` with
  :math:`\operatorname{dist} = \|(\max(|d_x| - A_x, 0), \max(|d_y| - A_y, 0))\|_2` (0 when the
  point enters the closed region).

Exactness
---------
Every planner's trajectory is piecewise polynomial: the PMP's position is a cubic between
contact times, a QP's is a cubic (FOH) or quadratic (ZOH) between grid nodes, and
:math:`x_{s,i}` is a polynomial.  On each piece :math:`[a, b]` the ego's position is rebuilt
from the trajectory's own evaluation as the Taylor polynomial
:math:`s(a + \tau) = s_a + v_a\tau + u_a\tau^2/2 + j\tau^3/6` (:math:`j` from the input at
the piece's midpoint) and checked at :math:`b`.  The interval ends are then **roots** of
polynomials (e.g. :math:`d_x(t) \mp (A_x - \delta)`), found per piece as eigenvalues of the
companion matrix in the scaled variable :math:`\sigma = \tau/(b-a) \in [0, 1]` and polished
by Newton steps; the condition is decided at the midpoint of every sub-interval between
consecutive cut points.  The extremes are attained at a finite set of candidates (piece ends,
roots of :math:`d_x, d_y, d_x', d_y'`, the crossings :math:`A_x - \sigma_x d_x = A_y -
\sigma_y d_y` of the two depths, and the stationary points of
:math:`(d_x - \sigma_x A_x)^2 + (d_y - \sigma_y A_y)^2` for the four sign pairs) where the
true functions are evaluated.  Interval ends are exact to about 1e-9 s.

A trajectory whose pieces are unknown (neither ``breakpoints()``, ``t_nodes`` nor
``contact_times``) or that fails the end-of-piece check is cut into 1 ms pieces instead
(SPEC §9 allows a grid of at most 1 ms); :attr:`SafetyReport.exact` says which.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from math import comb
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: Depth [m] beyond which the ego's point counts as inside a safety region (touching the
#: corner at a contact time and round-off are not an intrusion).
INTRUSION_TOL_M = 1e-3
#: Default ego body (SPEC §9), used when the problem does not carry one.
DEFAULT_EGO_LENGTH_M, DEFAULT_EGO_WIDTH_M = 4.8, 1.8
#: Cut points closer than this [s] are merged.
_MERGE_S = 1e-9
#: Fallback piece length [s] for trajectories of unknown structure.
_FALLBACK_PIECE_S = 1e-3

Interval = tuple[float, float]


class _Traj(Protocol):
    def states(self, t: ArrayLike) -> FloatArray: ...

    def inputs(self, t: ArrayLike) -> FloatArray: ...


# --------------------------------------------------------------------------------------
# The report
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class VehicleSafety:
    """Safety of the plan with respect to one vehicle (SPEC §9 ``vehicles[i]``)."""

    name: str
    intrusion: tuple[Interval, ...]
    max_intrusion_m: float
    overlap: tuple[Interval, ...]
    min_clearance_m: float

    @property
    def intrusion_free(self) -> bool:
        return not self.intrusion

    @property
    def collision_free(self) -> bool:
        return not self.overlap

    @property
    def safe(self) -> bool:
        return self.intrusion_free and self.collision_free

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name,
                "intrusion": [[a, b] for a, b in self.intrusion],
                "max_intrusion_m": self.max_intrusion_m,
                "overlap": [[a, b] for a, b in self.overlap],
                "min_clearance_m": self.min_clearance_m}

    def describe(self) -> str:
        """One line for the text output."""
        def fmt(iv: tuple[Interval, ...]) -> str:
            return ", ".join(f"[{a:.3f}, {b:.3f}] s" for a, b in iv) or "none"
        return (f"{self.name}: inside its safety region {fmt(self.intrusion)} "
                f"(max depth {self.max_intrusion_m:.3f} m); bodies overlap {fmt(self.overlap)}")


@dataclass(frozen=True)
class SafetyReport:
    """Safety of one plan (SPEC §9): one :class:`VehicleSafety` per vehicle, in file order."""

    vehicles: tuple[VehicleSafety, ...]
    ego_length_m: float
    ego_width_m: float
    exact: bool

    @property
    def collision_free(self) -> bool:
        return all(v.collision_free for v in self.vehicles)

    @property
    def intrusion_free(self) -> bool:
        return all(v.intrusion_free for v in self.vehicles)

    @property
    def safe(self) -> bool:
        return self.collision_free and self.intrusion_free

    def unsafe(self) -> list[VehicleSafety]:
        """The vehicles whose region the ego enters or whose body it overlaps."""
        return [v for v in self.vehicles if not v.safe]

    def lines(self) -> list[str]:
        """The text output: one line per unsafe vehicle with its intervals (or that it is safe)."""
        bad = self.unsafe()
        if not bad:
            return [f"safety    intrusion-free and collision-free (ego body {self.ego_length_m:g} x "
                    f"{self.ego_width_m:g} m)"]
        return [f"UNSAFE    {v.describe()}" for v in bad]

    def to_json(self) -> dict[str, Any]:
        return {"collision_free": self.collision_free, "intrusion_free": self.intrusion_free,
                "vehicles": [v.to_json() for v in self.vehicles],
                "ego_length_m": self.ego_length_m, "ego_width_m": self.ego_width_m,
                "intrusion_tol_m": INTRUSION_TOL_M,
                "method": "exact" if self.exact else "1ms-pieces"}


# --------------------------------------------------------------------------------------
# Piecewise polynomials of the trajectory
# --------------------------------------------------------------------------------------


def _breakpoints(traj: object, tf: float) -> FloatArray | None:
    bp: Any = getattr(traj, "breakpoints", None)
    if callable(bp):
        bp = bp()
    if bp is None and getattr(traj, "t_nodes", None) is not None:
        bp = traj.t_nodes  # type: ignore[attr-defined]
    if bp is None and getattr(traj, "contact_times", None) is not None:
        ct: FloatArray = np.asarray(getattr(traj, "contact_times"), dtype=np.float64).ravel()  # noqa: B009
        bp = ct[(ct > 0) & (ct < tf)]
    if bp is None:
        return None
    b = np.unique(np.r_[0.0, np.asarray(bp, dtype=float).ravel(), tf])
    b = b[(b >= 0) & (b <= tf)]
    keep = np.r_[True, np.diff(b) > _MERGE_S]
    b = b[keep]
    b[-1] = tf
    return b


def _taylor_pieces(traj: _Traj, breaks: FloatArray) -> tuple[FloatArray, float]:
    """Per piece and axis, the position's coefficients in ``σ ∈ [0, 1]`` (ascending, 4 each):
    shape ``(P, 2, 4)``, plus the largest end-of-piece mismatch (position and speed)."""
    a, b = breaks[:-1], breaks[1:]
    h = b - a
    Xa = traj.states(a)
    Ua = traj.inputs(a)
    Um = traj.inputs(0.5 * (a + b))
    jerk = (Um - Ua) / (0.5 * h)[:, None]
    C = np.empty((a.size, 2, 4))
    hh = h[:, None]
    C[:, :, 0] = Xa[:, [0, 2]]
    C[:, :, 1] = Xa[:, [1, 3]] * hh
    C[:, :, 2] = Ua * hh**2 / 2
    C[:, :, 3] = jerk * hh**3 / 6
    Xb = traj.states(b)
    s_end = C.sum(axis=2)
    v_end = (C[:, :, 1] + 2 * C[:, :, 2] + 3 * C[:, :, 3]) / hh
    scale = max(1.0, float(np.max(np.abs(Xb))))
    mismatch = max(float(np.max(np.abs(s_end - Xb[:, [0, 2]]))), float(np.max(np.abs(v_end - Xb[:, [1, 3]]))))
    return C, mismatch / scale


def _shifted_poly(coeffs: Sequence[float], a: FloatArray, h: FloatArray, degree: int) -> FloatArray:
    """Coefficients of ``p(a + h σ)`` in ``σ`` (ascending), shape ``(len(a), degree + 1)``."""
    c = np.zeros(degree + 1)
    c[:len(coeffs)] = coeffs
    out = np.zeros((a.size, degree + 1))
    for k in range(degree + 1):
        acc = np.zeros(a.size)
        for j in range(k, degree + 1):
            if c[j] != 0.0:
                acc += c[j] * comb(j, k) * a ** (j - k)
        out[:, k] = acc * h**k
    return out


# --------------------------------------------------------------------------------------
# Batched polynomial roots on [0, 1]
# --------------------------------------------------------------------------------------


def _polyval_rows(C: FloatArray, x: FloatArray) -> FloatArray:
    out = np.zeros_like(x)
    for k in range(C.shape[1] - 1, -1, -1):
        out = out * x + C[:, k]
    return out


def roots_in_unit_interval(C: FloatArray, imag_tol: float = 1e-6) -> tuple[NDArray[np.intp], FloatArray]:
    """Real roots in ``[0, 1]`` of many polynomials at once.

    Parameters
    ----------
    C : ndarray, shape (K, D + 1)
        Ascending coefficients, one polynomial per row.
    imag_tol : float
        Eigenvalues with ``|Im| <= imag_tol`` count as real (near-double roots; an extra cut
        point is harmless to every caller).

    Returns
    -------
    rows, sigma : ndarray
        Row index and root of every root found, polished by Newton steps.
    """
    C = np.asarray(C, dtype=float)
    D1 = C.shape[1]
    scale = np.max(np.abs(C), axis=1)
    big = np.abs(C) > 1e-12 * scale[:, None]
    deg = np.where(big.any(axis=1), D1 - 1 - np.argmax(big[:, ::-1], axis=1), 0)
    rows_out: list[NDArray[np.intp]] = []
    roots_out: list[FloatArray] = []
    for d in np.unique(deg):
        d = int(d)
        if d == 0:
            continue
        idx = np.flatnonzero(deg == d)
        lead = C[idx, d]
        if d == 1:
            r = (-C[idx, 0] / lead)[:, None].astype(complex)
        else:
            comp = np.zeros((idx.size, d, d))
            comp[:, 1:, :-1] = np.eye(d - 1)
            comp[:, :, -1] = -C[idx, :d] / lead[:, None]
            r = np.linalg.eigvals(comp)
        ok = (np.abs(r.imag) <= imag_tol) & (r.real >= -1e-9) & (r.real <= 1 + 1e-9)
        ii, jj = np.nonzero(ok)
        rows_out.append(idx[ii])
        roots_out.append(np.clip(r.real[ii, jj], 0.0, 1.0))
    if not rows_out:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    rows, x = np.concatenate(rows_out), np.concatenate(roots_out)
    if rows.size:
        Cr = C[rows]
        dC = Cr[:, 1:] * np.arange(1, D1)
        for _ in range(3):
            f = _polyval_rows(Cr, x)
            fp = _polyval_rows(dC, x)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(fp != 0, f / fp, 0.0)
            xn = np.clip(x - step, 0.0, 1.0)
            better = np.abs(_polyval_rows(Cr, xn)) < np.abs(f)
            x = np.where(better & np.isfinite(xn), xn, x)
    return rows, x


def _poly_mul(A: FloatArray, B: FloatArray) -> FloatArray:
    """Row-wise product of ascending coefficient arrays."""
    out = np.zeros((A.shape[0], A.shape[1] + B.shape[1] - 1))
    for i in range(A.shape[1]):
        out[:, i:i + B.shape[1]] += A[:, [i]] * B
    return out


def _pad(A: FloatArray, n: int) -> FloatArray:
    return np.pad(A, ((0, 0), (0, n - A.shape[1])))


def _deriv(A: FloatArray) -> FloatArray:
    return A[:, 1:] * np.arange(1, A.shape[1])


# --------------------------------------------------------------------------------------
# Sets and extremes
# --------------------------------------------------------------------------------------


def _cuts(breaks: FloatArray, p: NDArray[np.intp], sigma: FloatArray) -> FloatArray:
    """The piece ends plus the roots ``σ`` of piece ``p``, as sorted times (merged within 1 ns)."""
    a, h = breaks[:-1], np.diff(breaks)
    t = np.r_[breaks, a[p] + h[p] * sigma]
    t = np.unique(t)
    keep = np.r_[True, np.diff(t) > _MERGE_S]
    out: FloatArray = t[keep]
    out[-1] = breaks[-1]
    return out


def _runs(cuts: FloatArray, flags: NDArray[np.bool_]) -> tuple[Interval, ...]:
    out: list[Interval] = []
    start = None
    for j, f in enumerate(flags):
        if f and start is None:
            start = float(cuts[j])
        if not f and start is not None:
            out.append((start, float(cuts[j])))
            start = None
    if start is not None:
        out.append((start, float(cuts[-1])))
    return tuple(out)


def _offsets(vehicle: Any, traj: _Traj, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    X = traj.states(t)
    return X[:, 0] - vehicle.position(t), X[:, 2] - vehicle.y


def depth(dx: FloatArray, dy: FloatArray, ax: float, ay: float) -> FloatArray:
    """``min(A_x − |d_x|, A_y − |d_y|)``: > 0 inside the region, the distance to its boundary."""
    return np.minimum(ax - np.abs(dx), ay - np.abs(dy))


def distance(dx: FloatArray, dy: FloatArray, ax: float, ay: float) -> FloatArray:
    """Euclidean distance from the point to the box ``|d_x| ≤ A_x, |d_y| ≤ A_y`` (0 inside)."""
    return np.hypot(np.maximum(np.abs(dx) - ax, 0.0), np.maximum(np.abs(dy) - ay, 0.0))


def safety_report(problem: Any, trajectory: Any, ego_length: float | None = None,
                  ego_width: float | None = None) -> SafetyReport:
    """The SPEC §9 report of ``trajectory`` (a plan's own continuous trajectory) on ``problem``.

    Parameters
    ----------
    problem : Problem
    trajectory : object
        ``states(t)``/``inputs(t)`` and one of ``breakpoints()``, ``t_nodes``,
        ``contact_times`` (the pieces on which the position is a polynomial of degree <= 3).
    ego_length, ego_width : float, optional
        The ego body; default ``problem.ego.ego_length``/``ego_width`` or 4.8 × 1.8 m.
    """
    tf = float(problem.tf)
    ego = problem.ego
    Le = float(ego_length if ego_length is not None else getattr(ego, "ego_length", DEFAULT_EGO_LENGTH_M))
    We = float(ego_width if ego_width is not None else getattr(ego, "ego_width", DEFAULT_EGO_WIDTH_M))
    breaks = _breakpoints(trajectory, tf)
    exact = breaks is not None
    C = None
    if breaks is not None:
        C, mismatch = _taylor_pieces(trajectory, breaks)
        if mismatch > 1e-8:
            exact = False
    if not exact:
        n = max(1, int(np.ceil(tf / _FALLBACK_PIECE_S)))
        breaks = np.linspace(0.0, tf, n + 1)
        C, _ = _taylor_pieces(trajectory, breaks)
    assert breaks is not None and C is not None
    a, h = breaks[:-1], np.diff(breaks)
    P = a.size
    out = []
    for v in problem.vehicles:
        out.append(_vehicle_safety(v, trajectory, breaks, a, h, C, P, Le, We))
    return SafetyReport(tuple(out), Le, We, exact)


def _vehicle_safety(v: Any, traj: _Traj, breaks: FloatArray, a: FloatArray, h: FloatArray,
                    C: FloatArray, P: int, Le: float, We: float) -> VehicleSafety:
    degree = max(3, len(v.x_poly) - 1)
    xs = _shifted_poly(v.x_poly, a, h, degree)
    dX = _pad(C[:, 0, :], degree + 1) - xs
    dY = _pad(C[:, 1, :], degree + 1)
    dY[:, 0] -= v.y
    Ax, Ay = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
    Bx, By = (Le + v.length) / 2, (We + v.width) / 2
    d = INTRUSION_TOL_M
    n2 = 2 * degree + 1

    def shift(A: FloatArray, c: float) -> FloatArray:
        B = A.copy()
        B[:, 0] -= c
        return B

    def cuts_of(polys: list[FloatArray]) -> FloatArray:
        rows, sig = roots_in_unit_interval(np.concatenate([_pad(p, n2) for p in polys]))
        return _cuts(breaks, rows % P, sig)

    # intrusion: |dx| < Ax − δ and |dy| < Ay − δ
    if Ax > d and Ay > d:
        cuts = cuts_of([shift(dX, Ax - d), shift(dX, -(Ax - d)), shift(dY, Ay - d), shift(dY, -(Ay - d))])
        mid = 0.5 * (cuts[:-1] + cuts[1:])
        mx, my = _offsets(v, traj, mid)
        intrusion = _runs(cuts, depth(mx, my, Ax, Ay) > d)
    else:
        intrusion = ()
    # overlap of the bodies: |dx| < Bx and |dy| < By
    cuts = cuts_of([shift(dX, Bx), shift(dX, -Bx), shift(dY, By), shift(dY, -By)])
    mid = 0.5 * (cuts[:-1] + cuts[1:])
    mx, my = _offsets(v, traj, mid)
    overlap = _runs(cuts, (np.abs(mx) < Bx) & (np.abs(my) < By))
    # extremes: candidates where depth / distance can attain a max / min
    ddX, ddY = _deriv(dX), _deriv(dY)
    polys = [dX, dY, ddX, ddY, shift(dX, Ax), shift(dX, -Ax), shift(dY, Ay), shift(dY, -Ay)]
    for sx in (1.0, -1.0):
        for sy in (1.0, -1.0):
            # depth crossing: Ax − sx dx = Ay − sy dy
            polys.append(shift(sy * dY - sx * dX, Ay - Ax))
            # stationary points of (dx − sx Ax)² + (dy − sy Ay)²
            polys.append(_poly_mul(shift(dX, sx * Ax), ddX) + _pad(_poly_mul(shift(dY, sy * Ay), ddY),
                                                                    2 * degree))
    cand = cuts_of(polys)
    cx, cy = _offsets(v, traj, cand)
    max_depth = max(0.0, float(np.max(depth(cx, cy, Ax, Ay))))
    min_clear = float(np.min(distance(cx, cy, Ax, Ay)))
    return VehicleSafety(name=str(v.name), intrusion=intrusion, max_intrusion_m=max_depth, overlap=overlap,
                         min_clearance_m=min_clear)
