"""The optimal lane-change problem (SPEC §1) as a self-validating object.

The ego vehicle is a planar double integrator with state ``(s_x, v_x, s_y, v_y)`` and input
``(u_x, u_y)``; the cost is

.. math::  J = \\tfrac12 \\int_0^{t_f} (u_x^2 + u_y^2)\\,dt .

Every surrounding vehicle ``i`` contributes one interior-point equality constraint at a
free contact time ``t_i \\in (0, t_f)``: the ego passes through the named corner of the
vehicle's safety box,

.. math::

    s_x(t_i) = x_{s,i}(t_i) \\pm (L_i/2 + S_{x,i}), \\qquad
    s_y(t_i) = y_{s,i} \\pm (W_i/2 + S_{y,i}),

``+`` for ``front`` / ``upper`` and ``-`` for ``rear`` / ``lower``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import numpy.typing as npt

from iamp.core import contact
from iamp.core.errors import ScenarioError
from iamp.core.limits import LIMITS, first_refusal, polynomial_message
from iamp.core.physical import PhysicalLimits

CORNERS = ("front-lower", "front-upper", "rear-lower", "rear-upper")


def _finite(value: object, name: str, source: str | None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ScenarioError(f"must be a number (got {value!r})", name, source)
    try:
        out = float(value)
    except OverflowError:  # an integer beyond the float range
        raise ScenarioError(f"must be finite (got an integer of {len(str(value))} digits)", name, source) from None
    if not math.isfinite(out):
        raise ScenarioError(f"must be finite (got {out})", name, source)
    return out


def _check(msg: str | None, name: str, source: str | None) -> None:
    """Raise :class:`ScenarioError` for ``name`` if a bound check returned a message."""
    if msg is not None:
        raise ScenarioError(msg, name, source)


def _refuse(refusal: tuple[str, str] | None, source: str | None) -> None:
    """Raise :class:`ScenarioError` for the ``(field, message)`` of :func:`~iamp.core.limits.first_refusal`."""
    if refusal is not None:
        raise ScenarioError(refusal[1], refusal[0], source)


#: Which bound of :data:`iamp.core.limits.LIMITS` each ego field obeys.
_EGO_KIND = {"x0": "position", "y0": "position", "xf": "position", "yf": "position",
             "vx0": "speed", "vy0": "speed", "vxf": "speed", "vyf": "speed"}


@dataclass(frozen=True)
class EgoBoundary:
    """Horizon and the fixed initial and final ego state (SPEC §4 ``[ego]``)."""

    tf: float
    x0: float
    y0: float
    vx0: float
    xf: float
    yf: float
    vxf: float
    vy0: float = 0.0
    vyf: float = 0.0
    source: str | None = field(default=None, compare=False, repr=False)
    #: The ego's body ``[ego] length`` x ``width`` [m] (SPEC §9 overlap; default 4.8 x 1.8).
    ego_length: float = 4.8
    ego_width: float = 1.8

    def __post_init__(self) -> None:
        for name in ("tf", "x0", "y0", "vx0", "xf", "yf", "vxf", "vy0", "vyf"):
            object.__setattr__(self, name, _finite(getattr(self, name), f"ego.{name}", self.source))
        for name, key in (("ego_length", "length"), ("ego_width", "width")):
            object.__setattr__(self, name, _finite(getattr(self, name), f"ego.{key}", self.source))
            if getattr(self, name) <= 0:
                raise ScenarioError(f"must be > 0 (got {getattr(self, name)})", f"ego.{key}", self.source)
        if self.tf <= 0:
            raise ScenarioError(f"must be > 0 (got {self.tf})", "ego.tf", self.source)
        bound = {"position": (LIMITS["position_max_m"], "m"), "speed": (LIMITS["speed_max_mps"], "m/s")}
        _refuse(first_refusal([("ego.tf", self.tf, LIMITS["tf_min_s"], LIMITS["tf_max_s"], "s")],
                              [(f"ego.{name}", getattr(self, name), *bound[kind]) for name, kind in _EGO_KIND.items()]),
                self.source)
        self.initial, self.final  # noqa: B018 - once, here: later reads are plain attributes

    @cached_property
    def initial(self) -> np.ndarray:
        """Initial state ``(s_x, v_x, s_y, v_y)`` (read-only)."""
        out = np.array([self.x0, self.vx0, self.y0, self.vy0])
        out.flags.writeable = False
        return out

    @cached_property
    def final(self) -> np.ndarray:
        """Final state ``(s_x, v_x, s_y, v_y)`` (read-only)."""
        out = np.array([self.xf, self.vxf, self.yf, self.vyf])
        out.flags.writeable = False
        return out


@dataclass(frozen=True)
class SurroundingVehicle:
    """A surrounding vehicle with a known longitudinal trajectory ``x_s(t)``.

    ``x_poly`` holds the coefficients in ascending powers, ``x_s(t) = Σ_k c_k t^k``
    (SPEC §4); any degree is accepted.
    """

    x_poly: tuple[float, ...]
    corner: str
    y: float
    length: float
    width: float
    safety_x: float
    safety_y: float
    name: str = "sv"
    field_prefix: str = field(default="vehicles[0]", compare=False, repr=False)
    source: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        p, src = self.field_prefix, self.source
        if self.corner not in CORNERS:
            raise ScenarioError(
                f"unknown corner {self.corner!r}; expected one of {', '.join(CORNERS)}", f"{p}.corner", src
            )
        for name in ("y", "length", "width", "safety_x", "safety_y"):
            object.__setattr__(self, name, _finite(getattr(self, name), f"{p}.{name}", src))
        for name in ("length", "width"):
            if getattr(self, name) <= 0:
                raise ScenarioError(f"must be > 0 (got {getattr(self, name)})", f"{p}.{name}", src)
        for name in ("safety_x", "safety_y"):
            if getattr(self, name) < 0:
                raise ScenarioError(f"must be >= 0 (got {getattr(self, name)})", f"{p}.{name}", src)
        _refuse(first_refusal([(f"{p}.{name}", getattr(self, name), None, LIMITS["size_max_m"], "m")
                               for name in ("length", "width", "safety_x", "safety_y")],
                              [(f"{p}.y", self.y, LIMITS["position_max_m"], "m")]), src)
        coeffs = self.x_poly
        if isinstance(coeffs, np.ndarray):
            coeffs = coeffs.tolist()
        if not isinstance(coeffs, (list, tuple)):
            raise ScenarioError("must be a list of numbers (ascending powers)", f"{p}.x_poly", src)
        if len(coeffs) == 0:
            raise ScenarioError("must not be empty", f"{p}.x_poly", src)
        if len(coeffs) > LIMITS["poly_max_terms"]:
            raise ScenarioError(f"has {len(coeffs)} coefficients; at most {LIMITS['poly_max_terms']:g} are accepted",
                                f"{p}.x_poly", src)
        coeffs = tuple(_finite(c, f"{p}.x_poly[{k}]", src) for k, c in enumerate(coeffs))
        object.__setattr__(self, "x_poly", coeffs)
        self.offset_x, self.corner_y  # noqa: B018 - the geometry once, here: later reads are plain attributes

    # --- geometry (computed on construction, then plain attributes: a planner reading them does
    # not call back into this module, scripts/walk.py) ------------------------------------------
    @cached_property
    def sign_x(self) -> float:
        """+1 for a ``front`` corner, -1 for ``rear``."""
        return 1.0 if self.corner.startswith("front") else -1.0

    @cached_property
    def sign_y(self) -> float:
        """+1 for an ``upper`` corner, -1 for ``lower``."""
        return 1.0 if self.corner.endswith("upper") else -1.0

    @cached_property
    def offset_x(self) -> float:
        """Signed longitudinal offset of the corner from the vehicle centre."""
        return self.sign_x * (self.length / 2 + self.safety_x)

    @cached_property
    def corner_y(self) -> float:
        """Lateral coordinate of the corner, ``y_s ± (W/2 + S_y)``."""
        return self.y + self.sign_y * (self.width / 2 + self.safety_y)

    @property
    def poly(self) -> np.polynomial.Polynomial:
        """``x_s`` as a numpy polynomial."""
        return np.polynomial.Polynomial(self.x_poly)

    def position(self, t: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """``x_s(t)``."""
        return np.asarray(np.polynomial.polynomial.polyval(np.asarray(t, dtype=np.float64), self.x_poly),
                          dtype=np.float64)

    def speed(self, t: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """``ẋ_s(t)``."""
        d = np.polynomial.polynomial.polyder(self.x_poly) if len(self.x_poly) > 1 else [0.0]
        return np.asarray(np.polynomial.polynomial.polyval(np.asarray(t, dtype=np.float64), d), dtype=np.float64)

    def corner_x(self, t: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Longitudinal coordinate of the corner at time ``t``."""
        return self.position(t) + self.offset_x


