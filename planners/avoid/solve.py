r"""The avoidance QP's solver: a backend of the one registry (:mod:`iamp.planners.qp.backends`).

The problem is :math:`\min \tfrac12 z^\top P z` s.t. equality rows :math:`A_{eq} z = b` and
one-sided rows :math:`A_{in} z \le u` (:mod:`iamp.planners.avoid.data`), passed to the
registry's general form ``l <= Az <= u`` with ``l = (b, -inf)``, ``u = (b, u_in)``.  A sweep
candidate changes ``u`` only (:meth:`BoundSolver.set_upper`), a crossing-time box of the fixed
pattern the values of ``A`` and ``u`` (:meth:`BoundSolver.set_values`); the backend keeps its
set-up (OSQP and Clarabel update values on the same symbolic factorisation, PIQP too).
Multipliers are the registry's (OSQP's convention: :math:`Pz + A^\top y = 0`, ``y >= 0`` on a
binding upper bound).

Settings are each backend's registry defaults, plus :data:`AVOID_SETTINGS` (then the
caller's ``settings``):

* OSQP: ``eps_abs = 1e-7`` and ``max_iter = 50_000`` (the registry's equality-QP defaults are
  1e-5 and 10,000); ``eps_rel = 0``, polishing with ``polish_refine_iter = 10`` and no
  dual-gap check as in the registry.  The polish solves the KKT system of the guessed active
  set exactly; without it OSQP is accurate to ``eps_abs`` only and the plan's KKT check
  reports it ``inaccurate``.  Warm-started from the previous candidate.
* Clarabel: the registry's tolerances 1e-12, ``max_iter = 200`` (no warm start: interior point).
* PIQP: the registry's ``eps_abs = 1e-10``, ``eps_rel = 0``.

A backend that solves equality-constrained QPs only (``kkt``) is refused with
:class:`~iamp.core.errors.OptionError` (:func:`~.options.check_avoid_solver`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..qp.backends import QPSolution, get_backend
from .options import check_avoid_solver

FloatArray = NDArray[np.float64]

#: What the avoidance QP adds to a backend's registry defaults (module docstring).
AVOID_SETTINGS: dict[str, dict[str, Any]] = {"osqp": {"eps_abs": 1e-7, "max_iter": 50_000}}


class BoundSolver:
    """One set-up registry backend for ``½zᵀPz`` s.t. ``A[:n_eq] z = b``, ``A[n_eq:] z <= u_in``.

    Parameters
    ----------
    name : str
        A registered QP backend that accepts inequalities (osqp, clarabel, piqp).
    P : scipy.sparse matrix
        Upper triangle of the cost Hessian.
    A : scipy.sparse matrix
        Equality rows, then inequality rows; its pattern (explicit zeros included) is fixed.
    b_eq : ndarray, shape (n_eq,)
    u_in : ndarray
        Initial upper bounds of the inequality rows.
    settings : dict, optional
        Overrides of the backend's settings (after :data:`AVOID_SETTINGS`).

    Raises
    ------
    OptionError
        For a backend that does not accept inequality rows or an unknown name.
    MissingDependencyError
        When the backend's package is not installed.
    """

    def __init__(self, name: str, P: sp.spmatrix, A: sp.spmatrix, b_eq: FloatArray, u_in: FloatArray,
                 settings: dict[str, Any] | None = None) -> None:
        check_avoid_solver(name)
        self.name = name
        self.b_eq = np.asarray(b_eq, dtype=float)
        self.n_eq = self.b_eq.size
        u_in = np.asarray(u_in, dtype=float)
        n = P.shape[0]
        l = np.r_[self.b_eq, np.full(u_in.size, -np.inf)]
        given = {**AVOID_SETTINGS.get(name, {}), **(settings or {})}
        self.backend = get_backend(name)(P, np.zeros(n), A, l, np.r_[self.b_eq, u_in], given)
        self.settings = dict(self.backend.settings)

    def set_upper(self, u_in: FloatArray) -> None:
        """New upper bounds of the inequality rows."""
        self.backend.update(u=np.r_[self.b_eq, u_in])

    def set_values(self, A: sp.spmatrix, u_in: FloatArray) -> None:
        """New values of ``A`` on the pattern it was set up with (CSC, sorted), and new upper bounds."""
        A = sp.csc_matrix(A)
        A.sort_indices()
        self.backend.update(Ax=np.array(A.data, dtype=float), u=np.r_[self.b_eq, u_in])

    def warm_start(self, z: FloatArray, y: FloatArray) -> None:
        """Start the next solve from ``(z, y)`` (OSQP; interior-point backends ignore it)."""
        self.backend.warm_start(z, y)

    def solve(self) -> QPSolution:
        """Solve with the current data (the registry's :class:`~iamp.planners.qp.backends.base.QPSolution`)."""
        return self.backend.solve()
