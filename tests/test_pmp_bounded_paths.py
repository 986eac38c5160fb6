"""The bounded PMP's shortcuts return what the long way returns, bit for bit (issue 32).

* :func:`iamp.planners.pmp.bounded._derivative` is ``numpy``'s ``polyder`` (``j·c_j``);
* the contact-time search's evaluator answers a repeated contact time without a solve, with
  the numbers a solve warm-started from its own multipliers gives (no Newton step is taken);
* :meth:`BoundedSolution.states_inputs` and :meth:`BoundedSolution.ends_and_contacts` are
  :meth:`~BoundedSolution.states` and :meth:`~BoundedSolution.inputs` at those times.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.comparison.bench.limits import bounded_pmp_problems
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp.bounded import BoundedSolution, _derivative, _Evaluator

coefficient = st.floats(-1e4, 1e4, allow_nan=False).filter(lambda x: x == 0.0 or abs(x) > 1e-8)


@settings(max_examples=300, deadline=None)
@given(st.lists(coefficient, min_size=1, max_size=6))
def test_the_derivative_is_numpys_polyder(c: list[float]) -> None:
    ref = np.polynomial.polynomial.polyder(np.asarray(c, dtype=float)).tolist() if len(c) > 1 else [0.0]
    assert [x.hex() for x in _derivative(c)] == [float(x).hex() for x in ref]


def test_a_repeated_contact_time_is_answered_as_a_solve_would() -> None:
    problem = bounded_pmp_problems()["bounded_pmp_one_vehicle_certified"]
    ev = _Evaluator(problem)
    for t in (3.0, 3.5, 3.2):
        ev(np.array([t]))
    solved = ev.evaluations
    J, r, lams = ev(np.array([3.5]))
    assert ev.evaluations == solved  # no solve
    t = np.array([3.5])
    J2, r2, lams2 = ev._solve(t, t.tolist())  # warm from its own multipliers
    assert ev.evaluations == solved + 1
    assert J == J2 and r.tobytes() == r2.tobytes() and lams == lams2


def test_the_combined_evaluations_are_the_separate_ones() -> None:
    problem = bounded_pmp_problems()["bounded_pmp_one_vehicle_certified"]
    sol = PMPPlanner(diagnostics=False).plan(problem).trajectory
    assert isinstance(sol, BoundedSolution)
    t = np.linspace(-0.5, problem.tf + 0.5, 777)
    X, U = sol.states_inputs(t)
    assert X.tobytes() == sol.states(t).tobytes() and U.tobytes() == sol.inputs(t).tobytes()
    ends = np.concatenate(([0.0, problem.tf], sol.contact_times))
    assert sol.ends_and_contacts().tobytes() == sol.states(ends).tobytes()
