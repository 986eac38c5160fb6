r"""The paper's indirect planner: Pontryagin's minimum principle with interior-point
equality constraints at free contact times (SPEC §2).

The pieces, one concern per module:

* :mod:`~iamp.planners.pmp.scale` — the dimensionless problem (time over ``t_f``, lengths
  over the problem's size ``L``; negligible trailing ``x_poly`` terms dropped);
* :mod:`~iamp.planners.pmp.fixed` — the fixed-contact-time jump system
  (:func:`solve_fixed_times`) and the closed-form value function :class:`ValueFunction`
  :math:`J(t) = \bar J + \tfrac12\sum_{\text{axis}} e^\top K(t)^{-1}e`;
* :mod:`~iamp.planners.pmp.roots` — real roots on ``(0, 1)`` without eigenvalues;
* :mod:`~iamp.planners.pmp.search` / :mod:`~iamp.planners.pmp.bound` — the global contact
  times (exact for one vehicle; starts + Newton + certified branch and bound for more);
* :mod:`~iamp.planners.pmp.verify` — the self-check every plan passes before it is called
  optimal;
* :mod:`~iamp.planners.pmp.batch` — many one-vehicle problems at once.

Statuses (:mod:`iamp.core.status`): ``optimal`` — every check passed and the contact times
are the certified global minimiser (for caller-given contact times: the fixed-time optimum);
``local`` — checks passed, global optimality not certified within the box budget;
``inaccurate`` / ``numerical_error`` — a check failed or the linear algebra broke down (no
cost; ``info["failed_check"]`` names it); ``infeasible`` — ``J`` has no interior stationary
point (a corner sits on the ego's start or end state).

Speed (issue 14).  One vehicle goes through the scalar kernel of
:mod:`~iamp.planners.pmp.one` (no arrays until the plan is built; the solution's ``a``, ``b``
and ``z_scaled`` are made on first use, :class:`~iamp.planners.pmp.solution.OneVehicleSolution`);
the kernel's five checks are judged before the plan is called optimal.  The default kernel is
the pure-Python one even when numba is installed: compiling the numba twin
(:func:`iamp.planners.pmp.compiled.compiled_kernel`) takes about 7 s on the first plan and
``import numba`` alone about 0.2–0.4 s, while a pure-Python plan takes about 25 µs, so a
command-line plan, or any process that plans fewer than some 10⁵ problems, would only lose.
Long-running callers opt in with ``PMPPlanner(kernel=compiled_kernel())`` (the same numbers,
tested); many problems at once go through :func:`plan_batch` (numpy, no compilation).
Several vehicles: the search's kernels run as Python (numpy over boxes) unless
:func:`iamp.planners.pmp.compiled.load_search` has compiled them in the process (two vehicles
about 2 ms instead of 13; the same numbers bit for bit).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.core.errors import SolverError
from iamp.core.free import free_plan, transfer_cost
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.status import INFEASIBLE, LOCAL, NUMERICAL_ERROR, OPTIMAL

from .batch import BatchPlan, plan_batch
from .diagnostics import PMPDiagnostics
from .fixed import (
    ValueFunction,
    bridge_kernel,
    bridge_kernel_ds,
    bridge_variance_dt,
    check_times,
    hamiltonian_jump_residuals,
    hermite_cubic,
    jump_system,
    one_vehicle_z,
    solution_from_sigma,
    solve_fixed_times,
    solve_one_vehicle,
    solve_sigma,
)
from .one import one_vehicle_kernel, solve_one
from .options import PMPOptions
from .scale import Scaled, scale_problem
from .search import global_search, newton_sigma, one_vehicle_sigma
from .solution import OneVehicleSolution, PMPSolution
from .verify import check_values, judge, verify

FloatArray = npt.NDArray[np.float64]
#: ``info["search"]["method"]`` of a one-vehicle plan.
ONE_VEHICLE_METHOD = "all roots of the stationarity polynomial"

__all__ = [
    "BatchPlan", "PMPPlanner", "PMPSolution", "ValueFunction", "bridge_kernel", "bridge_kernel_ds",
    "bridge_variance_dt", "hamiltonian_jump_residuals", "hermite_cubic", "jump_system",
    "one_vehicle_contact_time", "plan_batch", "plan_with", "solve_fixed_times", "solve_one_vehicle", "transfer_cost",
]


def one_vehicle_contact_time(problem: Problem) -> float:
    """The exact global contact time for one vehicle (raises SolverError if none)."""
    S = scale_problem(problem)
    s, _ = one_vehicle_sigma(S.EX[0].tolist(), S.EY[0].tolist())
    if not np.isfinite(s):
        raise SolverError("J(t) has no stationary point in (0, tf): no interior contact time", INFEASIBLE)
    return float(s * S.units.T)


def _newton_on_jump_conditions(problem: Problem, J: ValueFunction, t0: Any) -> tuple[FloatArray, float]:
    """Newton on ``r(t) = ∇J(t) = 0`` from ``t0`` (physical units) → ``(t, J(t))``."""
    s, q = newton_sigma(J, np.asarray(t0, dtype=float) / J.tf)
    return s * J.tf, float((J.scaled.jbar + 0.5 * q) * J.units.cost)


#: Newton starts of the uncertified unbounded search that starts the bounded one (``m ≥ 2``,
#: active box): the bounded plan from it equalled the one from the certified ``t*`` on 59 of 59
#: random m = 2, 3 problems with the box at 85 % of the peaks (issue 32).
START_STARTS = 4


@dataclass
class PMPPlanner:
    r"""The PMP planner: Pontryagin's minimum principle with a global contact-time search.

    For fixed contact times :math:`t = (t_1, \dots, t_m)` the optimum is the solution of the
    linear jump system (co-state jumps :math:`\Phi_i` at each :math:`t_i`, input linear between
    them), with the closed-form value function

    .. math::  J(t) = \bar J + \tfrac12 \sum_{\text{axis}} e(t)^\top K(t)^{-1} e(t)

    (:class:`~iamp.planners.pmp.fixed.ValueFunction`).  The planner finds the global minimiser
    :math:`t^*` of :math:`J` over :math:`(0, t_f)^m` -- exactly for one vehicle (every root
    of the stationarity polynomial), by starts, Newton and a certified branch and bound for
    more -- solves the jump system there, and checks the solution's own conditions (corner,
    boundary, co-state and Hamiltonian jumps, cost) before calling the plan ``optimal``.

    Parameters
    ----------
    max_starts : int
        Newton starts (combinations of one-vehicle stationary points) for ``m ≥ 2``.
    max_boxes : int
        Box budget of the branch-and-bound certificate; beyond it the status is ``local``.
    kernel : callable
        The one-vehicle kernel (:func:`~iamp.planners.pmp.one.one_vehicle_kernel`, or its
        numba-compiled twin from :func:`iamp.planners.pmp.compiled.compiled_kernel`).
    compiled : bool or None
        Accepted and ignored (kept for callers of earlier releases): the ``m ≥ 2`` search has
        one implementation, :func:`~iamp.planners.pmp.search.global_search`, whatever is
        installed or loaded (issue 32; its numba copy was removed).
    diagnostics : bool
        Add the physical max-abs residuals to every plan (``plan.residuals``), after the clock
        stops.
    certify_bounded : bool
        With an active input box (SPEC §14), one vehicle: certify the bounded contact-time
        search global (status ``optimal``) or say ``local``; ``False`` skips the certificate.

    See Also
    --------
    iamp.plan : The same planner through the registry (``planner="pmp"``).
    iamp.plan_batch : Many one-vehicle problems at once.

    Examples
    --------
    >>> import iamp
    >>> problem = iamp.load_scenario("two-vehicle")
    >>> plan = iamp.PMPPlanner().plan(problem)
    >>> plan.status, plan.contact_times.round(3).tolist()
    ('optimal', [4.217, 2.462])
    """

    max_starts: int = 32
    max_boxes: int = 200_000
    kernel: Callable[..., list[float]] = one_vehicle_kernel
    compiled: bool | None = None
    diagnostics: bool = True
    certify_bounded: bool = True

    @classmethod
    def from_options(cls, options: PMPOptions) -> PMPPlanner:
        """The planner of the registry's validated options.

        Parameters
        ----------
        options : iamp.planners.pmp.options.PMPOptions
            The validated options (``max_starts``, ``max_boxes``, ``compiled``,
            ``diagnostics``, ``certify_bounded``).

        Returns
        -------
        PMPPlanner
            The planner with those options and the default kernel.
        """
        return cls(max_starts=options.max_starts, max_boxes=options.max_boxes, compiled=options.compiled,
                   diagnostics=options.diagnostics, certify_bounded=options.certify_bounded)

    def search(self, problem: Problem, S: Scaled | None = None,
               progress: Callable[[int, int], None] | None = None) -> tuple[FloatArray, float, bool, dict[str, Any]]:
        r"""The contact-time search: the global minimiser of :math:`J` over :math:`(0, t_f)^m`.

        In scaled units (time over :math:`t_f`, :math:`\sigma = t/t_f`), :math:`\tilde J(\sigma)
        = \tilde J_0 + q(\sigma)/2`.  One vehicle: every root of the stationarity polynomial
        on :math:`(0, 1)`, the one of least :math:`q` (exact, always certified).  More vehicles:
        Newton from up to ``max_starts`` combinations of one-vehicle stationary points, then a
        branch and bound over boxes of :math:`(0, 1)^m` that certifies the minimiser global
        within ``max_boxes`` boxes.

        Parameters
        ----------
        problem : Problem
            The problem.
        S : iamp.planners.pmp.scale.Scaled, optional
            Its scaled form (:func:`~iamp.planners.pmp.scale.scale_problem`), if already made.
        progress : callable, optional
            Called as ``progress(done, total)`` by the branch and bound (``m >= 2``).

        Returns
        -------
        sigma : numpy.ndarray, shape (m,)
            :math:`\sigma^* = t^*/t_f` (NaN when :math:`J` has no interior stationary point).
        q : float
            :math:`q(\sigma^*)`, the scaled cost above :math:`\tilde J_0`.
        certified : bool
            Whether :math:`\sigma^*` is certified global (``False``: the box budget ran out;
            the plan's status is then ``local``).
        info : dict
            How it was found: ``method``, and for ``m >= 2`` the ``boxes`` and ``starts`` used.
        """
        S = scale_problem(problem) if S is None else S
        if problem.m == 1:
            s, q = one_vehicle_sigma(S.EX[0].tolist(), S.EY[0].tolist())
            return np.array([s]), q, True, {"method": ONE_VEHICLE_METHOD}
        res = global_search(ValueFunction(problem, S), self.max_starts, self.max_boxes, progress)
        return res.sigma, res.q, res.certified, {"method": "starts + Newton + branch and bound",
                                                 "boxes": res.boxes, "starts": res.starts}

    def contact_times(self, problem: Problem) -> FloatArray:
        r"""The contact times :math:`t^*`: the global minimiser of :math:`J` over :math:`(0, t_f)^m`.

        Parameters
        ----------
        problem : Problem
            The problem.

        Returns
        -------
        numpy.ndarray, shape (m,)
            :math:`t^*` [s], in the order of ``problem.vehicles`` (see :meth:`search`).

        Raises
        ------
        iamp.SolverError
            :math:`J` has no interior stationary point (status ``infeasible``: a corner sits on
            the ego's start or end state).

        Examples
        --------
        >>> import iamp
        >>> iamp.PMPPlanner().contact_times(iamp.load_scenario("paper-1-poly")).round(3)
        array([3.52])
        """
        S = scale_problem(problem)
        s, _, _, _ = self.search(problem, S)
        if not np.all(np.isfinite(s)):
            raise SolverError("J(t) has no stationary point in (0, tf): no interior contact time", INFEASIBLE)
        return s * S.units.T

    def solve(self, problem: Problem, contact_times: Any = None) -> PMPSolution:
        """The PMP solution at fixed contact times, without the plan's self-check.

        Parameters
        ----------
        problem : Problem
            The problem.
        contact_times : array_like of float, shape (m,), optional
            The contact times [s] (default: the global :math:`t^*`, :meth:`contact_times`).

        Returns
        -------
        PMPSolution
            The solution of the jump system: trajectory, co-state jumps, cost and residuals.

        Raises
        ------
        iamp.SolverError
            No interior contact time (default ``contact_times``), or the jump system is singular.
        ValueError
            Contact times of the wrong length or outside ``(0, t_f)``.
        """
        t = self.contact_times(problem) if contact_times is None else contact_times
        if problem.m == 1:
            return solve_one_vehicle(problem, float(np.asarray(t, dtype=float).reshape(-1)[0]))
        return solve_fixed_times(problem, t)

    def plan(self, problem: Problem, contact_times: Any = None, diagnostics: bool | None = None,
             progress: Callable[[int, int], None] | None = None) -> Plan:
        """Plan and verify: search the contact times, solve the jump system, check the solution.

        Never raises for numerical trouble: a failure is a :class:`Plan` with a failure status
        (``infeasible``, ``numerical_error``, ``inaccurate``) and no cost.  ``solve_time_s``
        covers the search, the solve and the self-check.  With ``problem.limits`` the
        unbounded plan is tried first and the saturated PMP used only if it leaves the input
        box (SPEC §14).

        Parameters
        ----------
        problem : Problem
            The problem.
        contact_times : array_like of float, shape (m,), optional
            Fix the contact times [s]: the plan is then the fixed-time optimum, and the
            Hamiltonian-jump condition is reported in the diagnostics but not required.
            Default: the global minimiser of :math:`J` (:meth:`contact_times`).
        diagnostics : bool, optional
            Add the physical max-abs residuals (``plan.residuals``) after the clock stops
            (default: the planner's field).
        progress : callable, optional
            Called as ``progress(done, total)`` by the branch and bound (``m >= 2``).

        Returns
        -------
        Plan
            ``status`` ``optimal`` (verified, certified global), ``local`` (verified, the box
            budget ran out) or a failure.

        Raises
        ------
        ValueError
            ``contact_times`` of the wrong length or outside ``(0, t_f)``.

        Examples
        --------
        >>> import iamp
        >>> problem = iamp.load_scenario("paper-1-poly")
        >>> planner = iamp.PMPPlanner()
        >>> best = planner.plan(problem)
        >>> fixed = planner.plan(problem, contact_times=[3.0])      # the fixed-time optimum
        >>> round(best.cost, 3), round(fixed.cost, 3)
        (22.865, 25.793)
        """
        if problem.limits is not None and not problem.limits.empty:
            return self._plan_limited(problem, contact_times, diagnostics, progress)
        if problem.m == 0:  # nothing to contact: the minimum-energy cubic, exact and self-checked
            return free_plan(problem, "pmp")
        start = _time.perf_counter()
        diagnostics = self.diagnostics if diagnostics is None else diagnostics
        m = problem.m
        fixed = contact_times is not None
        if m == 1 and not fixed:
            return self._plan_one(problem, start, diagnostics)
        info: dict[str, Any] = {}
        if fixed:
            t_given = check_times(problem, contact_times)
        try:
            with np.errstate(over="raise", divide="raise", invalid="raise"):
                S = scale_problem(problem)
            if fixed:
                sig = t_given / S.units.T
                certified = True
            else:
                sig, _, certified, info["search"] = self.search(problem, S, progress)
                if not np.all(np.isfinite(sig)):
                    return self._failed(problem, INFEASIBLE, "no_interior_contact_time", info, start)
            with np.errstate(over="raise", divide="raise", invalid="raise"):
                z = one_vehicle_z(S, float(sig[0])) if m == 1 else solve_sigma(S, sig)
                sol = solution_from_sigma(problem, S, sig, z)
            checks, failed, bad = judge(check_values(sol, S, stationary=not fixed))
        except SolverError as exc:
            info["error"] = str(exc)
            return self._failed(problem, NUMERICAL_ERROR, "linear_system", info, start)
        except (np.linalg.LinAlgError, FloatingPointError, OverflowError, ZeroDivisionError) as exc:
            info["error"] = f"{type(exc).__name__}: {exc}"
            return self._failed(problem, NUMERICAL_ERROR, "linear_algebra", info, start)
        info["checks"] = checks
        info["failed_check"] = failed
        info["certified_global"] = bool(certified)
        status = bad if bad is not None else (OPTIMAL if certified else LOCAL)
        cost = sol.cost() if bad is None else None
        elapsed = _time.perf_counter() - start
        residuals = None
        if diagnostics:  # after the clock; the plan is made last, with every diagnostic
            with np.errstate(all="ignore"):
                residuals, info["hamiltonian_jump_residuals"] = sol.residuals_and_jumps()
        return Plan(problem=problem, planner="pmp", status=status, cost=cost, contact_times=sol.contact_times.copy(),
                    jumps=sol.jumps.copy(), trajectory=sol, solve_time_s=elapsed, residuals=residuals,
                    diagnostics=PMPDiagnostics(**PMPDiagnostics.info_fields(info)))  # type: ignore[arg-type]

    def _plan_limited(self, problem: Problem, contact_times: Any, diagnostics: bool | None,
                      progress: Callable[[int, int], None] | None) -> Plan:
        """``problem.limits`` given (SPEC §14, :mod:`~iamp.planners.pmp.bounded`).

        Dispatch: the unbounded plan first (the paper's problem, unchanged).  If its inputs
        stay in the ``ax``/``ay`` box (or no box is given), it is the bounded optimum too
        (``J_b ≥ J_u ≥ J_u(t*) = J_b(t*)``) and is returned as it is, with the limits report;
        otherwise the saturated PMP plans from the unbounded ``t*``.  Either way every given
        bound is then checked with exact peaks (``limits_violated`` if one fails).

        With ``m ≥ 2`` free contact times the bounded plan is ``local`` (no certificate over
        several contact times), so the unbounded ``t*`` is only its start: the unbounded
        search runs first without its branch-and-bound certificate (``max_boxes = 0``) from
        the :data:`START_STARTS` best starts (the best Newton-polished one); only if that plan
        respects the box (or fails) is the certified unbounded plan made (it is then the answer,
        ``optimal`` when certified).
        """
        from iamp.planners.pmp.bounded import apply_state_limits, box_respected, plan_bounded

        start = _time.perf_counter()
        free = problem.with_limits(None)
        if problem.m >= 2 and contact_times is None and self.max_boxes > 0:
            base = replace(self, max_boxes=0, max_starts=min(self.max_starts, START_STARTS)).plan(free, None, False)
            base.problem = problem  # the box to check
            if base.status not in (OPTIMAL, LOCAL) or box_respected(base):
                base = self.plan(free, None, diagnostics, progress)  # the answer (or a failure): certified
        else:
            base = self.plan(free, contact_times, diagnostics, progress)
        base.problem = problem
        if base.status not in (OPTIMAL, LOCAL) or box_respected(base):
            return apply_state_limits(base, bounded={"box_active": False,
                                                     "note": "the unbounded plan respects the input box, so it "
                                                             "solves the bounded problem too"}
                                      if base.trajectory is not None else {})
        # no vehicle: the fixed-time problem with no contact time (strictly convex, unique)
        fixed = contact_times if problem.m else np.empty(0)
        plan = plan_bounded(problem, base.contact_times, fixed, start, certify=self.certify_bounded)
        bounded = getattr(plan.diagnostics, "bounded", None)
        return apply_state_limits(plan, bounded={**(bounded or {}), "box_active": True},
                                  unbounded={"status": base.status, "cost": base.cost,
                                             "contact_times": [float(x) for x in base.contact_times]})

    def _plan_one(self, problem: Problem, start: float, diagnostics: bool) -> Plan:
        """One vehicle: :func:`~iamp.planners.pmp.one.solve_one` (scalar code, the data, the
        kernel and its five checks judged before the plan is called optimal); then, after the
        clock and with ``diagnostics``, the solution with its physical residuals
        (:meth:`~iamp.planners.pmp.solution.OneVehicleSolution.checked_from_kernel`) and every
        check of :mod:`~iamp.planners.pmp.verify` on the scaled problem; a failure downgrades the
        plan.  Each stage is called once, in this order, and the plan is made last
        (``python scripts/walk.py``: no module entered twice).  Without ``diagnostics`` the
        solution's trajectory arrays are made on first use
        (:class:`~iamp.planners.pmp.solution.OneVehicleSolution`)."""
        try:
            T, L, k, judged = solve_one(problem, self.kernel)
        except (OverflowError, ZeroDivisionError, ValueError) as exc:
            info: dict[str, Any] = {"search": {"method": ONE_VEHICLE_METHOD}, "error": f"{type(exc).__name__}: {exc}"}
            return self._failed(problem, NUMERICAL_ERROR, "linear_algebra", info, start)
        if judged is None:
            return self._failed(problem, INFEASIBLE, "no_interior_contact_time",
                                {"search": {"method": ONE_VEHICLE_METHOD}}, start)
        checks, failed, bad = judged
        jerk = L / (T * T * T)
        ct = np.empty(1)
        ct[0] = k[0] * T
        jumps = np.empty((1, 2))
        jumps[0, 0] = k[5] * jerk
        jumps[0, 1] = k[6] * jerk
        status = OPTIMAL if bad is None else bad
        cost = k[7] * L * L / (T * T * T) if bad is None else None
        order: tuple[str, ...] = ("search", "checks", "failed_check", "certified_global")
        if not diagnostics:
            sol = OneVehicleSolution.from_kernel(problem, ct, jumps, k, T, L)
            return Plan(problem=problem, planner="pmp", status=status, cost=cost, contact_times=ct, jumps=jumps,
                        trajectory=sol, solve_time_s=_time.perf_counter() - start,
                        diagnostics=PMPDiagnostics(search={"method": ONE_VEHICLE_METHOD}, checks=checks,
                                                   failed_check=failed, certified_global=True, order=order))
        elapsed = _time.perf_counter() - start
        sol, residuals, hj, ev = OneVehicleSolution.checked_from_kernel(problem, ct, jumps, k, T, L)
        with np.errstate(all="ignore"):
            checks, failed_all, bad_all = verify(sol, scale_problem(problem), stationary=True, ev=ev)
        if bad_all is not None and status in (OPTIMAL, LOCAL):
            status, cost, failed = bad_all, None, failed_all
        return Plan(problem=problem, planner="pmp", status=status, cost=cost, contact_times=ct, jumps=jumps,
                    trajectory=sol, solve_time_s=elapsed, residuals=residuals,
                    diagnostics=PMPDiagnostics(search={"method": ONE_VEHICLE_METHOD}, checks=checks,
                                               failed_check=failed, certified_global=True,
                                               hamiltonian_jump_residuals=hj,
                                               order=(*order, "hamiltonian_jump_residuals")))

    @staticmethod
    def _failed(problem: Problem, status: str, check: str, info: dict[str, Any], start: float) -> Plan:
        info["failed_check"] = check
        info.setdefault("checks", {})
        return Plan(problem=problem, planner="pmp", status=status, cost=None,
                    contact_times=np.full(problem.m, np.nan), jumps=np.full((problem.m, 2), np.nan),
                    trajectory=None, solve_time_s=_time.perf_counter() - start,
                    diagnostics=PMPDiagnostics(**PMPDiagnostics.info_fields(info)))  # type: ignore[arg-type]


def plan_with(options: PMPOptions, problem: Problem, /,
              progress: Callable[[int, int], None] | None = None) -> Plan:
    """``PMPPlanner.from_options(options).plan(problem, progress=progress)``: the registry's one call
    (:func:`iamp.planners.registry.prepare`) that builds the planner and plans."""
    return PMPPlanner.from_options(options).plan(problem, progress=progress)
