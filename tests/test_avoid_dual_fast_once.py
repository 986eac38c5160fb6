"""A candidate's polynomial bounded once (issue 32): in
:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidPlanner.search` the polynomial of a box's
candidate that joins the box's polynomials is no longer bounded on its own before the largest bound of
them all (:func:`~iamp.planners.avoid.dual.max_lower_bound`), which takes it in: the box's bound is the
same number.  Checked as the property it rests on (no member's own bound,
:func:`~iamp.planners.avoid.dual.lower_bounds`, exceeds the largest; a NaN proves nothing) over
hypothesis-generated polynomials (ties, repeats, constants, NaN and infinite coefficients) and over
every bound of a one- and a three-vehicle search, the former and the present maximum compared bit for
bit."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st_h

from iamp.planners import registry
from iamp.planners.avoid import continuous, dual, schur
from iamp.planners.avoid.dual import DualPolynomial, Packing
from iamp.planners.examples import overtake_problem, overtake_three_problem

# --- a candidate's polynomial bounded once (ContinuousAvoidPlanner.search) ---------------------

def _bits(x: float) -> bytes:
    return np.asarray(x, dtype=float).tobytes()


def _former_and_now(bound: float, own: float, largest: float) -> tuple[float, float]:
    """The box's bound after its candidate's polynomial ``dp`` as it was, ``max(max(bound,
    dp.lower_bound), max_lower_bound(polys))``, and as it is, ``max(bound, max_lower_bound(polys))``
    (``dp`` among ``polys``; Python's max: the first of equal numbers)."""
    return max(max(bound, own), largest), max(bound, largest)


@st_h.composite
def _boxes(draw: Any) -> tuple[Any, ...]:
    """Polynomials on one or two vehicles' pieces (ties: repeated polynomials, constant ones; some
    with a NaN or an infinite coefficient, some with a round-off margin), a box inside their pieces
    and a bound before them (NaN, -inf, ties with theirs)."""
    m, h = 2, 0.1
    rng = np.random.default_rng(draw(st_h.integers(0, 2**31 - 1)))
    lo = np.array([0.1 + 0.1 * rng.random(), 0.3 + 0.1 * rng.random()])
    hi = np.minimum(lo + 0.1 * rng.random(m) * rng.integers(0, 2, m), [0.2, 0.4])
    polys: list[DualPolynomial] = []
    for _ in range(draw(st_h.integers(1, 10))):
        if polys and rng.random() < 0.2:
            polys.append(polys[int(rng.integers(0, len(polys)))])  # the same polynomial twice
            continue
        q = int(rng.integers(1, 3))
        vehicles = (0, 1) if q == 2 else (int(rng.integers(0, 2)),)
        n = int(rng.choice([3, 5, 9]))
        coef = rng.standard_normal((n,) * q) * float(rng.choice([1.0, 1e6]))
        if rng.random() < 0.3:
            coef.flat[1:] = 0.0  # a constant: its bound on every box the same
        if rng.random() < 0.1:
            coef.flat[int(rng.integers(0, coef.size))] = float(rng.choice([np.nan, np.inf, -np.inf]))
        polys.append(DualPolynomial(vehicles, tuple(1 + 2 * v for v in vehicles), coef, h, np.ones(m),
                                    roundoff=float(rng.choice([0.0, 1e-3]))))
    return polys, lo, hi, draw(st_h.sampled_from([-np.inf, np.nan, 0.0, -1.0, 2.5]))


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning", "ignore:overflow:RuntimeWarning")
@settings(max_examples=120, deadline=None, derandomize=True)
@given(_boxes())
def test_a_member_bound_adds_nothing_to_the_largest(case: tuple[Any, ...]) -> None:
    polys, lo, hi, before = case
    for python in (True, False):  # the kernels run as Python, then compiled (where numba is installed)
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(schur, "_PYTHON", python or schur._PYTHON)
            own = dual.lower_bounds(polys, lo, hi)
            for packing in (None, Packing()):
                largest = dual.max_lower_bound(polys, lo, hi, packing)
                for b in own:
                    # each member's bound is among those the largest is taken over (NaN proves nothing)
                    assert np.isnan(b) or b <= largest
                    for start in (before, b, largest):
                        former, now = _former_and_now(start, b, largest)
                        assert _bits(former) == _bits(now) or (former == now == 0.0)


@pytest.mark.parametrize("case", ["one", "three"])
def test_the_searchs_candidate_polynomials_add_nothing(case: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # every bound of a search's boxes: no member's own bound exceeds the largest, bit for bit
    seen: list[int] = []
    former = continuous.max_lower_bound

    def checked(polys: list[DualPolynomial], lo: Any, hi: Any, packing: Any = None) -> float:
        largest = former(polys, lo, hi, packing)
        for b in dual.lower_bounds(polys, lo, hi):
            assert np.isnan(b) or b <= largest
            f, n = _former_and_now(-np.inf, b, largest)
            assert _bits(f) == _bits(n)
        seen.append(len(polys))
        return largest

    monkeypatch.setattr(continuous, "max_lower_bound", checked)
    problem = overtake_problem() if case == "one" else overtake_three_problem()
    planner = registry.make_planner("qp-avoid", steps=50, hold="foh", solver="piqp", safety="continuous")
    plan = planner.plan(problem)
    assert plan.status == "optimal" and sum(seen) > 0
