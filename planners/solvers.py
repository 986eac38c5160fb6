"""Solver backends for the discretised QP through cvxpy: one entry per solver, one uniform
signature, registered in :data:`SOLVERS`.

Each backend maps to cvxpy's solver name plus the explicit high-accuracy settings the
comparison relies on (SPEC §3).  A missing solver raises
:class:`~iamp.core.errors.MissingDependencyError` saying how to install it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import metadata

from iamp.core.errors import MissingDependencyError


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def osqp_settings(eps_abs: float = 1e-5, max_iter: int = 10_000) -> dict:
    """OSQP: ``eps_rel = 0``, ``eps_abs`` small, polishing on.

    The QP has only equality constraints, so a successful polish solves the reduced KKT
    system exactly and the result agrees with Clarabel to ~1e-12; ADMM alone stalls long
    before ``eps_abs = 1e-9`` on this problem (measured: 1e-7 needs ~1.3e5 iterations), so
    ``1e-5`` plus polishing is the accurate *and* fast setting (1e-6 already failed to
    converge in 20,000 iterations on a two-vehicle case whose cost is ~2e3, while 1e-5
    converged in 75 and polished to the exact solution).  Whether the polish succeeded is
    reported per solve (``polished``); an unpolished solution is accurate only to about
    ``eps_abs``.

    OSQP 1.x renamed ``polish`` to ``polishing``; the key is chosen from the installed
    version.
    """
    v = _version("osqp") or "1"
    polish_key = "polishing" if int(v.split(".")[0]) >= 1 else "polish"
    settings = {"eps_abs": eps_abs, "eps_rel": 0.0, polish_key: True, "max_iter": max_iter,
                "polish_refine_iter": 10, "verbose": False}
    if polish_key == "polishing":
        # OSQP 1.x also stops on an absolute duality gap; with eps_rel = 0 it cannot reach
        # 1e-5 on the expensive (far-from-optimal) candidates of a sweep.  Measured on
        # paper-2-poly, N = 100 sweep: 19 of 99 candidates failed and the sweep took 3.4 s
        # with the check, 1 failed and 0.54 s without; the polished optimum is identical
        # (KKT residuals are recomputed by the comparison, not taken from OSQP).
        settings["check_dualgap"] = False
    return settings


def clarabel_settings(tol: float = 1e-12) -> dict:
    """Clarabel: gap and feasibility tolerances tightened to ``tol``."""
    return {"tol_gap_abs": tol, "tol_gap_rel": tol, "tol_feas": tol, "tol_ktratio": 1e-10,
            "max_iter": 200, "verbose": False}


@dataclass(frozen=True)
class SolverBackend:
    """A QP solver reachable through cvxpy."""

    name: str
    cvxpy_name: str
    distribution: str
    settings: dict = field(default_factory=dict)

    @property
    def version(self) -> str | None:
        return _version(self.distribution)

    def require(self) -> None:
        if self.version is None:
            raise MissingDependencyError(
                f"solver {self.name!r} needs the package {self.distribution!r}: pip install {self.distribution}")


SOLVERS: dict[str, SolverBackend] = {
    "osqp": SolverBackend("osqp", "OSQP", "osqp", osqp_settings()),
    "clarabel": SolverBackend("clarabel", "CLARABEL", "clarabel", clarabel_settings()),
}


def get_solver(name: str, **overrides) -> SolverBackend:
    """Look a backend up by name, optionally overriding settings (e.g. a loose ``eps_abs``)."""
    try:
        backend = SOLVERS[name]
    except KeyError:
        raise ValueError(f"unknown solver {name!r}; choose from {', '.join(SOLVERS)}") from None
    backend.require()
    if overrides:
        backend = SolverBackend(backend.name, backend.cvxpy_name, backend.distribution,
                                {**backend.settings, **overrides})
    return backend
