r"""Where the ego is inside one vehicle's safety region or overlaps its body, exactly (SPEC §9).

With the ego's offset from vehicle :math:`i`'s centre :math:`d_x = s_x - x_{s,i}(t)`,
:math:`d_y = s_y - y_{s,i}`, the region's half-sizes :math:`A_x = L_i/2 + S_{x,i}`,
:math:`A_y = W_i/2 + S_{y,i}` and the overlap box's :math:`B_x = (L_e + L_i)/2`,
:math:`B_y = (W_e + W_i)/2`:

* **intrusion** where the depth :math:`D = \min(A_x - |d_x|,\ A_y - |d_y|) > \delta`
  (:data:`INTRUSION_TOL_M`, 1 mm; :func:`depth`);
* **overlap** where :math:`|d_x| < B_x` and :math:`|d_y| < B_y`;
* :math:`\max(0, \max_t D)` and the clearance :math:`\min_t \|(\max(|d_x| - A_x, 0),
  \max(|d_y| - A_y, 0))\|_2` (:func:`distance`).

On the polynomial pieces of :mod:`iamp.core.trajectory_pieces`, :math:`d_x, d_y` are
polynomials in :math:`\sigma \in [0, 1]`.  The interval ends are their roots with the
boundaries (e.g. :math:`d_x \mp (A_x - \delta)`, :math:`d_y \mp B_y`), found by
:func:`iamp.core.polyroots.roots_in_unit_interval`; each condition is decided at the midpoint
of every sub-interval between consecutive cut points.  The extremes are attained at a finite
set of candidates, where the true functions are evaluated: piece ends, the roots of
:math:`d_x, d_y, d_x', d_y'` and of :math:`d_x \mp A_x`, :math:`d_y \mp A_y`, the crossings
:math:`A_x - \sigma_x d_x = A_y - \sigma_y d_y` of the two depths, and the stationary points
:math:`(d_x - \sigma_x A_x) d_x' + (d_y - \sigma_y A_y) d_y' = 0` of the squared distance to
each corner, for the four sign pairs :math:`\sigma_x, \sigma_y = \pm 1`.  Interval ends are
exact to about 1e-9 s.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from iamp.core.polyroots import pad_coeffs, poly_deriv, poly_mul, roots_in_unit_interval
from iamp.core.trajectory_pieces import PiecewiseTrajectory, merged_times, shifted_poly

__all__ = ["INTRUSION_TOL_M", "Interval", "VehicleSets", "depth", "distance", "vehicle_sets", "vehicles_sets"]

FloatArray = NDArray[np.float64]
Interval = tuple[float, float]

#: Depth [m] beyond which the ego's point counts as inside a safety region (touching the
#: corner at a contact time and round-off are not an intrusion).
INTRUSION_TOL_M = 1e-3


class VehicleSets(NamedTuple):
    """The intervals and extremes of one vehicle (the fields of SPEC §9 ``vehicles[i]``)."""

    intrusion: tuple[Interval, ...]
    max_intrusion_m: float
    overlap: tuple[Interval, ...]
    min_clearance_m: float


def depth(dx: FloatArray, dy: FloatArray, ax: float, ay: float) -> FloatArray:
    """``min(A_x − |d_x|, A_y − |d_y|)``: > 0 inside the region, the distance to its boundary."""
    return np.minimum(ax - np.abs(dx), ay - np.abs(dy))


def distance(dx: FloatArray, dy: FloatArray, ax: float, ay: float) -> FloatArray:
    """Euclidean distance from the point to the box ``|d_x| ≤ A_x, |d_y| ≤ A_y`` (0 inside)."""
    return np.hypot(np.maximum(np.abs(dx) - ax, 0.0), np.maximum(np.abs(dy) - ay, 0.0))


def _runs(cuts: FloatArray, flags: NDArray[np.bool_]) -> tuple[Interval, ...]:
    r"""The maximal runs of consecutive sub-intervals ``[cuts[j], cuts[j+1]]`` with ``flags[j]``.

    With ``flags`` padded by ``False`` at both ends, the flag changes at positions
    :math:`i_0 < i_1 < \dots`: a run starts at each even one (``flags[i]`` set, ``flags[i-1]`` not)
    and ends at the next (``flags[i]`` not set or the end, :math:`i \le` ``flags.size``), so the runs
    are :math:`[c_{i_0}, c_{i_1}], [c_{i_2}, c_{i_3}], \dots` (``cuts`` has one more entry than ``flags``).
    """
    f = np.zeros(flags.size + 2, dtype=np.bool_)
    f[1:-1] = flags
    change = (f[1:] != f[:-1]).nonzero()[0]  # numpy.flatnonzero of a 1-d array, without its wrapper
    return tuple(zip(cuts[change[0::2]].tolist(), cuts[change[1::2]].tolist()))


def _offsets(vehicle: Any, traj: PiecewiseTrajectory, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(d_x, d_y)`` at ``t``, from the trajectory's own evaluation."""
    X = traj.states(t)
    return X[:, 0] - vehicle.position(t), X[:, 2] - vehicle.y


