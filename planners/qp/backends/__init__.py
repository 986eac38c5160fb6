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

from iamp.core.errors import OptionError

from .base import KKTResiduals, QPBackend, QPSolution, UnsupportedProblemError, kkt_residuals
from .clarabel import ClarabelBackend
from .kkt import KKTBackend
from .osqp import OSQPBackend
from .piqp import PIQPBackend

#: name -> backend class, all with the signature ``cls(P, q, A, l, u, settings=None)``.
BACKENDS: dict[str, type[QPBackend]] = {
    "osqp": OSQPBackend,
    "clarabel": ClarabelBackend,
    "piqp": PIQPBackend,
    "kkt": KKTBackend,
}

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
