""":func:`iamp.planners.pmp.bounded.exact_peaks` on a bounded plan evaluates the extra points
of ``v_x`` and ``s_y`` in one :meth:`~BoundedSolution.states` call (issue 32): the peaks are
those of the long way (states and inputs asked separately, one call per kind of extra point),
bit for bit, and :func:`~iamp.planners.pmp.bounded.apply_state_limits` writes the same
diagnostics in the same order."""

from __future__ import annotations

from typing import Any

import numpy as np

from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.planners.examples import random_problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp.bounded import BoundedSolution, check_values, exact_peaks, solve_bounded_fixed


class _Separate:
    """A trajectory with only ``states`` and ``inputs``: exact_peaks takes the long way."""

    def __init__(self, sol: BoundedSolution):
        self.sol = sol

    def states(self, t: Any) -> Any:
        return self.sol.states(t)

    def inputs(self, t: Any) -> Any:
        return self.sol.inputs(t)


def _bounded_solutions() -> list[BoundedSolution]:
    out = []
    for seed in (0, 4, 5, 10, 11):
        for scale in (0.5, 0.8, 1.0):
            box = PhysicalLimits(ax=(PASSENGER_CAR.ax[0] * scale, PASSENGER_CAR.ax[1] * scale),
                                 ay=(PASSENGER_CAR.ay[0] * scale, PASSENGER_CAR.ay[1] * scale))
            plan = PMPPlanner(diagnostics=False).plan(random_problem(seed, m=1).with_limits(box))
            if isinstance(plan.trajectory, BoundedSolution):
                out.append(plan.trajectory)
    return out


def test_the_peaks_are_those_of_the_long_way() -> None:
    sols = _bounded_solutions()
    assert len(sols) >= 8
    extra = 0
    for sol in sols:
        tf = float(sol.problem.tf)
        got, ref = exact_peaks(sol, tf, sol.knots()), exact_peaks(_Separate(sol), tf, sol.knots())
        assert repr(got) == repr(ref)
        # some plans have interior extrema (the combined call is exercised)
        kn = np.asarray(sorted(set(sol.knots()) | {0.0, tf}))
        U = sol.inputs(kn)
        extra += int(np.any(U[:-1, 0] * U[1:, 0] < 0))
    assert extra > 0


def test_the_hamiltonian_jump_terms_of_the_self_check_are_the_long_ways() -> None:
    """One vehicle: check_values evaluates H at the contact time with its other H values; the
    terms (r, size) are those of a separate evaluation with ẋ_s from Vehicle.speed, bit for bit."""
    for sol in _bounded_solutions():
        fresh = solve_bounded_fixed(sol.problem, sol.contact_times, [ax.lam for ax in sol.axes])
        check_values(fresh)
        r, size = fresh.hamiltonian_jump_terms()
        t = fresh.contact_times
        veh = sol.problem.vehicles[0]
        xdot = np.array([float(veh.speed(t[0]))])
        H = fresh._hamiltonian(np.concatenate((t, t)), np.array([True, False]))
        X = fresh.states(t)
        J = fresh.jumps
        r_ref = H[:1] - H[1:] - xdot * J[:, 0]
        size_ref = np.abs(J[:, 0]) * (np.abs(X[:, 1]) + np.abs(xdot)) + np.abs(J[:, 1]) * np.abs(X[:, 3])
        assert r.tobytes() == r_ref.tobytes() and size.tobytes() == size_ref.tobytes()