def vehicle_sets(v: Any, traj: PiecewiseTrajectory, breaks: FloatArray, C: FloatArray,
                 Le: float, We: float) -> VehicleSets:
    """Intrusion and overlap intervals, deepest intrusion and smallest clearance for vehicle ``v``.

    Parameters
    ----------
    v : SurroundingVehicle
    traj : PiecewiseTrajectory
        The plan's trajectory (evaluated at the midpoints and candidates).
    breaks, C : ndarray
        Piece ends and the ego position's coefficients per piece
        (:func:`iamp.core.trajectory_pieces.taylor_pieces`, shape ``(P, 2, 4)``).
    Le, We : float
        The ego body.

    Returns
    -------
    VehicleSets
    """
    return vehicles_sets([v], traj, breaks, C, Le, We)[0]


def vehicles_sets(vehicles: Sequence[Any], traj: PiecewiseTrajectory, breaks: FloatArray, C: FloatArray,
                  Le: float, We: float) -> list[VehicleSets]:
    """:func:`vehicle_sets` of every vehicle, the roots of all their cut polynomials found together
    (one :func:`~iamp.core.polyroots.roots_in_unit_interval` call per polynomial degree; the roots
    of a row do not depend on the other rows, so the numbers are those of one vehicle at a time).

    Parameters
    ----------
    vehicles : sequence of SurroundingVehicle
    traj, breaks, C, Le, We
        As for :func:`vehicle_sets`.

    Returns
    -------
    list of VehicleSets
        One per vehicle, in order.
    """
    P = breaks.size - 1
    cuts = [_CutPolynomials(v, breaks, C, Le, We) for v in vehicles]
    roots: list[tuple[NDArray[np.intp], FloatArray]] = [(np.zeros(0, dtype=np.intp), np.zeros(0))] * len(cuts)
    for n2 in sorted({c.n2 for c in cuts}):
        which = [k for k, c in enumerate(cuts) if c.n2 == n2]
        stacks = [cuts[k].rows for k in which]
        rows, sig = roots_in_unit_interval(np.concatenate(stacks))
        start = 0
        for k, st in zip(which, stacks):
            sel = (rows >= start) & (rows < start + st.shape[0])
            roots[k] = (rows[sel] - start, sig[sel])
            start += st.shape[0]
    return [c.sets(traj, breaks, P, *r) for c, r in zip(cuts, roots)]


#: The sign pairs (sx, sy) of :class:`_CutPolynomials`, in order, shaped to multiply ``(P, D)`` arrays.
_SX = np.array([1.0, 1.0, -1.0, -1.0])[:, None, None]
_SY = np.array([1.0, -1.0, 1.0, -1.0])[:, None, None]
#: The products of :class:`_CutPolynomials` added per sign pair: (dx − sx Ax) dx' of the first,
#: (dy − sy Ay) dy' of the second.
_FIRST, _SECOND = np.array([0, 0, 1, 1], dtype=np.intp), np.array([2, 3, 2, 3], dtype=np.intp)