@dataclass(frozen=True)
class Problem:
    """One optimal lane change: ego boundary conditions plus ``m >= 1`` vehicles.

    Validates itself on construction (raises :class:`~iamp.core.errors.ScenarioError`).
    """

    ego: EgoBoundary
    vehicles: tuple[SurroundingVehicle, ...]
    name: str = "problem"
    #: The ego's physical limits (the scenario's ``[limits]`` table); ``None``: the paper's
    #: unbounded problem.
    limits: PhysicalLimits | None = None

    def __post_init__(self) -> None:
        vehicles = tuple(self.vehicles)
        for v in vehicles:
            if not isinstance(v, SurroundingVehicle):
                raise ScenarioError("every vehicle must be a SurroundingVehicle with x_poly", "vehicles")
        if len(vehicles) > LIMITS["vehicles_max"]:
            raise ScenarioError(f"at most {LIMITS['vehicles_max']:g} vehicles are accepted (got {len(vehicles)})",
                                "vehicles", self.ego.source)
        for v in vehicles:
            _check(polynomial_message(v.x_poly, self.ego.tf), f"{v.field_prefix}.x_poly", v.source)
        object.__setattr__(self, "vehicles", vehicles)
        if self.limits is not None and not isinstance(self.limits, PhysicalLimits):
            raise ScenarioError("must be an iamp.core.physical.PhysicalLimits or None", "limits", self.ego.source)
        self.m, self.tf  # noqa: B018 - computed once, here: later reads are plain attributes

    @cached_property
    def m(self) -> int:
        """Number of surrounding vehicles (= number of contact times)."""
        return len(self.vehicles)

    @cached_property
    def tf(self) -> float:
        """The horizon ``t_f``."""
        return self.ego.tf

    def corners(self, contact_times: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Corner positions ``(m, 2)`` at the given contact times (:func:`iamp.core.contact.corners`)."""
        return contact.corners(self, contact_times)

    def corners_and_speeds(self, contact_times: npt.ArrayLike) -> tuple[npt.NDArray[np.float64],
                                                                        npt.NDArray[np.float64]]:
        """``(corners(t), [ẋ_s,i(t_i)])``: what a planner's self-check reads of the vehicles at its
        contact times, in one call (the same numbers as :meth:`corners` and
        :meth:`SurroundingVehicle.speed`; :func:`iamp.core.contact.corners_and_speeds`)."""
        return contact.corners_and_speeds(self, contact_times)

    def with_vehicles(self, vehicles: Iterable[SurroundingVehicle]) -> Problem:
        """The same ego problem with other vehicles."""
        return Problem(self.ego, tuple(vehicles), self.name, self.limits)

    def with_limits(self, limits: PhysicalLimits | None) -> Problem:
        """The same problem with other physical limits (``None``: unbounded).

        Only ``limits`` is validated: the ego and the vehicles are this problem's, validated
        when it was made (the vehicle checks cost about 80 µs a problem, and the bounded
        planners call this on every plan)."""
        if limits is not None and not isinstance(limits, PhysicalLimits):
            raise ScenarioError("must be an iamp.core.physical.PhysicalLimits or None", "limits", self.ego.source)
        new = object.__new__(Problem)
        for name, value in (("ego", self.ego), ("vehicles", self.vehicles), ("name", self.name), ("limits", limits)):
            object.__setattr__(new, name, value)
        return new
