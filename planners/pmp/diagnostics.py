r"""The diagnostics of a PMP plan (:class:`PMPDiagnostics`) and of a bounded PMP plan
(:class:`BoundedPMPDiagnostics`, SPEC §14).

A PMP plan is ``optimal`` only after its checks (:mod:`~iamp.planners.pmp.verify`) were
recomputed on the solution: the boundary conditions, the corner conditions
:math:`s(t_i) = c_i(t_i)`, the co-state jumps :math:`\lambda(t_i^+) - \lambda(t_i^-) = -\Phi_i`
and, at a searched contact time, the stationarity :math:`H(t_i^-) - H(t_i^+) = \dot c_i(t_i)\cdot\Phi_i`
(:attr:`~iamp.core.diagnostics.Diagnostics.checks`).
"""

from __future__ import annotations

from dataclasses import dataclass

from iamp.core.diagnostics import Diagnostics, Record


@dataclass(frozen=True)
class PMPDiagnostics(Diagnostics):
    r"""What the PMP planner reports (besides :class:`~iamp.core.diagnostics.Diagnostics`' fields).

    Attributes
    ----------
    search : mapping or None
        The contact-time search: ``{"method": ...}`` and the search's own record (candidates,
        roots, certificate); absent for given contact times.
    certified_global : bool or None
        Whether the search certified the contact times as the global minimiser of
        :math:`J(t_1, \dots, t_m)` (then the status is ``optimal``, otherwise ``local``).
    hamiltonian_jump_residuals : ndarray or None
        Per vehicle, :math:`|H(t_i^-) - H(t_i^+) - \dot c_i(t_i)\cdot\Phi_i|` in m²/s⁴ (only
        with ``diagnostics=True``).
    bounded : mapping or None
        With ``problem.limits``: ``box_active`` (whether the input box is active), and for a
        saturated plan its switching times [s] and Newton iterations.
    unbounded : mapping or None
        The unbounded plan a bounded plan started from: ``status``, ``cost`` [m²/s³],
        ``contact_times`` [s].
    limits : mapping or None
        Per given bound, ``{"peak", "bound", "ok"}`` on the exact peaks (SPEC §14).
    peaks : mapping or None
        The exact peaks of the trajectory (:func:`~iamp.planners.pmp.bounded.exact_peaks`).
    limits_violated : list of str or None
        The bounds the plan exceeds (status ``limits_violated``).
    limits_note : str or None
        Why an unbounded plan is the bounded optimum too.
    """

    search: Record | None = None
    certified_global: bool | None = None
    hamiltonian_jump_residuals: object | None = None
    bounded: Record | None = None
    unbounded: Record | None = None
    limits: Record | None = None
    peaks: object | None = None
    limits_violated: list[str] | None = None
    limits_note: str | None = None


@dataclass(frozen=True)
class BoundedPMPDiagnostics(PMPDiagnostics):
    r"""What the saturated (bounded) PMP reports (:mod:`~iamp.planners.pmp.bounded`).

    Attributes
    ----------
    evaluations : int or None
        Evaluations of :math:`J_b(t)` (one boundary-value solve each) in the contact-time search.
    global_certificate : mapping or None
        The interval certificate over the contact time(s): lower bounds of :math:`J_b` on
        every box against the best cost, with its relative tolerance ``rel``.
    global_note : str or None
        Why the plan is ``local`` (no certificate, or one that did not close).
    """

    evaluations: int | None = None
    global_certificate: Record | None = None
    global_note: str | None = None
