"""PMP measurements for ``iamp bench`` (imported by :mod:`iamp.comparison.bench.run`).

:func:`bench_pmp` returns medians over ``repeats`` of the per-call wall time (each repeat
times an inner loop and divides), in seconds:

* ``one_vehicle`` — ``PMPPlanner().plan(paper scenario 1, diagnostics=False)``: scaling,
  exact global contact time (Bernstein root isolation), solve and self-check (pure Python);
* ``two_vehicles`` — the same for ``random_problem(0, m=2)`` including the certified branch
  and bound: ``two_vehicles_pure`` with the search's kernels run as Python,
  ``two_vehicles_compiled`` with the same kernels compiled by numba
  (:func:`iamp.planners.pmp.compiled.load_search`, compiled before the clock starts; the same
  plans bit for bit, tests/test_pmp_search_kernels.py), and ``two_vehicles`` the compiled one
  where numba is installed, else the Python one;
* ``one_vehicle_bounded`` — ``one_vehicle`` with a passenger car's input box
  (``ax`` [-6, 3], ``ay`` [-2, 2]; active: the unbounded plan reaches 4.7 m/s²), the saturated
  PMP of :mod:`iamp.planners.pmp.bounded` (contact-time grid + Brent polish, self-check;
  ``certify_bounded=False``: status ``local``, as the CasADi peer, which certifies nothing);
  ``one_vehicle_bounded_certified`` — the default planner, which adds the global certificate
  over the contact times (status ``optimal``);
  ``fixed_t_bounded`` — its fixed-time solve alone (both axes, semi-smooth Newton);
  the three with the numba-compiled axis solve (:func:`iamp.planners.pmp.compiled.load_axis`,
  compiled before the clock starts) where numba is installed, else the pure path; the
  ``_pure`` and ``_compiled`` keys keep both (the same numbers, tested);
* ``fixed_t_closed_form`` — ``solve_one_vehicle`` at a given contact time (closed-form
  Schur-complement solve, no search);
* ``batch_plans_per_s`` — one-vehicle plans per second of ``plan_batch`` on 10,000 seeded
  random problems (a rate, not a time);
* ``compiled_limit_one_vehicle`` — ``one_vehicle`` with the numba-compiled kernel (only if
  numba is installed; compiled before timing), and ``compiled_kernel_only`` — the compiled
  kernel alone (the limit the Python around it cannot beat).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def _median_per_call(fn: Callable[[], object], repeats: int, inner: int) -> float:
    fn()  # warm-up
    samples = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        samples.append((time.perf_counter() - t0) / inner)
    return float(statistics.median(samples))


def bench_pmp(repeats: int = 7) -> dict[str, float]:
    """The PMP medians (module docstring); keys ``one_vehicle``, ``one_vehicle_bounded``,
    ``fixed_t_bounded``, ``two_vehicles``,
    ``fixed_t_closed_form``, ``batch_plans_per_s`` and, with numba,
    ``compiled_limit_one_vehicle`` and ``compiled_kernel_only``."""
    from iamp.planners.examples import paper_problem, random_problem
    from iamp.planners.pmp.compiled import compiled_kernel, numba_available
    from iamp.planners.pmp.one import one_vehicle_data
    from iamp.planners.pmp.planner import PMPPlanner, plan_batch, solve_one_vehicle

    one = paper_problem(1)
    two = random_problem(0, m=2)
    planner = PMPPlanner()
    t1 = float(planner.plan(one, diagnostics=False).contact_times[0])
    out = {
        "one_vehicle": _median_per_call(lambda: planner.plan(one, diagnostics=False), repeats, 200),
        "two_vehicles_pure": _median_per_call(lambda: planner.plan(two, diagnostics=False), repeats, 3),
        "fixed_t_closed_form": _median_per_call(lambda: solve_one_vehicle(one, t1), repeats, 200),
    }
    out["two_vehicles"] = out["two_vehicles_pure"]
    # the bounded PMP (SPEC §14): the same problem with a passenger car's input box, which
    # the unbounded plan violates (u_x up to 4.7 m/s² against 3), so the saturated law is solved
    from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
    from iamp.planners.pmp.bounded import solve_bounded_fixed

    boxed = one.with_limits(PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay))
    tb = float(planner.plan(boxed, diagnostics=False).contact_times[0])
    from iamp.planners.pmp import compiled as pmp_compiled

    quick = PMPPlanner(certify_bounded=False)
    pmp_compiled.unload_axis()  # the pure path first (a no-op unless loaded before)
    out["one_vehicle_bounded_pure"] = _median_per_call(lambda: quick.plan(boxed, diagnostics=False), repeats, 20)
    out["one_vehicle_bounded_certified_pure"] = _median_per_call(lambda: planner.plan(boxed, diagnostics=False),
                                                                 max(1, repeats // 2), 1)
    out["fixed_t_bounded_pure"] = _median_per_call(lambda: solve_bounded_fixed(boxed, [tb]), repeats, 50)
    for key in ("one_vehicle_bounded", "one_vehicle_bounded_certified", "fixed_t_bounded"):
        out[key] = out[f"{key}_pure"]
    if pmp_compiled.load_axis():  # the numba axis solve, compiled outside the timing
        out["one_vehicle_bounded_compiled"] = _median_per_call(lambda: quick.plan(boxed, diagnostics=False),
                                                               repeats, 50)
        out["one_vehicle_bounded_certified_compiled"] = _median_per_call(
            lambda: planner.plan(boxed, diagnostics=False), repeats, 1)
        out["fixed_t_bounded_compiled"] = _median_per_call(lambda: solve_bounded_fixed(boxed, [tb]), repeats, 200)
        for key in ("one_vehicle_bounded", "one_vehicle_bounded_certified", "fixed_t_bounded"):
            out[key] = out[f"{key}_compiled"]
    if pmp_compiled.load_search():  # the m >= 2 search kernels compiled from the same source (issue 32)
        out["two_vehicles_compiled"] = _median_per_call(lambda: planner.plan(two, diagnostics=False), repeats, 3)
        out["two_vehicles"] = out["two_vehicles_compiled"]
        pmp_compiled.unload_search()
    problems = [random_problem(seed, m=1) for seed in range(10_000)]
    out["batch_plans_per_s"] = len(problems) / _median_per_call(lambda: plan_batch(problems), repeats, 1)
    if numba_available():
        kern = compiled_kernel()
        fast = PMPPlanner(kernel=kern)
        out["compiled_limit_one_vehicle"] = _median_per_call(lambda: fast.plan(one, diagnostics=False), repeats, 200)
        import numpy as np

        _, _, ego, ex, ey, cx, cy = one_vehicle_data(one)
        arrays = [np.asarray(x, dtype=float) for x in (ego, ex, ey, cx)]
        out["compiled_kernel_only"] = _median_per_call(lambda: kern(*arrays, cy), repeats, 2000)
    return out


if __name__ == "__main__":  # pragma: no cover - manual measurement
    import json
    import sys

    print(json.dumps(bench_pmp(int(sys.argv[1]) if len(sys.argv) > 1 else 7), indent=1))
