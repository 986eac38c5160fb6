r"""The result every planner returns (PMP, equality QP, avoidance QP): :class:`Plan`.

A :class:`Plan` carries the problem it came from, the status (:mod:`iamp.core.status`), the
cost

.. math::  J = \tfrac12 \int_0^{t_f} \big(u_x^2 + u_y^2\big)\,dt

evaluated on the planner's own solution, the contact times :math:`t_i`, the jumps (the co-state
jumps :math:`\Phi_i` for the PMP, the multipliers :math:`\nu_i` for the QP, SPEC §3.3), and a
trajectory that can be evaluated at any :math:`t \in [0, t_f]`.  A plan whose status is not in
:data:`~iamp.core.status.SUCCESS` carries no cost, no contact times and no jumps.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from iamp.core.diagnostics import Diagnostics
from iamp.core.peaks import PeaksReport, peaks_report
from iamp.core.problem import Problem
from iamp.core.safety import SafetyReport, safety_report
from iamp.core.status import LIMITS_VIOLATED, OPTIMAL, SUCCESS, UNSAFE
from iamp.core.status import OPTIMAL as STATUS_OPTIMAL  # noqa: F401 - kept for callers

FloatArray = NDArray[np.float64]
#: Column names of a sampled trajectory (SPEC §5), in order.
TRAJECTORY_KEYS = ("t", "x", "y", "vx", "vy", "ax", "ay")


class Trajectory(Protocol):
    """A continuous ego trajectory: states ``(s_x, v_x, s_y, v_y)`` and inputs ``(u_x, u_y)``."""

    def states(self, t: ArrayLike) -> FloatArray:
        """States at the times ``t``, shape ``(len(t), 4)``."""
        ...

    def inputs(self, t: ArrayLike) -> FloatArray:
        """Inputs at the times ``t``, shape ``(len(t), 2)``."""
        ...


@dataclass(init=False)
class Plan:
    """The outcome of one plan: status, cost, contact times, jumps and the trajectory.

    Every planner (:func:`iamp.plan`, :class:`iamp.PMPPlanner`, the QPs) returns one.  A plan
    whose status is not a success (:data:`iamp.core.status.SUCCESS`) carries no cost, NaN
    contact times and jumps, and (usually) no trajectory: a solver failure is a status, never
    an exception with a half result.

    Attributes
    ----------
    problem : Problem
        The problem that was solved (with the exact polynomials used).
    planner : str
        ``"pmp"`` or ``"qp"``.
    status : str
        One of :data:`iamp.core.status.STATUSES`; ``"optimal"`` only after the plan checked
        its own residuals against the tolerance table.
    cost : float or None
        ``J`` on the planner's own solution; ``None`` unless the status is a success.
    contact_times : ndarray, shape (m,)
        ``t_i`` in the order of ``problem.vehicles``.
    jumps : ndarray, shape (m, 2)
        ``(Φ_i,x, Φ_i,y)`` (PMP) or ``(ν_i,x, ν_i,y)`` (QP).
    trajectory : Trajectory or None
        ``states(t) -> (len(t), 4)`` and ``inputs(t) -> (len(t), 2)`` (the planner's own class:
        the PMP's solution, the QP's exact hold trajectory); ``None`` for a failed plan.
    solve_time_s : float
        Wall time of the whole plan (including the contact-time search).
    residuals : dict
        Max-abs residual of every condition the planner solved or satisfied.
    solver, hold, steps : optional
        QP configuration (``None`` for the PMP; ``steps`` is the output sampling).
    diagnostics : Diagnostics
        How the planner reached the plan (the checks and which one failed, the search, the
        sweep's candidates): the planner family's frozen, typed subclass of
        :class:`~iamp.core.diagnostics.Diagnostics`.
    info : Mapping (read-only, deprecated)
        ``diagnostics.as_info()``, the old ``info`` dict's keys and values; kept for one
        release, read :attr:`diagnostics` instead.  ``Plan(..., info={...})`` is still
        accepted (converted with :meth:`Diagnostics.from_info`).

    See Also
    --------
    iamp.plan : Plan a problem.

    Examples
    --------
    >>> import iamp
    >>> plan = iamp.plan(iamp.load_scenario("paper-1-poly"))
    >>> plan.planner, plan.status, plan.ok
    ('pmp', 'optimal', True)
    >>> plan.jumps.shape
    (1, 2)
    """

    problem: Problem
    planner: str
    status: str
    cost: float | None
    contact_times: FloatArray
    jumps: FloatArray
    trajectory: Trajectory | None
    solve_time_s: float = 0.0
    residuals: dict[str, float] = field(default_factory=dict)
    solver: str | None = None
    hold: str | None = None
    steps: int | None = None
    diagnostics: Diagnostics = field(default_factory=Diagnostics)
    _safety: SafetyReport | None = field(default=None, repr=False, compare=False)
    _peaks: PeaksReport | None = field(default=None, repr=False, compare=False)

    def __init__(self, problem: Problem, planner: str, status: str, cost: float | None,
                 contact_times: FloatArray, jumps: FloatArray, trajectory: Trajectory | None,
                 solve_time_s: float = 0.0, residuals: dict[str, float] | None = None,
                 solver: str | None = None, hold: str | None = None, steps: int | None = None,
                 diagnostics: Diagnostics | None = None, info: Mapping[str, object] | None = None,
                 _safety: SafetyReport | None = None, _peaks: PeaksReport | None = None) -> None:
        self.problem, self.planner, self.status, self.cost = problem, planner, status, cost
        self.contact_times, self.jumps, self.trajectory = contact_times, jumps, trajectory
        self.solve_time_s = solve_time_s
        self.residuals = {} if residuals is None else residuals
        self.solver, self.hold, self.steps = solver, hold, steps
        if diagnostics is not None and info:
            raise ValueError("give a plan either diagnostics or info (deprecated), not both")
        self.diagnostics = diagnostics if diagnostics is not None else Diagnostics.from_info(info or {})
        self._safety, self._peaks = _safety, _peaks

    @property
    def info(self) -> Mapping[str, Any]:
        """Deprecated: the read-only mapping ``diagnostics.as_info()`` (the old ``info`` dict)."""
        return MappingProxyType(self.diagnostics.as_info())

    def annotate(self, **values: object) -> None:
        """Set diagnostics fields after the plan is made.

        :attr:`diagnostics` is replaced by a new frozen
        :class:`~iamp.core.diagnostics.Diagnostics` of the same family with ``values`` set.

        Parameters
        ----------
        **values
            Diagnostics fields and their new values (e.g. ``reason="..."``).
        """
        self.diagnostics = self.diagnostics.updated(**values)

    # --- status ------------------------------------------------------------------------
    def is_optimal(self) -> bool:
        """Whether the plan is verified and globally optimal.

        Returns
        -------
        bool
            ``True`` when the status is ``"optimal"`` (every self-check passed and, for the
            PMP, the contact times are the certified global minimiser); ``False`` for
            ``"local"`` and every failure.
        """
        return self.status == OPTIMAL

    @property
    def ok(self) -> bool:
        """``True`` when the plan is verified (``"optimal"`` or ``"local"``) and has a cost."""
        return self.status in SUCCESS and self.cost is not None

    # --- the trajectory ----------------------------------------------------------------
    def require_trajectory(self) -> Trajectory:
        """The plan's trajectory, or an error for a plan without one.

        Returns
        -------
        Trajectory
            The planner's own continuous trajectory (``states(t)``, ``inputs(t)``).

        Raises
        ------
        ValueError
            The plan has no trajectory (a failed plan); the message names the planner and the
            status.
        """
        if self.trajectory is None:
            raise ValueError(f"this {self.planner} plan has no trajectory (status {self.status})")
        return self.trajectory

    def states(self, t: ArrayLike) -> FloatArray:
        r"""The ego state :math:`(s_x, v_x, s_y, v_y)` at the times ``t``.

        The state of the planar double integrator :math:`\dot s_x = v_x`, :math:`\dot v_x = u_x`,
        :math:`\dot s_y = v_y`, :math:`\dot v_y = u_y`, evaluated exactly on the planner's own
        continuous trajectory (the PMP's piecewise-cubic solution, whose input is linear between
        the contact times; the QP's exact hold trajectory), not interpolated from samples.

        Parameters
        ----------
        t : float or array_like of float
            Times in ``[0, t_f]`` [s]; a scalar is one time.

        Returns
        -------
        numpy.ndarray, shape (n, 4)
            Row ``k`` is :math:`(s_x, v_x, s_y, v_y)` at ``t[k]`` [m, m/s, m, m/s];
            ``n = 1`` for a scalar ``t``.

        Raises
        ------
        ValueError
            The plan has no trajectory (a failed plan).

        See Also
        --------
        inputs : The inputs at the same times.
        sample : The trajectory on a uniform grid, by column.

        Examples
        --------
        >>> import numpy as np
        >>> import iamp
        >>> problem = iamp.load_scenario("paper-1-poly")
        >>> plan = iamp.plan(problem)
        >>> plan.states(2.5).round(2)
        array([[39.42, 14.67,  0.67,  1.67]])
        >>> ends = plan.states([0.0, problem.tf])
        >>> np.allclose(ends, [problem.ego.initial, problem.ego.final])
        True
        """
        return np.asarray(self.require_trajectory().states(np.atleast_1d(np.asarray(t, dtype=float))), dtype=float)

    def inputs(self, t: ArrayLike) -> FloatArray:
        r"""The ego input (acceleration) :math:`(u_x, u_y)` at the times ``t``.

        Evaluated on the planner's own continuous trajectory; the PMP's input is linear between
        contact times and its derivative jumps at each :math:`t_i` by the co-state jump
        :math:`\Phi_i` (:attr:`jumps`).

        Parameters
        ----------
        t : float or array_like of float
            Times in ``[0, t_f]`` [s]; a scalar is one time.

        Returns
        -------
        numpy.ndarray, shape (n, 2)
            Row ``k`` is :math:`(u_x, u_y)` at ``t[k]`` [m/s²].

        Raises
        ------
        ValueError
            The plan has no trajectory (a failed plan).

        Examples
        --------
        >>> import iamp
        >>> plan = iamp.plan(iamp.load_scenario("paper-1-poly"))
        >>> plan.inputs([0.0, 5.0]).round(3)
        array([[-5.894,  1.227],
               [-1.857, -1.744]])
        """
        return np.asarray(self.require_trajectory().inputs(np.atleast_1d(np.asarray(t, dtype=float))), dtype=float)

    def sample(self, steps: int) -> dict[str, FloatArray]:
        """The trajectory sampled at ``t_k = k·t_f/N``, ``k = 0..N`` (SPEC §5).

        Parameters
        ----------
        steps : int
            ``N``, the number of intervals (``N + 1`` samples).

        Returns
        -------
        dict of str to numpy.ndarray
            The columns ``t``, ``x``, ``y``, ``vx``, ``vy``, ``ax``, ``ay``
            (:data:`TRAJECTORY_KEYS`), each of length ``N + 1``.

        Raises
        ------
        ValueError
            The plan has no trajectory (a failed plan).

        Examples
        --------
        >>> import iamp
        >>> plan = iamp.plan(iamp.load_scenario("paper-1-poly"))
        >>> columns = plan.sample(4)
        >>> columns["t"].tolist()
        [0.0, 1.25, 2.5, 3.75, 5.0]
        >>> columns["x"].round(2).tolist()
        [0.0, 21.37, 39.42, 59.99, 85.0]
        """
        t = np.linspace(0.0, self.problem.tf, int(steps) + 1)
        X = self.states(t)
        U = self.inputs(t)
        return {"t": t, "x": X[:, 0], "y": X[:, 2], "vx": X[:, 1], "vy": X[:, 3], "ax": U[:, 0], "ay": U[:, 1]}

    # --- safety (SPEC §9) -----------------------------------------------------------------
    @property
    def safety(self) -> SafetyReport | None:
        """Where the plan is unsafe (:func:`iamp.core.safety.safety_report`), computed once on
        the plan's own continuous trajectory (a QP's exact hold trajectory); ``None`` for a
        plan without a trajectory."""
        if self._safety is None and self.trajectory is not None:
            self._safety = safety_report(self.problem, self.trajectory)
        return self._safety

    # --- physical limits (SPEC §14) ----------------------------------------------------------
    def judge_limits(self, remedy: str | None = None) -> Plan:
        r"""SPEC §14: no verified plan exceeds a given bound.

        A plan that is ``optimal`` or ``local`` whose exact peaks (:attr:`peaks`) exceed a bound
        of ``problem.limits`` by more than the bound tolerance becomes ``limits_violated`` with
        the reason (the peak, the bound, the violation and where); its cost and trajectory stay,
        so the user sees what an unconstrained planner did.  Idempotent; without limits, or for
        a plan without a trajectory, nothing changes.

        Parameters
        ----------
        remedy : str, optional
            Appended to the reason (e.g. the option that would impose the bound).

        Returns
        -------
        Plan
            The plan itself (changed in place).
        """
        lim = self.problem.limits
        if lim is None or lim.empty or not self.ok or self.peaks is None:
            return self
        bad = self.peaks.exceeded
        if not bad:
            return self
        what = "; ".join(f"{p.name} peaks at {p.peak} beyond {p.bound} by {p.violation:.3g} (t = {p.at})"
                         for p in bad)
        self.annotate(reason=f"the plan exceeds its limits: {what}" + (f"; {remedy}" if remedy else ""),
                      status_before_limits=self.status)
        self.status = LIMITS_VIOLATED
        return self

    @property
    def peaks(self) -> PeaksReport | None:
        """The exact peaks of the plan's own trajectory against ``problem.limits``
        (:func:`iamp.core.peaks.peaks_report`), computed once; ``None`` without a trajectory."""
        if self._peaks is None and self.trajectory is not None:
            self._peaks = peaks_report(self.trajectory, self.problem.tf, self.problem.limits)
            sides = self.diagnostics.polygon_sides
            if sides is not None:
                self._peaks.polygon_sides = int(sides)
        return self._peaks

    # --- residuals of the problem's own conditions --------------------------------------
    def corner_residual(self) -> float:
        r"""How far the plan misses the corners it must pass through.

        .. math::  \max_{i,\ \text{axis}} |s(t_i) - c_i(t_i)|,

        with :math:`c_i(t_i)` the corner of vehicle ``i`` at its contact time
        (:meth:`Problem.corners`).

        Returns
        -------
        float
            The largest absolute corner miss [m] over vehicles and axes.

        Raises
        ------
        ValueError
            The plan has no trajectory (a failed plan).
        """
        X = self.states(self.contact_times)
        C = self.problem.corners(self.contact_times)
        return float(np.max(np.abs(X[:, [0, 2]] - C)))

    def boundary_residual(self) -> float:
        r"""How far the plan misses its fixed boundary states.

        .. math::  \max\big(|x(0) - x_0|_\infty,\ |x(t_f) - x_f|_\infty\big),

        with :math:`x = (s_x, v_x, s_y, v_y)` and :math:`x_0`, :math:`x_f` the problem's
        ``ego.initial`` and ``ego.final``.

        Returns
        -------
        float
            The largest absolute boundary miss (metres or metres per second).

        Raises
        ------
        ValueError
            The plan has no trajectory (a failed plan).
        """
        X = self.states(np.array([0.0, self.problem.tf]))
        return float(max(np.max(np.abs(X[0] - self.problem.ego.initial)),
                         np.max(np.abs(X[1] - self.problem.ego.final))))

    # --- output --------------------------------------------------------------------------
    def to_json(self, scenario: str | None = None, steps: int | None = None) -> dict[str, Any]:
        """The plan as the JSON object of SPEC §5 (and §9, §14).

        Keys: ``scenario``, ``planner``, ``solver``, ``hold``, ``steps``, ``status``, ``cost``,
        ``contact_times``, ``jumps``, ``solve_time_s``, ``trajectory`` (columns sampled by
        :meth:`sample`), ``safety``, and ``limits`` when the problem has limits.  A failed plan
        has ``cost = null`` and empty arrays; its ``failed_check`` and ``reason`` say why.

        Parameters
        ----------
        scenario : str, optional
            The ``scenario`` field (default: the problem's name).
        steps : int, optional
            Sampling intervals of ``trajectory`` (default: the QP's ``N``, else 100).

        Returns
        -------
        dict
            A JSON-serialisable object (plain floats, lists and ``None``).

        Examples
        --------
        >>> import iamp
        >>> plan = iamp.plan(iamp.load_scenario("paper-1-poly"))
        >>> out = plan.to_json(steps=10)
        >>> out["status"], len(out["trajectory"]["t"])
        ('optimal', 11)
        """
        name = self.problem.name if scenario is None else scenario
        n = int(steps if steps is not None else (self.steps or 100))
        # an ``unsafe`` plan (SPEC §14) is a verified trajectory that intrudes: shown with its report
        ok = self.ok or (self.status == UNSAFE and self.trajectory is not None and self.cost is not None)
        traj: dict[str, Any] = self.sample(n) if ok else {k: [] for k in TRAJECTORY_KEYS}
        out: dict[str, Any] = {
            "scenario": name,
            "planner": self.planner,
            "solver": self.solver,
            "hold": self.hold,
            "steps": n,
            "status": self.status,
            "cost": float(self.cost) if ok and self.cost is not None else None,
            # null for a vehicle without a contact (--constraint active: a corner not imposed)
            "contact_times": [float(t) if np.isfinite(t) else None for t in self.contact_times] if ok else [],
            "jumps": [[float(j[0]), float(j[1])] for j in self.jumps] if ok else [],
            "solve_time_s": float(self.solve_time_s),
            "trajectory": {k: [float(x) for x in np.asarray(v)] for k, v in traj.items()},
        }
        safety = self.safety if ok else None
        out["safety"] = safety.to_json() if safety is not None else None
        peaks = self.peaks if ok or self.status == LIMITS_VIOLATED else None
        if peaks is not None:
            out["limits"] = peaks.to_json()
            if peaks.warnings:
                out["limits_warnings"] = list(peaks.warnings)
        d = self.diagnostics
        reported = set(d.order)
        for key in ("limits_infeasible", "limits_polygon_sides"):
            if key in reported or getattr(d, key) is not None:
                out[key] = getattr(d, key)
        avoidance = getattr(d, "avoidance", None) or d.extra.get("avoidance")
        if ok and avoidance is not None:
            out["avoidance"] = avoidance
        active_set = getattr(d, "active_set", None) or d.extra.get("active_set")
        if active_set is not None:
            out["active_set"] = active_set
        if not ok and d.failed_check is not None:
            out["failed_check"] = d.failed_check
        if self.status == UNSAFE and d.unsafe_reason is not None:
            out["reason"] = d.unsafe_reason
        if not ok and d.reason is not None:
            out["reason"] = d.reason
        return out
