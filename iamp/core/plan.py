"""Planner results shared by every planner (PMP and QP).

A :class:`Plan` carries the problem it came from, the status, the cost
``J = ½∫(u_x² + u_y²)dt`` evaluated on the planner's own solution, the contact times, the
jumps (``Φ_i`` for the PMP, the multipliers ``ν_i`` for the QP — SPEC §3.3), and a
trajectory that can be evaluated at any time.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from iamp.core.problem import Problem

from iamp.core.status import OPTIMAL as STATUS_OPTIMAL  # noqa: F401 - re-exported


@dataclass
class Plan:
    """The outcome of one plan.

    Attributes
    ----------
    problem : Problem
        The problem that was solved (with the exact polynomials used).
    planner : str
        ``"pmp"`` or ``"qp"``.
    status : str
        ``"optimal"`` or the solver's failure status.
    cost : float or None
        ``J`` on the planner's own solution; ``None`` unless ``status == "optimal"``.
    contact_times : ndarray, shape (m,)
        ``t_i`` in the order of ``problem.vehicles``.
    jumps : ndarray, shape (m, 2)
        ``(Φ_i,x, Φ_i,y)`` (PMP) or ``(ν_i,x, ν_i,y)`` (QP).
    trajectory : object
        Has ``states(t) -> (len(t), 4)`` and ``inputs(t) -> (len(t), 2)``; states are
        ``(s_x, v_x, s_y, v_y)``.
    solve_time_s : float
        Wall time of the whole plan (including the contact-time search).
    residuals : dict
        Max-abs residual of every condition the planner solved or satisfied.
    solver, hold, steps : optional
        QP configuration (``None`` for the PMP; ``steps`` is the output sampling).
    info : dict
        Planner-specific extras (e.g. the sweep's candidate costs).
    """

    problem: Problem
    planner: str
    status: str
    cost: float | None
    contact_times: np.ndarray
    jumps: np.ndarray
    trajectory: object
    solve_time_s: float = 0.0
    residuals: dict = field(default_factory=dict)
    solver: str | None = None
    hold: str | None = None
    steps: int | None = None
    info: dict = field(default_factory=dict)

    def is_optimal(self) -> bool:
        return self.status == STATUS_OPTIMAL

    def sample(self, steps: int) -> dict:
        """Trajectory sampled at ``t_k = k·t_f/N``, ``k = 0..N`` (SPEC §5)."""
        t = np.linspace(0.0, self.problem.tf, int(steps) + 1)
        X = self.trajectory.states(t)
        U = self.trajectory.inputs(t)
        return {"t": t, "x": X[:, 0], "y": X[:, 2], "vx": X[:, 1], "vy": X[:, 3], "ax": U[:, 0], "ay": U[:, 1]}

    def corner_residual(self) -> float:
        """max |s(t_i) − corner_i(t_i)| over vehicles and axes."""
        X = self.trajectory.states(self.contact_times)
        C = self.problem.corners(self.contact_times)
        return float(np.max(np.abs(X[:, [0, 2]] - C)))

    def boundary_residual(self) -> float:
        """max |state(0) − x0|, |state(t_f) − x_f|."""
        X = self.trajectory.states(np.array([0.0, self.problem.tf]))
        return float(max(np.max(np.abs(X[0] - self.problem.ego.initial)),
                         np.max(np.abs(X[1] - self.problem.ego.final))))

    def to_json(self, scenario: str, steps: int) -> dict:
        """The SPEC §5 JSON object."""
        ok = self.is_optimal()
        traj = self.sample(steps) if ok else {k: [] for k in ("t", "x", "y", "vx", "vy", "ax", "ay")}
        return {
            "scenario": scenario,
            "planner": self.planner,
            "solver": self.solver,
            "hold": self.hold,
            "steps": int(steps),
            "status": self.status,
            "cost": float(self.cost) if ok else None,
            "contact_times": [float(t) for t in self.contact_times] if ok else [],
            "jumps": [[float(j[0]), float(j[1])] for j in self.jumps] if ok else [],
            "solve_time_s": float(self.solve_time_s),
            "trajectory": {k: [float(x) for x in np.asarray(v)] for k, v in traj.items()},
        }
