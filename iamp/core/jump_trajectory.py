r"""The trajectory of the paper's solution form (SPEC §2), evaluated by the core.

Per axis (column 0 = x, 1 = y) the input is linear with a kink at every contact time,
:math:`u(t) = a + bt - \sum_i \Phi_i (t-t_i)_+`; the co-states are
:math:`p_1 = b - \sum_i \Phi_{i,x} H(t-t_i)`, :math:`p_2 = -a - bt + \sum_i \Phi_{i,x}(t-t_i)_+`
(``p3``, ``p4`` likewise), and the positions and speeds are the input integrated twice from the
problem's initial state.

:class:`JumpTrajectory` holds only numbers (``a``, ``b``, the jumps ``Φ``, the contact times and
the problem) and evaluates them here, in :mod:`iamp.core`: the PMP's solution
(:class:`iamp.planners.pmp.solution.PMPSolution`) is one, so a plan's safety report, peaks and
samples evaluate its trajectory without calling back into the planner (``scripts/walk.py``:
no upward call).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.core.problem import Problem

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class JumpSamples:
    """The trajectory at the times ``t`` and its one-sided values at the contact times, from one
    call of :meth:`JumpTrajectory.samples`.

    Attributes
    ----------
    states, inputs, costates : ndarray
        At ``t``: ``(len(t), 4)``, ``(len(t), 2)``, ``(len(t), 4)`` (co-states: right limits).
    costates_left : ndarray (m, 4)
        The left limits of the co-states at the contact times.
    h_left, h_right : ndarray (m,)
        The Hamiltonian's left and right limits at the contact times.
    """

    states: FloatArray
    inputs: FloatArray
    costates: FloatArray
    costates_left: FloatArray
    h_left: FloatArray
    h_right: FloatArray


class JumpTrajectory:
    """The solution form's trajectory (module docstring); a subclass provides the attributes."""

    problem: Problem
    contact_times: FloatArray
    a: FloatArray
    b: FloatArray
    jumps: FloatArray

    def _ramps(self, t: FloatArray, power: int, side: str = "right") -> FloatArray:
        d = t[:, None] - self.contact_times[None, :]
        if power == 0:
            return (d > 0).astype(float) if side == "left" else (d >= 0).astype(float)
        out: FloatArray = np.maximum(d, 0.0) ** power
        return out

    def inputs(self, t: Any) -> FloatArray:
        """``(u_x, u_y)`` at times ``t`` → shape ``(len(t), 2)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out: FloatArray = self.a[None, :] + self.b[None, :] * t[:, None] - self._ramps(t, 1) @ self.jumps
        return out

    def states(self, t: Any) -> FloatArray:
        """``(s_x, v_x, s_y, v_y)`` at times ``t`` → shape ``(len(t), 4)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ego = self.problem.ego
        s0 = np.array([ego.x0, ego.y0])
        v0 = np.array([ego.vx0, ego.vy0])
        tt = t[:, None]
        v = v0 + self.a * tt + self.b * tt**2 / 2 - self._ramps(t, 2) @ self.jumps / 2
        s = s0 + v0 * tt + self.a * tt**2 / 2 + self.b * tt**3 / 6 - self._ramps(t, 3) @ self.jumps / 6
        return np.stack([s[:, 0], v[:, 0], s[:, 1], v[:, 1]], axis=1)

    def costates(self, t: Any, side: str = "right") -> FloatArray:
        """``(p1, p2, p3, p4)`` at ``t``; ``side`` picks the one-sided limit at a contact time.
        ``p1, p3`` from the jump rule; ``p2, p4`` by integrating ``ṗ2 = −p1`` from
        ``p2(0) = −a`` (not from ``u``), so ``∂H/∂u = u + p2`` is a real check."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        p13 = self.b[None, :] - self._ramps(t, 0, side) @ self.jumps
        p24 = -self.a[None, :] - self.b[None, :] * t[:, None] + self._ramps(t, 1) @ self.jumps
        return np.stack([p13[:, 0], p24[:, 0], p13[:, 1], p24[:, 1]], axis=1)

    def hamiltonian(self, t: Any, side: str = "right") -> FloatArray:
        """``H = ½|u|² + p1 v_x + p2 u_x + p3 v_y + p4 u_y`` (one-sided at contact times)."""
        X = self.states(t)
        U = self.inputs(t)
        p = self.costates(t, side)
        out: FloatArray = (0.5 * np.sum(U**2, axis=1) + p[:, 0] * X[:, 1] + p[:, 1] * U[:, 0]
                           + p[:, 2] * X[:, 3] + p[:, 3] * U[:, 1])
        return out

    def samples(self, t: Any) -> JumpSamples:
        """States, inputs and co-states at ``t`` and the one-sided co-states and Hamiltonians at
        the contact times, in one call (the numbers of :meth:`states`, :meth:`inputs`,
        :meth:`costates` and :meth:`hamiltonian`: every row is computed on its own)."""
        tc = self.contact_times
        return JumpSamples(self.states(t), self.inputs(t), self.costates(t), self.costates(tc, "left"),
                           self.hamiltonian(tc, "left"), self.hamiltonian(tc, "right"))