class _CutPolynomials:
    """Vehicle ``v``'s polynomials whose roots are cut points: groups of ``P`` rows (one per piece)."""

    def __init__(self, v: Any, breaks: FloatArray, C: FloatArray, Le: float, We: float) -> None:
        a = breaks[:-1]
        h = breaks[1:] - a  # numpy.diff's subtraction
        degree = max(3, len(v.x_poly) - 1)
        xs = shifted_poly(v.x_poly, a, h, degree)
        dX = pad_coeffs(C[:, 0, :], degree + 1) - xs
        dY = pad_coeffs(C[:, 1, :], degree + 1)
        dY[:, 0] -= v.y
        Ax, Ay = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
        Bx, By = (Le + v.length) / 2, (We + v.width) / 2
        d = INTRUSION_TOL_M
        self.v, self.Ax, self.Ay, self.Bx, self.By = v, Ax, Ay, Bx, By
        self.n2 = n2 = 2 * degree + 1

        ddX, ddY = poly_deriv(dX), poly_deriv(dY)
        # per group of P rows, in order: its polynomial (dX, dY, dX', dY' or one of the eight
        # below) and the constant subtracted from its σ⁰ coefficient
        base: list[int] = []
        const: list[float] = []
        self.with_intrusion = Ax > d and Ay > d
        if self.with_intrusion:  # intrusion: |dx| < Ax − δ and |dy| < Ay − δ
            base += [0, 0, 1, 1]
            const += [Ax - d, -(Ax - d), Ay - d, -(Ay - d)]
        self.first_overlap = len(base)  # overlap of the bodies: |dx| < Bx and |dy| < By
        base += [0, 0, 1, 1]
        const += [Bx, -Bx, By, -By]
        self.first_extreme = len(base)  # extremes: candidates where depth / distance can attain a max / min
        base += [0, 1, 2, 3, 0, 0, 1, 1]
        const += [0.0, 0.0, 0.0, 0.0, Ax, -Ax, Ay, -Ay]
        # the products (dx − sx Ax) dx' and (dy − sy Ay) dy', each computed once (one row-wise
        # product of the four stacked: each row's numbers are those of its own product)
        P, D = dX.shape
        # dx − Ax, dx + Ax, dy − Ay, dy + Ay stacked: each copy's σ⁰ coefficient less its constant
        # (one subtraction per number, as one copy at a time)
        # (numpy.stack's array, by one concatenation of the four)
        shifted = np.concatenate((dX, dX, dY, dY)).reshape(4, P, D)
        shifted[:, :, 0] -= np.array([[Ax], [-Ax], [Ay], [-Ay]])
        prods = poly_mul(shifted.reshape(4 * P, D), np.concatenate((ddX, ddX, ddY, ddY)))
        prods = prods.reshape(4, P, -1)
        # per sign pair (sx, sy) = (1, 1), (1, −1), (−1, 1), (−1, −1): the depth crossing
        # Ax − sx dx = Ay − sy dy and the stationary points of (dx − sx Ax)² + (dy − sy Ay)²
        cross = _SY * dY - _SX * dX
        stationary = prods.take(_FIRST, 0) + prods.take(_SECOND, 0)  # (indexing with lists: the same copies)
        # the polynomials, zero-padded to n2 columns: dX, dY, dX', dY', then per sign pair its
        # crossing and its stationary points
        padded = np.zeros((12, P, n2))
        padded[0, :, :D], padded[1, :, :D] = dX, dY
        padded[2, :, :D - 1], padded[3, :, :D - 1] = ddX, ddY
        padded[4::2, :, :D] = cross
        padded[5::2, :, :stationary.shape[2]] = stationary
        base += [4, 5, 6, 7, 8, 9, 10, 11]
        const += [Ay - Ax, 0.0] * 4
        self.n_groups = len(base)
        # every group's polynomial written into its rows, then its constant subtracted
        # (subtracting 0.0 changes no bit)
        rows = padded.take(base, 0)
        rows[:, :, 0] -= np.asarray(const)[:, None]
        self.rows = rows.reshape(self.n_groups * P, n2)

    def sets(self, traj: PiecewiseTrajectory, breaks: FloatArray, P: int, rows: NDArray[np.intp],
             sig: FloatArray) -> VehicleSets:
        """The sets from the roots ``sig`` of rows ``rows`` of :attr:`rows`."""
        v, Ax, Ay, Bx, By, d = self.v, self.Ax, self.Ay, self.Bx, self.By, INTRUSION_TOL_M
        group = rows // P
        # every root's time a_p + h_p σ at once (cut_times's numbers, element by element), and its
        # set: 0 intrusion, 1 overlap, 2 extremes (groups [0, first_overlap), [first_overlap,
        # first_extreme), [first_extreme, n_groups))
        p = rows % P
        times = breaks[:-1][p] + (breaks[1:] - breaks[:-1])[p] * sig
        kind = (group >= self.first_overlap).astype(np.int64) + (group >= self.first_extreme)

        # the three sets of times (the intrusion's and the overlap's midpoints, the extremes'
        # candidates) evaluated in one call: the trajectory and the vehicle are evaluated point by
        # point, so the numbers are those of three calls
        i_cuts = merged_times(breaks, times[kind == 0]) if self.with_intrusion else np.zeros(0)
        i_mid = 0.5 * (i_cuts[:-1] + i_cuts[1:])
        o_cuts = merged_times(breaks, times[kind == 1])
        o_mid = 0.5 * (o_cuts[:-1] + o_cuts[1:])
        cand = merged_times(breaks, times[kind == 2])
        dx, dy = _offsets(v, traj, np.concatenate((i_mid, o_mid, cand)))
        a, b = i_mid.size, i_mid.size + o_mid.size
        intrusion = _runs(i_cuts, depth(dx[:a], dy[:a], Ax, Ay) > d) if self.with_intrusion else ()
        overlap = _runs(o_cuts, (np.abs(dx[a:b]) < Bx) & (np.abs(dy[a:b]) < By))
        cx, cy = dx[b:], dy[b:]
        max_depth = max(0.0, float(np.max(depth(cx, cy, Ax, Ay))))
        min_clear = float(np.min(distance(cx, cy, Ax, Ay)))
        return VehicleSets(intrusion=intrusion, max_intrusion_m=max_depth, overlap=overlap,
                           min_clearance_m=min_clear)
