"""A :class:`~iamp.simulation.decision.Neighbour` is built by its own ``__init__`` (the fields written into the
instance's dict) instead of the frozen dataclass's generated one (``object.__setattr__`` per field): the same
object — its signature is the fields' (names, order, defaults), every field holds what the generated
``__init__`` of the same fields (the oracle here) stores, positionally or by keyword, and it stays frozen,
comparable, hashable and ``replace``-able."""

from __future__ import annotations

import dataclasses
import inspect
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.decision import Neighbour


@dataclasses.dataclass(frozen=True)
class _Generated:
    """The former class's fields with the dataclass's generated ``__init__``."""

    name: str
    poly: tuple[float, ...]
    y: float
    length: float
    width: float
    lane: int
    vy: float = 0.0
    now: tuple[float, float, float] | None = None


def test_the_signature_is_the_fields():
    sig = inspect.signature(Neighbour)
    fields = dataclasses.fields(Neighbour)
    assert [p.name for p in sig.parameters.values()] == [f.name for f in fields]
    assert [f.name for f in fields] == [f.name for f in dataclasses.fields(_Generated)]
    for p, f in zip(sig.parameters.values(), fields):
        assert p.default is (inspect.Parameter.empty if f.default is dataclasses.MISSING else f.default)
    assert sig.parameters == inspect.signature(_Generated).parameters


number = st.one_of(st.floats(), st.integers(-5, 5), st.sampled_from([0.0, -0.0, math.nan]))
now = st.none() | st.tuples(number, number, number)


@settings(max_examples=100, deadline=None)
@given(name=st.text(max_size=4), poly=st.lists(number, min_size=1, max_size=4).map(tuple), y=number, length=number,
       width=number, lane=st.integers(0, 4), vy=number, now=now, keywords=st.booleans(), defaults=st.booleans())
def test_a_neighbour_holds_what_the_generated_init_stores(name, poly, y, length, width, lane, vy, now, keywords,
                                                          defaults):
    args = (name, poly, y, length, width, lane) if defaults else (name, poly, y, length, width, lane, vy, now)
    names = [f.name for f in dataclasses.fields(_Generated)][: len(args)]
    if keywords:
        n, g = Neighbour(**dict(zip(names, args))), _Generated(**dict(zip(names, args)))
    else:
        n, g = Neighbour(*args), _Generated(*args)
    assert vars(n) == vars(g) and list(vars(n)) == list(vars(g))  # the same objects, in field order
    assert all(getattr(n, f) is getattr(g, f) for f in names)
    assert repr(n) == repr(g).replace("_Generated", "Neighbour", 1)
    m = Neighbour(*args)
    assert (n == m) == (dataclasses.astuple(g) == dataclasses.astuple(_Generated(*args)))
    if n == m:
        assert hash(n) == hash(m) == hash(dataclasses.astuple(n))
    with pytest.raises(dataclasses.FrozenInstanceError):
        n.y = 1.0  # type: ignore[misc]
    r = dataclasses.replace(n, lane=lane + 1)
    assert type(r) is Neighbour and r.lane == lane + 1 and r.poly is n.poly
