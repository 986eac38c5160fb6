r"""The one registry of QP backends (qpsolvers style: one module per backend, one signature).

Every backend solves the general OSQP form

.. math::  \min_z \tfrac12 z^\top P z + q^\top z \quad\text{s.t.}\quad l \le Az \le u

behind :class:`~iamp.planners.qp.backends.base.QPBackend`::

    from . import get_backend

    backend = get_backend("osqp")(P, q, A, l, u)          # P: upper triangle, CSC
    sol = backend.solve()                                 # -> QPSolution (typed)
    backend.update(Ax=new_values, Ax_idx=positions, l=l2, u=u2)   # same patterns
    backend.warm_start(sol.z, sol.y)                      # no-op unless .warm_starts
    sol = backend.solve()
    res = backend.residuals(sol)                          # KKT residuals, recomputed

======== ============================== ============ ==============
name     method                         inequalities warm start
======== ============================== ============ ==============
osqp     ADMM + polishing               yes          yes
clarabel interior point                 yes          no
piqp     proximal interior point        yes          no
kkt      direct banded LU of the KKT    no (raises)  (exact)
======== ============================== ============ ==============

A backend whose package is missing raises
:class:`~iamp.core.errors.MissingDependencyError` naming the ``pip install`` command when it
is requested.  ``kkt`` refuses rows with ``l < u`` with
:class:`~iamp.planners.qp.backends.base.UnsupportedProblemError`.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from iamp.core.errors import OptionError

if TYPE_CHECKING:
    from .base import KKTResiduals, QPBackend, QPSolution, UnsupportedProblemError, kkt_residuals

#: name -> (module, class); the classes are imported on first use (issue 22 item 10: every
#: ``iamp`` command builds the parser that names the backends, and the backends import
#: scipy.sparse, the solvers' packages and the KKT's symbolic analysis).
_CLASSES = {"osqp": ("osqp", "OSQPBackend"), "clarabel": ("clarabel", "ClarabelBackend"),
            "piqp": ("piqp", "PIQPBackend"), "kkt": ("kkt", "KKTBackend")}

#: Which backends accept inequality rows (``cls.supports_inequalities``, without importing them;
#: tests/test_issue22.py checks the two agree).
SUPPORTS_INEQUALITIES = {"osqp": True, "clarabel": True, "piqp": True, "kkt": False}


class _Backends(Mapping[str, "type[QPBackend]"]):
    """A read-only name -> class mapping that imports a backend's module when it is looked up."""

    def __init__(self) -> None:
        #: the classes imported so far (a plan looks its backend up several times)
        self._loaded: dict[str, type[QPBackend]] = {}

    def __getitem__(self, name: str) -> type[QPBackend]:
        backend = self._loaded.get(name)
        if backend is None:
            module, cls = _CLASSES[name]
            backend = self._loaded[name] = getattr(importlib.import_module(f"{__name__}.{module}"), cls)
        return backend

    def __iter__(self) -> Iterator[str]:
        return iter(_CLASSES)

    def __len__(self) -> int:
        return len(_CLASSES)

    def __repr__(self) -> str:
        return f"BACKENDS({', '.join(_CLASSES)})"


#: name -> backend class, all with the signature ``cls(P, q, A, l, u, settings=None)``.
BACKENDS: Mapping[str, type[QPBackend]] = _Backends()


def __getattr__(name: str) -> Any:
    """The base module's names on first use (it imports scipy.sparse)."""
    if name in ("KKTResiduals", "QPBackend", "QPSolution", "UnsupportedProblemError", "kkt_residuals"):
        from . import base

        return getattr(base, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: The backends that iterate (measured against ``kkt``).
ITERATIVE = ("osqp", "clarabel", "piqp")


def get_backend(name: str) -> type[QPBackend]:
    """The backend class registered as ``name``.

    Raises :class:`~iamp.core.errors.OptionError` (a ``ValueError``) for an unknown name and
    :class:`~iamp.core.errors.MissingDependencyError` (with the ``pip install`` command) when
    its package is not installed.
    """
    try:
        cls = BACKENDS[name]
    except KeyError:
        raise OptionError(f"unknown QP backend {name!r}; choose from {', '.join(BACKENDS)}", "solver") from None
    cls.require()
    return cls


__all__ = ["BACKENDS", "ITERATIVE", "KKTResiduals", "QPBackend", "QPSolution", "UnsupportedProblemError",
           "get_backend", "kkt_residuals"]
