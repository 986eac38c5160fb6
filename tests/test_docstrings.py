"""Every public name of ``iamp.__all__`` carries a numpydoc docstring (issue 31).

The API reference of the documentation site is generated from these docstrings, so a name
without one is a hole in the reference. Checked here, without numpydoc installed:

- a docstring whose first line is a one-line summary (ends with a period);
- functions and public methods: a ``Parameters`` section that names every parameter of the
  signature (``self``/``cls``, ``*args``/``**kwargs`` aside) and nothing else, and a
  ``Returns`` (or ``Yields``) section unless the annotation says ``None``;
- classes: the summary, and a ``Parameters`` or ``Attributes`` section describing what a
  caller constructs or reads.
"""

from __future__ import annotations

import inspect
import re
import types
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import iamp

_SECTION = re.compile(r"^\s*([A-Z][A-Za-z ]+)\n\s*-{3,}\s*$", re.M)


def _sections(doc: str) -> dict[str, str]:
    """The numpydoc sections of a cleaned docstring, by title."""
    heads = list(_SECTION.finditer(doc))
    out = {}
    for k, m in enumerate(heads):
        end = heads[k + 1].start() if k + 1 < len(heads) else len(doc)
        out[m.group(1).strip()] = doc[m.end():end]
    return out


def _documented_params(body: str) -> set[str]:
    """The names a Parameters section documents (``name : type`` lines, ``a, b : type`` too)."""
    names: set[str] = set()
    for line in body.splitlines():
        if line and not line[0].isspace():
            head = line.split(" : ")[0].split(":")[0] if " : " in line or line.rstrip().endswith(":") else line
            for name in head.split(","):
                name = name.strip().lstrip("*")
                if name.isidentifier():
                    names.add(name)
    return names


def _public_objects() -> Iterator[tuple[str, Any]]:
    for name in sorted(iamp.__all__):
        if name.startswith("_"):
            continue
        yield name, getattr(iamp, name)


def _callables() -> Iterator[tuple[str, Callable[..., Any]]]:
    for name, obj in _public_objects():
        if isinstance(obj, types.FunctionType):
            yield name, obj
        elif inspect.isclass(obj) and not issubclass(obj, BaseException):
            for attr, member in vars(obj).items():
                if attr.startswith("_") or not isinstance(member, (types.FunctionType, classmethod, staticmethod)):
                    continue
                yield f"{name}.{attr}", member.__func__ if isinstance(member, (classmethod, staticmethod)) else member


def _doc(obj: Any) -> str:
    return inspect.cleandoc(obj.__doc__ or "")


@pytest.mark.parametrize(("name", "obj"), list(_public_objects()), ids=lambda v: v if isinstance(v, str) else "")
def test_every_public_name_has_a_summary(name: str, obj: Any) -> None:
    doc = _doc(obj)
    assert doc, f"iamp.{name} has no docstring"
    summary = doc.split("\n\n")[0].strip()
    assert summary.endswith("."), f"iamp.{name}: the summary paragraph must end with a period: {summary!r}"


@pytest.mark.parametrize(("name", "obj"), [(n, o) for n, o in _public_objects()
                                           if inspect.isclass(o) and not issubclass(o, BaseException)],
                         ids=lambda v: v if isinstance(v, str) else "")
def test_every_public_class_documents_what_it_holds(name: str, obj: type) -> None:
    sections = _sections(_doc(obj))
    assert {"Parameters", "Attributes"} & set(sections), f"iamp.{name}: no Parameters or Attributes section"


@pytest.mark.parametrize(("name", "func"), list(_callables()), ids=lambda v: v if isinstance(v, str) else "")
def test_every_public_function_documents_its_parameters_and_return(name: str, func: Callable[..., Any]) -> None:
    doc = _doc(func)
    assert doc, f"iamp.{name} has no docstring"
    sections = _sections(doc)
    sig = inspect.signature(func)
    params = {p.name for p in sig.parameters.values()
              if p.name not in ("self", "cls") and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
    if params:
        assert "Parameters" in sections, f"iamp.{name}: no Parameters section for {sorted(params)}"
        documented = _documented_params(sections["Parameters"])
        assert params <= documented, f"iamp.{name}: undocumented parameters {sorted(params - documented)}"
        assert documented <= params | {p.name for p in sig.parameters.values()}, (
            f"iamp.{name}: documents parameters it does not take {sorted(documented - params)}")
    returns = sig.return_annotation
    if returns not in (None, "None", inspect.Signature.empty) or name.split(".")[-1] in ("plan", "compare"):
        assert {"Returns", "Yields"} & set(sections), f"iamp.{name}: no Returns section"


def test_the_checker_sees_a_missing_section() -> None:
    """The checks above are not vacuous: a function without sections fails them."""

    def undocumented(a: int, b: int) -> int:
        """Add.

        Parameters
        ----------
        a : int
            One.
        """
        return a + b

    sections = _sections(_doc(undocumented))
    assert "Returns" not in sections
    assert _documented_params(sections["Parameters"]) == {"a"}
