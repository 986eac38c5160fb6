r"""A road-aligned (curvilinear) frame: arc length ``s`` along a smooth reference path and the
signed lateral offset ``d`` (positive to the left of the direction of travel).

The reference path is a polynomial in a rotated Cartesian frame: with the rotation angle
:math:`\psi_0` and origin :math:`p_0`, a world point :math:`p` has rotated coordinates
:math:`(u, w) = R(-\psi_0)(p - p_0)` and the path is :math:`c(u) = (u, f(u))`, ``f`` a
polynomial least-squares fit to a lane's centre line (the road turns a few degrees per scene,
so a straight line would leave metres of lateral error while the fit leaves centimetres).

.. math::

    s(u) = \int_0^u \sqrt{1 + f'(\xi)^2}\,d\xi, \qquad
    n(u) = \frac{(-f'(u),\ 1)}{\sqrt{1 + f'(u)^2}}, \qquad
    p = p_0 + R(\psi_0)\big(c(u(s)) + d\,n(u(s))\big).

The forward map projects ``p`` on the path (Newton on
:math:`g(u) = (u - u_p) + (f(u) - w_p) f'(u) = 0`); the back map is the formula above, so the
round trip is exact to the Newton tolerance wherever :math:`|d| < 1/\kappa` (the projection is
unique).  Arc length is Gauss-Legendre quadrature (16 nodes per 1 m table cell), exact to
round-off for a polynomial path of this curvature.  Velocities follow the Frenet relations

.. math::  \dot p = (1 - \kappa d)\,\dot s\,t + \dot d\,n, \qquad
           \kappa = \frac{f''}{(1 + f'^2)^{3/2}} .

This module needs numpy only (no CommonRoad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)
#: Newton tolerance of the projection and of the arc-length inverse [m].
NEWTON_TOL_M = 1e-10


@dataclass(frozen=True)
class RoadFrame:
    """The frame of the module docstring.

    Parameters
    ----------
    origin : (2,) array
        :math:`p_0` (world coordinates) [m].
    angle : float
        :math:`\\psi_0` [rad], the direction of travel of the rotated ``u`` axis.
    coeffs : sequence of float
        ``f`` in ascending powers of ``u`` [m].
    u_range : (float, float)
        Where the path is defined (extrapolated beyond, polynomially).
    """

    origin: tuple[float, float]
    angle: float
    coeffs: tuple[float, ...]
    u_range: tuple[float, float]
    _table_u: FloatArray = field(init=False, repr=False, compare=False)
    _table_s: FloatArray = field(init=False, repr=False, compare=False)
    _derivs: tuple[FloatArray, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        c = np.asarray(self.coeffs, dtype=float)
        derivs = [c]
        for der in (1, 2, 3):
            derivs.append(np.polynomial.polynomial.polyder(c, der) if len(c) > der else np.zeros(1))
        object.__setattr__(self, "_derivs", tuple(derivs))
        lo, hi = self.u_range
        pad = 0.5 * (hi - lo) + 50.0
        u = np.arange(lo - pad, hi + pad + 1.0, 1.0)
        # arc length from u = 0 at every table node
        seg = np.array([self._segment(a, b) for a, b in zip(u[:-1], u[1:])])
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        k0 = int(np.clip(np.searchsorted(u, 0.0) - 1, 0, len(u) - 2))
        base = cum[k0] + self._segment(float(u[k0]), 0.0)  # s = 0 at u = 0
        object.__setattr__(self, "_table_u", u)
        object.__setattr__(self, "_table_s", cum - base)

    # --- the polynomial path ------------------------------------------------------------------
    @classmethod
    def fit(cls, points: npt.ArrayLike, degree: int = 5) -> RoadFrame:
        """A frame whose path fits the centre-line ``points`` ``(n, 2)`` (world, in driving order):
        rotated by the chord's direction, origin at the first point, ``f`` of degree
        ``min(degree, n - 1)`` by least squares."""
        P = np.asarray(points, dtype=float)
        if P.ndim != 2 or P.shape[1] != 2 or len(P) < 2:
            raise ValueError("need at least two centre-line points (n, 2)")
        chord = P[-1] - P[0]
        angle = float(np.arctan2(chord[1], chord[0]))
        c, s = np.cos(angle), np.sin(angle)
        rel = P - P[0]
        u = rel[:, 0] * c + rel[:, 1] * s
        w = -rel[:, 0] * s + rel[:, 1] * c
        deg = int(min(degree, len(P) - 1))
        coeffs = np.polynomial.polynomial.polyfit(u, w, deg)
        return cls((float(P[0, 0]), float(P[0, 1])), angle, tuple(float(x) for x in coeffs),
                   (float(u.min()), float(u.max())))

    def _f(self, u: npt.ArrayLike, der: int = 0) -> FloatArray:
        return np.asarray(np.polynomial.polynomial.polyval(np.asarray(u, dtype=float), self._derivs[der]),
                          dtype=float)

    def _speed(self, u: npt.ArrayLike) -> FloatArray:
        return np.sqrt(1.0 + self._f(u, 1) ** 2)

    def _segment(self, a: float, b: float) -> float:
        mid, half = 0.5 * (a + b), 0.5 * (b - a)
        return float(half * np.sum(_GL_W * self._speed(mid + half * _GL_X)))

    # --- arc length ---------------------------------------------------------------------------
    def arc_length(self, u: npt.ArrayLike) -> FloatArray:
        """``s(u)``: the table node below ``u`` plus one quadrature of the rest."""
        uu = np.atleast_1d(np.asarray(u, dtype=float)).reshape(-1)
        k = np.clip(np.searchsorted(self._table_u, uu) - 1, 0, len(self._table_u) - 2)
        a = self._table_u[k]
        mid, half = 0.5 * (a + uu), 0.5 * (uu - a)
        seg = half * np.sum(_GL_W[None, :] * self._speed(mid[:, None] + half[:, None] * _GL_X[None, :]), axis=1)
        return np.asarray((self._table_s[k] + seg).reshape(np.shape(u)), dtype=float)

    def u_of_s(self, s: npt.ArrayLike) -> FloatArray:
        """The inverse of :meth:`arc_length` (Newton from the table's interpolation)."""
        ss = np.atleast_1d(np.asarray(s, dtype=float))
        u = np.interp(ss, self._table_s, self._table_u)
        for _ in range(30):
            step = (self.arc_length(u) - ss) / self._speed(u)
            u = u - step
            if np.max(np.abs(step)) < NEWTON_TOL_M * 1e-2:
                break
        return np.asarray(u.reshape(np.shape(s)), dtype=float)

    # --- geometry at arc length s ------------------------------------------------------------
    def _rot(self) -> FloatArray:
        c, s = np.cos(self.angle), np.sin(self.angle)
        return np.array([[c, -s], [s, c]])

    def heading(self, s: npt.ArrayLike) -> FloatArray:
        """World heading of the path's tangent at ``s`` [rad]."""
        return np.asarray(self.angle + np.arctan(self._f(self.u_of_s(s), 1)), dtype=float)

    def curvature(self, s: npt.ArrayLike) -> FloatArray:
        """Signed curvature ``κ(s)`` (positive turning left) [1/m]."""
        u = self.u_of_s(s)
        return np.asarray(self._f(u, 2) / self._speed(u) ** 3, dtype=float)

    # --- transforms ---------------------------------------------------------------------------
    def to_world(self, s: npt.ArrayLike, d: npt.ArrayLike) -> FloatArray:
        """``(s, d) -> (x, y)`` world, shape ``(n, 2)``."""
        ss, dd = np.broadcast_arrays(np.atleast_1d(np.asarray(s, dtype=float)),
                                     np.atleast_1d(np.asarray(d, dtype=float)))
        u = self.u_of_s(ss)
        fp = self._f(u, 1)
        norm = np.sqrt(1.0 + fp ** 2)
        local = np.stack([u - dd * fp / norm, self._f(u) + dd / norm], axis=1)
        return np.asarray(local @ self._rot().T + np.asarray(self.origin), dtype=float)

    def to_road(self, points: npt.ArrayLike) -> FloatArray:
        """``(x, y)`` world ``(n, 2)`` -> ``(s, d)`` ``(n, 2)`` by projection on the path."""
        P = np.atleast_2d(np.asarray(points, dtype=float))
        local = (P - np.asarray(self.origin)) @ self._rot()
        up, wp = local[:, 0], local[:, 1]
        u = up.copy()
        for _ in range(50):
            f, f1, f2 = self._f(u), self._f(u, 1), self._f(u, 2)
            g = (u - up) + (f - wp) * f1
            dg = 1.0 + f1 ** 2 + (f - wp) * f2
            step = g / dg
            u = u - step
            if np.max(np.abs(step)) < NEWTON_TOL_M * 1e-2:
                break
        f1 = self._f(u, 1)
        norm = np.sqrt(1.0 + f1 ** 2)
        d = (-(up - u) * f1 + (wp - self._f(u))) / norm
        return np.stack([self.arc_length(u), d], axis=1)

    def velocity_to_world(self, s: npt.ArrayLike, d: npt.ArrayLike, vs: npt.ArrayLike,
                          vd: npt.ArrayLike) -> FloatArray:
        """World velocity ``(n, 2)`` of the road-frame motion ``(s, d, ṡ, ḋ)`` (Frenet)."""
        ss, dd, a, b = (np.atleast_1d(np.asarray(x, dtype=float)) for x in (s, d, vs, vd))
        h = self.heading(ss)
        k = self.curvature(ss)
        t = np.stack([np.cos(h), np.sin(h)], axis=1)
        n = np.stack([-np.sin(h), np.cos(h)], axis=1)
        return np.asarray(((1.0 - k * dd) * a)[:, None] * t + b[:, None] * n, dtype=float)

    def velocity_to_road(self, s: npt.ArrayLike, d: npt.ArrayLike, velocity: npt.ArrayLike) -> FloatArray:
        """``(ṡ, ḋ)`` ``(n, 2)`` of a world velocity ``(n, 2)`` at ``(s, d)``."""
        ss, dd = np.atleast_1d(np.asarray(s, dtype=float)), np.atleast_1d(np.asarray(d, dtype=float))
        V = np.atleast_2d(np.asarray(velocity, dtype=float))
        h = self.heading(ss)
        k = self.curvature(ss)
        vt = V[:, 0] * np.cos(h) + V[:, 1] * np.sin(h)
        vn = -V[:, 0] * np.sin(h) + V[:, 1] * np.cos(h)
        return np.stack([vt / (1.0 - k * dd), vn], axis=1)
