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
    """The horizon and the fixed initial and final ego states (SPEC §4 ``[ego]``).

    The ego starts at :math:`x_0 = (x_0, v_{x,0}, y_0, v_{y,0})` at ``t = 0`` and must reach
    :math:`x_f = (x_f, v_{x,f}, y_f, v_{y,f})` at ``t = t_f`` (:attr:`initial`, :attr:`final`).
    Every field is validated on construction: finite, ``tf > 0``, the body positive, and
    within the bounds of :mod:`iamp.core.limits` (SPEC §6).

    Parameters
    ----------
    tf : float
        The horizon :math:`t_f` [s], ``> 0``.
    x0, y0 : float
        Initial longitudinal and lateral position [m].
    vx0 : float
        Initial longitudinal speed [m/s].
    xf, yf : float
        Final longitudinal and lateral position [m].
    vxf : float
        Final longitudinal speed [m/s].
    vy0, vyf : float
        Initial and final lateral speed [m/s] (default 0).
    source : str, optional
        The file the values came from (named by refusals; not compared).
    ego_length, ego_width : float
        The ego's body [m] (``[ego] length`` and ``width``; default 4.8 x 1.8), used by the
        overlap check of SPEC §9.

    Raises
    ------
    iamp.ScenarioError
        A field is not a finite number, ``tf`` or the body is not positive, or a value is
        beyond its bound (the message names the field, e.g. ``ego.tf``).

    Examples
    --------
    >>> from iamp import EgoBoundary
    >>> ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=85.0, yf=3.75, vxf=20.0)
    >>> ego.initial.tolist(), ego.final.tolist()
    ([0.0, 20.0, -2.0, 0.0], [85.0, 20.0, 3.75, 0.0])
    """

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
    r"""A surrounding vehicle with a known longitudinal trajectory :math:`x_s(t)`.

    The vehicle keeps its lane (``y`` constant) and moves along the polynomial
    :math:`x_s(t) = \sum_k c_k t^k` (SPEC §4; any degree).  Around it lies the safety box
    :math:`[x_s(t) \pm (L/2 + S_x)] \times [y_s \pm (W/2 + S_y)]`; the ego passes through the
    named ``corner`` of that box at its contact time :math:`t_i` (:meth:`corner_x`,
    :attr:`corner_y`).

    Parameters
    ----------
    x_poly : sequence of float
        The coefficients :math:`c_0, c_1, \dots` of :math:`x_s(t)` in ascending powers [m, m/s, ...].
    corner : {"front-lower", "front-upper", "rear-lower", "rear-upper"}
        The corner the ego passes: ``front`` / ``rear`` is the sign of the longitudinal
        offset, ``upper`` / ``lower`` that of the lateral one.
    y : float
        The vehicle's lateral position :math:`y_s` (its lane centre) [m].
    length, width : float
        The body :math:`L`, :math:`W` [m], ``> 0``.
    safety_x, safety_y : float
        The safety margins :math:`S_x`, :math:`S_y` around the body [m], ``>= 0``.
    name : str
        The vehicle's name (``sv1``, ... in a scenario file).
    field_prefix : str
        The field refusals name (``vehicles[i]``; not compared).
    source : str, optional
        The file the values came from (not compared).

    Raises
    ------
    iamp.ScenarioError
        An unknown corner, a non-finite, non-positive (body) or negative (margin) value, an
        empty or too long ``x_poly``, or a value beyond its bound (the message names the field,
        e.g. ``vehicles[0].safety_x``).

    Examples
    --------
    >>> from iamp import SurroundingVehicle
    >>> sv = SurroundingVehicle(x_poly=(-15.0, 18.0), corner="front-lower", y=3.75,
    ...                         length=4.8, width=1.8, safety_x=5.0, safety_y=0.5)
    >>> float(sv.offset_x), float(sv.corner_y)
    (7.4, 2.35)
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
        r"""The vehicle's longitudinal position :math:`x_s(t) = \sum_k c_k t^k`.

        Parameters
        ----------
        t : float or array_like of float
            Times [s].

        Returns
        -------
        numpy.ndarray
            :math:`x_s(t)` [m], the shape of ``t``.

        Examples
        --------
        >>> import iamp
        >>> sv = iamp.load_scenario("paper-1-poly").vehicles[0]
        >>> sv.position([0.0, 1.0, 2.0]).tolist()
        [-15.0, 3.0, 21.0]
        """
        return np.asarray(np.polynomial.polynomial.polyval(np.asarray(t, dtype=np.float64), self.x_poly),
                          dtype=np.float64)

    def speed(self, t: npt.ArrayLike) -> npt.NDArray[np.float64]:
        r"""The vehicle's longitudinal speed :math:`\dot x_s(t) = \sum_{k \ge 1} k c_k t^{k-1}`.

        Parameters
        ----------
        t : float or array_like of float
            Times [s].

        Returns
        -------
        numpy.ndarray
            :math:`\dot x_s(t)` [m/s], the shape of ``t`` (0 for a constant :math:`x_s`).
        """
        d = np.polynomial.polynomial.polyder(self.x_poly) if len(self.x_poly) > 1 else [0.0]
        return np.asarray(np.polynomial.polynomial.polyval(np.asarray(t, dtype=np.float64), d), dtype=np.float64)

    def corner_x(self, t: npt.ArrayLike) -> npt.NDArray[np.float64]:
        r"""The longitudinal coordinate of the vehicle's corner at the times ``t``.

        .. math::  x_s(t) \pm (L/2 + S_x),

        ``+`` for a ``front`` corner and ``-`` for a ``rear`` one (:attr:`offset_x`).

        Parameters
        ----------
        t : float or array_like of float
            Times [s].

        Returns
        -------
        numpy.ndarray
            The corner's :math:`x` [m], the shape of ``t``.

        Examples
        --------
        >>> import iamp
        >>> sv = iamp.load_scenario("paper-1-poly").vehicles[0]   # front corner, L/2 + S_x = 7.4 m
        >>> sv.corner_x([0.0, 1.0]).round(6).tolist()
        [-7.6, 10.4]
        """
        return self.position(t) + self.offset_x


@dataclass(frozen=True)
class Problem:
    r"""One optimal lane change: the ego's boundary conditions plus ``m`` surrounding vehicles.

    The problem of SPEC §1: minimise :math:`J = \tfrac12 \int_0^{t_f} (u_x^2 + u_y^2)\,dt` of
    the planar double integrator from ``ego.initial`` to ``ego.final``, with one interior-point
    equality per vehicle ``i`` at a free contact time :math:`t_i \in (0, t_f)`,

    .. math::

        s_x(t_i) = x_{s,i}(t_i) \pm (L_i/2 + S_{x,i}), \qquad
        s_y(t_i) = y_{s,i} \pm (W_i/2 + S_{y,i}).

    Validates itself on construction.  :func:`iamp.load_scenario` builds one from a scenario
    file; every planner takes one.

    Parameters
    ----------
    ego : EgoBoundary
        The horizon and the fixed initial and final ego states.
    vehicles : sequence of SurroundingVehicle
        The surrounding vehicles, one contact time each (``m = len(vehicles)``).
    name : str
        The problem's name (reported in the JSON outputs).
    limits : iamp.core.physical.PhysicalLimits, optional
        The ego's physical limits (the scenario's ``[limits]`` table, SPEC §14); ``None``: the
        paper's unbounded problem.

    Attributes
    ----------
    m : int
        The number of vehicles (= the number of contact times).
    tf : float
        The horizon :math:`t_f` [s] (``ego.tf``).

    Raises
    ------
    iamp.ScenarioError
        A vehicle that is not a :class:`SurroundingVehicle`, too many vehicles, a polynomial
        beyond the bounds over ``[0, t_f]``, or ``limits`` of the wrong type.

    Examples
    --------
    >>> from iamp import EgoBoundary, Problem, SurroundingVehicle
    >>> ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=85.0, yf=3.75, vxf=20.0)
    >>> sv = SurroundingVehicle(x_poly=(-15.0, 18.0), corner="front-lower", y=3.75,
    ...                         length=4.8, width=1.8, safety_x=5.0, safety_y=0.5)
    >>> problem = Problem(ego, (sv,), name="mine")
    >>> problem.m, problem.tf
    (1, 5.0)
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
        r"""The corner positions at the contact times: where the ego must be at each :math:`t_i`.

        Row ``i`` is the corner of vehicle ``i`` at its own contact time,

        .. math::  \big(x_{s,i}(t_i) \pm (L_i/2 + S_{x,i}),\ y_{s,i} \pm (W_i/2 + S_{y,i})\big)

        (:func:`iamp.core.contact.corners`).

        Parameters
        ----------
        contact_times : array_like of float, shape (m,)
            :math:`t_i` in the order of :attr:`vehicles` [s].

        Returns
        -------
        numpy.ndarray, shape (m, 2)
            The corners' :math:`(x, y)` [m].

        Examples
        --------
        >>> import iamp
        >>> problem = iamp.load_scenario("two-vehicle")
        >>> problem.corners([2.0, 3.0]).round(6).tolist()
        [[28.4, 2.35], [58.6, -0.6]]
        """
        return contact.corners(self, contact_times)

    def corners_and_speeds(self, contact_times: npt.ArrayLike) -> tuple[npt.NDArray[np.float64],
                                                                        npt.NDArray[np.float64]]:
        r"""The corners and the vehicles' speeds at the contact times, in one call.

        What a planner's self-check reads of the vehicles at its contact times: the same
        numbers as :meth:`corners` and :meth:`SurroundingVehicle.speed`
        (:func:`iamp.core.contact.corners_and_speeds`).

        Parameters
        ----------
        contact_times : array_like of float, shape (m,)
            :math:`t_i` in the order of :attr:`vehicles` [s].

        Returns
        -------
        corners : numpy.ndarray, shape (m, 2)
            As :meth:`corners` [m].
        speeds : numpy.ndarray, shape (m,)
            :math:`\dot x_{s,i}(t_i)` [m/s].
        """
        return contact.corners_and_speeds(self, contact_times)

    def with_vehicles(self, vehicles: Iterable[SurroundingVehicle]) -> Problem:
        """The same ego problem with other vehicles.

        Parameters
        ----------
        vehicles : iterable of SurroundingVehicle
            The new vehicles.

        Returns
        -------
        Problem
            A new, validated problem with this problem's ego, name and limits.

        Raises
        ------
        iamp.ScenarioError
            As the constructor (a vehicle of the wrong type, a polynomial beyond the bounds).
        """
        return Problem(self.ego, tuple(vehicles), self.name, self.limits)

    def with_limits(self, limits: PhysicalLimits | None) -> Problem:
        """The same problem with other physical limits.

        Only ``limits`` is validated: the ego and the vehicles are this problem's, validated
        when it was made (the vehicle checks cost about 80 µs a problem, and the bounded
        planners call this on every plan).

        Parameters
        ----------
        limits : iamp.core.physical.PhysicalLimits or None
            The new limits; ``None``: the unbounded problem.

        Returns
        -------
        Problem
            A new problem with this problem's ego, vehicles and name.

        Raises
        ------
        iamp.ScenarioError
            ``limits`` is neither a ``PhysicalLimits`` nor ``None``.
        """
        if limits is not None and not isinstance(limits, PhysicalLimits):
            raise ScenarioError("must be an iamp.core.physical.PhysicalLimits or None", "limits", self.ego.source)
        new = object.__new__(Problem)
        for name, value in (("ego", self.ego), ("vehicles", self.vehicles), ("name", self.name), ("limits", limits)):
            object.__setattr__(new, name, value)
        return new
