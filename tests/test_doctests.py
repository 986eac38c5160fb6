"""The ``Examples`` sections of the public API run and print what they say (issue 31).

The API reference shows every docstring of ``iamp.__all__``; an example there that no longer
runs, or prints another number, would teach the reader something false.  Each example found by
:class:`doctest.DocTestFinder` on the public objects (their methods included) is one test here,
run with ``NORMALIZE_WHITESPACE | ELLIPSIS`` in fresh globals.
"""

from __future__ import annotations

import doctest
import inspect
from collections.abc import Iterator
from typing import Any

import pytest

import iamp

FLAGS = doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS

#: Names whose docstrings must carry an example (the entry points a reader starts from).
MUST_HAVE_EXAMPLES = ("iamp.load_scenario", "iamp.plan", "iamp.compare", "iamp.Plan.states",
                      "iamp.Predictor.default", "iamp.Predictor.predict", "iamp.Problem.corners",
                      "iamp.SurroundingVehicle.corner_x", "iamp.PMPPlanner.plan", "iamp.plan_batch")


def _examples() -> Iterator[doctest.DocTest]:
    finder = doctest.DocTestFinder(exclude_empty=True)
    seen: set[tuple[str | None, int | None, str]] = set()
    for name in sorted(iamp.__all__):
        obj: Any = getattr(iamp, name)
        if name.startswith("_") or not (inspect.isclass(obj) or inspect.isroutine(obj) or inspect.ismodule(obj)):
            continue
        for test in finder.find(obj, f"iamp.{name}", globs={}):
            key = (test.filename, test.lineno, test.docstring or "")
            if test.examples and key not in seen:
                seen.add(key)
                yield test


EXAMPLES = sorted(_examples(), key=lambda t: t.name)


def test_the_entry_points_have_examples() -> None:
    """The examples this file runs include those of the entry points (the finder is not vacuous)."""
    found = {t.name for t in EXAMPLES}
    missing = [n for n in MUST_HAVE_EXAMPLES if n not in found]
    assert not missing, f"no Examples section in {missing}"


@pytest.mark.parametrize("test", EXAMPLES, ids=[t.name for t in EXAMPLES])
def test_docstring_example_runs(test: doctest.DocTest) -> None:
    out: list[str] = []
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    result = runner.run(test, out=out.append, clear_globs=True)
    assert result.failed == 0, "".join(out)


def test_a_wrong_example_fails() -> None:
    """The runner above does fail an example whose output is not what it says."""
    parser = doctest.DocTestParser()
    test = parser.get_doctest(">>> import iamp\n>>> iamp.load_scenario('paper-1-poly').m\n2\n", {}, "wrong",
                              None, 0)
    result = doctest.DocTestRunner(optionflags=FLAGS).run(test, out=lambda s: None)
    assert result.failed == 1
