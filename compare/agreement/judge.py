r"""Do the PMP and the QP baselines agree on one problem?  A comparison that can fail.

:func:`compare_problem` runs the PMP planner and every requested QP configuration
(:class:`QPConfig`: OSQP or Clarabel, FOH or ZOH, ``N`` steps, through cvxpy or the native
path, e.g. ``qp-clarabel-foh-100``) on the **same** :class:`~iamp.core.problem.Problem`
object, records a fingerprint of the problem each planner reports having solved (the exact
``x_poly`` coefficients, :func:`problem_fingerprint`), and judges every pair.  This module
is the driver and states the rules; the pieces live in one module per concern:

* :mod:`iamp.comparison.agreement.verdict` — checks ``value ≤ limit`` into a verdict, rules 0–1;
* :mod:`iamp.comparison.agreement.pmp_qp` — :func:`compare_pmp_qp`, rules 2–7;
* :mod:`iamp.comparison.agreement.qp_qp` — :func:`compare_qp_qp`, pairs of QP runs;
* :mod:`iamp.comparison.agreement.gaps` — run-vs-run gaps and ``at_same_contact_times`` (SPEC §5b);
* :mod:`iamp.comparison.agreement.references` — the exact references below;
* :mod:`iamp.comparison.agreement.signs` — what the sign of a jump means.

References
----------
A QP is never compared with the continuous optimum alone: the discretisation has an exact
reference at the QP's *own* contact times ``t_Q`` (grid nodes) —

* **FOH** is exact (SPEC §3.1): its reference is the PMP's fixed-time solution at ``t_Q``
  (:func:`iamp.planners.pmp.planner.solve_fixed_times`), and on the grid the PMP's value function
  :math:`J(t)` (:class:`iamp.planners.pmp.planner.ValueFunction`) is the exact sweep cost;
* **ZOH** restricts the input to piecewise constants; with the contact times on nodes the
  QP is the moment problem :math:`\min \tfrac12\int u^2` s.t. :math:`\int \varphi_j u = c_j`
  over piecewise-constant ``u``, with :math:`\varphi \in \{1,\ t_f-\tau,\ (t_i-\tau)_+\}`
  (final speed, final position, contact positions).  Its solution is
  :math:`u = \sum_j \mu_j \Pi_h\varphi_j` with :math:`(G - E)\mu = c`, where
  :math:`G_{jk} = \int\varphi_j\varphi_k` is the continuous (PMP) Gram matrix and
  :math:`E_{jk} = \int(\varphi_j - \Pi_h\varphi_j)(\varphi_k - \Pi_h\varphi_k)
  = \sum_k \tfrac{h_k^3}{12}\varphi_j'\varphi_k'` (each :math:`\varphi` is linear on every
  interval).  So :math:`J_{ZOH} = \tfrac12\sum_{axes} c^\top (G-E)^{-1} c` exactly, the
  multipliers are :math:`\nu_i = -\mu_i`, and (with :math:`\lambda = G^{-1}c`,
  the PMP's input :math:`u^* = \sum\lambda_j\varphi_j`, and
  :math:`\rho = \lambda_{\max}(G^{-1}E) = O(h^2)`)

  .. math::  \Delta_1 \le J_{ZOH} - J_{PMP} \le \frac{\Delta_1}{1-\rho},\qquad
             \Delta_1 = \tfrac12\lambda^\top E\lambda = \frac{h^2}{24}\int_0^{t_f}|\dot u^*|^2\,dt

  (uniform grid) — the ``O(h²)`` gap of SPEC §3.2 with its constant and a rigorous bracket
  (:func:`zoh_reference`).

Verdict rules (pair ``pmp`` / QP run; every rule must pass for ``agree``)
-------------------------------------------------------------------------
(:func:`compare_pmp_qp`; the limits written out in :mod:`iamp.comparison.agreement.pmp_qp`.)

0. *Same problem*: both planners report the identical problem (fingerprints of the
   ``x_poly`` coefficients and of all other data are equal).
1. *Status*: both runs are ``optimal``.  The PMP's own conditions hold: every residual of
   :meth:`~iamp.planners.pmp.planner.PMPSolution.residuals` ``≤ pmp_condition_residual·scale`` and the
   Hamiltonian-jump residual at ``t*`` ``≤ pmp_hjump_at_optimum·max(1, J*)``.
2. *Solver precision at the QP's contact times* ``t_Q``: cost, nodal states and inputs, and
   multipliers ``ν`` match the exact reference (FOH: the PMP at ``t_Q``; ZOH: the closed form)
   within the solver's ``cmp_cost_rel_*``, ``cmp_state_rel_*``, ``cmp_jump_rel_*``.
3. *KKT*: primal, dual and duality-gap residuals recomputed from the QP matrices and the
   returned primal/dual solution (:func:`iamp.planners.qp.backends.kkt_residuals`; never the
   solver's own report) are below ``cmp_kkt_rel_*``.
4. *Constraints*: the QP trajectory's boundary and collision residuals are below
   ``cmp_residual_rel_*``.
5. *Search* (grid sweeps): the QP's candidate is the grid optimum of the exact sweep cost —
   ``J_ref(t_Q) ≤ min_grid J_ref + tol`` (ties within solver precision allowed).  For FOH this
   is "the sweep's best equals the PMP's global optimum restricted to the grid" (SPEC §3.4).
6. *Continuous optimum*: ``J_PMP(t_Q) ≥ J* − tol`` (the PMP's ``t*`` is a lower bound over the
   grid; this fails if the PMP missed the global minimum) and ``J_QP ≤ min J_ref`` over the
   ``2^m`` grid candidates bracketing ``t*`` ``+ tol`` (the sweep saw them).  The contact-time
   gap to ``t*`` is expected ``≤ h`` (not ``h/2``: of the two nodes bracketing ``t*`` the
   cheaper need not be the nearer when ``J`` is asymmetric); a larger gap with rule 6's cost
   bounds satisfied is a near-tie between basins and is reported as a note, not a failure.
   ``refine`` runs instead need, for FOH, ``|J_QP − J*| ≤ refine_cost_rel·J*``.
7. *ZOH only*: ``J_QP ≥ J_PMP(t_Q)`` and ``J_QP − J_PMP(t_Q)`` inside the bracket above.

Pairs of QP runs (:func:`compare_qp_qp`; same hold and ``N``, e.g. OSQP vs Clarabel, native
vs cvxpy): rules 0–1, rule 3 for each run at its own solver's tolerance, the same grid contact
times (or equal costs within precision: a tie), and cost, states and multipliers equal within
the looser solver's tolerances.

Signs (SPEC §2, identity 4) are reported for the PMP's ``Φ_i`` and every QP's ``ν_i`` through
:mod:`iamp.comparison.agreement.signs`.  That module derives the meaning from
:math:`\partial J/\partial \text{corner} = -\Phi`: ``Φ_x > 0`` means the unconstrained ego would
be *ahead of* the corner.  This differs from the parenthetical in SPEC §2.4 ("for a ``front``
corner, ``Φ_x > 0`` means the ego would otherwise be behind the corner"); the derivation is
kept (it is what identity 2 implies and what the numbers show: in ``paper-1-poly`` the
unconstrained ego is 2.8 m ahead of the corner at ``t*`` and ``Φ_x = +7.4``).

Headline numbers (SPEC §5b) compare the two runs **as they came out**, each at its own contact
times: ``cost_rel_gap = (J_QP − J_PMP)/|J_PMP|`` (``J_PMP`` at ``t*``), ``contact_time_gap =
max|t_Q − t*|``, ``state_sup_gap`` the sup-norm of the nodal state difference between the two
trajectories on the QP's grid, ``jump_gap = max|ν − Φ(t*)|`` (absolute).  The identity at the
QP's own contact times ``t_Q`` (the PMP re-solved there: FOH exact to solver precision, ZOH the
``O(h²)`` excess) goes under ``at_same_contact_times`` with the same four gaps and
``contact_time_gap_to_grid_optimum = max|t_Q − t_grid*|`` (:mod:`iamp.comparison.agreement.gaps`).
``verdict_basis`` says what the verdict judged.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from iamp.comparison.timing import QPBreakdown
from iamp.comparison.trajectories import hamiltonian_jump_residuals
from iamp.core.problem import Problem

from .bounded_pair import compare_bounded_pmp_qp
from .fingerprints import problem_fingerprint, x_poly_fingerprint
from .pmp_qp import compare_pmp_qp
from .qp_qp import compare_qp_qp
from .records import PairJSON
from .runs import QPConfig, Run, default_configs, run_pmp, run_qp
from .signs import sign_entry
from .verdict import VERDICT_AGREE, VERDICT_DISAGREE

__all__ = ["VERDICT_AGREE", "VERDICT_DISAGREE", "Comparison", "ProblemComparison", "QPConfig", "Run", "compare_pmp_qp",
           "compare_problem", "compare_qp_qp", "default_configs", "run_pmp", "run_qp"]

# --------------------------------------------------------------------------------------
# One problem, every configuration
# --------------------------------------------------------------------------------------


@dataclass
class ProblemComparison:
    """Runs and verdicts of one problem (:func:`compare_problem`)."""

    name: str
    problem: Problem
    runs: list[Run]
    agreement: list[PairJSON]
    #: ``iamp compare`` adds ``"breakdown"``: :func:`iamp.comparison.timing.qp_breakdown` per configuration
    timing: dict[str, list[QPBreakdown]] = field(default_factory=dict)
    #: configurations left out, with the reason (ZOH under a jerk bound)
    skipped: list[str] = field(default_factory=list)

    @property
    def all_agree(self) -> bool:
        """Every pair's verdict is ``agree``."""
        return all(a["verdict"] == VERDICT_AGREE for a in self.agreement)

    @property
    def any_failed(self) -> bool:
        """Some run did not finish with a verified optimum."""
        return any(not r.ok for r in self.runs)

    def run(self, label: str) -> Run:
        """The run with this label."""
        for r in self.runs:
            if r.label == label:
                return r
        raise KeyError(label)

    def pair(self, a: str, b: str) -> PairJSON:
        """The verdict of the pair ``(a, b)``."""
        for p in self.agreement:
            if p["a"] == a and p["b"] == b:
                return p
        raise KeyError((a, b))

    def to_json(self) -> dict[str, Any]:
        """One entry of SPEC §5b's ``scenarios``."""
        pmp = next((r for r in self.runs if r.planner == "pmp"), None)
        out: dict[str, Any] = {"name": self.name, "m": self.problem.m,
               "x_poly": [list(map(float, v.x_poly)) for v in self.problem.vehicles],
               "x_poly_sha256": x_poly_fingerprint(self.problem),
               "problem_sha256": problem_fingerprint(self.problem),
               "runs": [r.to_json() for r in self.runs],
               "agreement": self.agreement}
        if pmp is not None and pmp.ok:
            out["pmp"] = {
                "signs": [sign_entry(v, j[0]) for v, j in zip(self.problem.vehicles, pmp.result.jumps)],
                "hamiltonian_jump_residuals": [float(r) for r in hamiltonian_jump_residuals(pmp.result)],
            }
        lim = self.problem.limits
        if lim is not None and not lim.empty:  # only then: the unbounded JSON is what it was
            out["limits"] = {k: list(v) if isinstance(v, tuple) else v for k, v in lim.given().items()}
        if self.timing:
            out["timing"] = self.timing
        if self.skipped:
            out["skipped"] = list(self.skipped)
        return out


@dataclass
class Comparison:
    """What :func:`iamp.compare` returns: the comparison of one or more problems.

    For each problem, the PMP and every QP configuration planned the same problem object and
    every pair was judged by the rules of this module (``agree`` only when every rule passes).

    Attributes
    ----------
    scenarios : list of ProblemComparison
        One entry per problem: its ``runs`` (:class:`~iamp.comparison.agreement.runs.Run`,
        with the plan and its timing) and its ``agreement`` (one verdict per pair, with the
        reasons).
    all_agree : bool
        Every pair of every problem agrees.
    any_failed : bool
        Some run of some problem did not finish with a verified optimum.

    See Also
    --------
    iamp.compare : Makes one for a single problem.

    Examples
    --------
    >>> import iamp
    >>> comparison = iamp.compare(iamp.load_scenario("paper-1-poly"), steps=(20,),
    ...                           solvers=("clarabel",), holds=("foh",), repeats=1)
    >>> [(p["a"], p["b"], p["verdict"]) for p in comparison.scenarios[0].agreement]
    [('pmp', 'qp-clarabel-foh-20', 'agree')]
    """

    scenarios: list[ProblemComparison]

    @property
    def all_agree(self) -> bool:
        """Every pair of every problem agrees."""
        return all(s.all_agree for s in self.scenarios)

    @property
    def any_failed(self) -> bool:
        """Some run of some problem did not finish with a verified optimum."""
        return any(s.any_failed for s in self.scenarios)

    def to_json(self) -> dict[str, Any]:
        """The comparison as the object of ``iamp compare --json`` (SPEC §5b).

        Returns
        -------
        dict
            ``{"scenarios": [...]}``, one entry per problem
            (:meth:`ProblemComparison.to_json`: ``name``, ``m``, the ``x_poly`` and problem
            fingerprints, ``runs``, ``agreement``, and the PMP's jump ``signs``).
        """
        return {"scenarios": [s.to_json() for s in self.scenarios]}


def compare_problem(problem: Problem, configs: Iterable[QPConfig], name: str | None = None, repeats: int = 3,
                    pmp_repeats: int | None = None, budget_s: float = 30.0,
                    problems: dict[str, Problem] | None = None,
                    qp_pairs: bool = True, warmup: int = 1,
                    progress: Callable[[int, int], None] | None = None) -> ProblemComparison:
    """Run the PMP and every QP configuration on ``problem`` and judge every pair.

    Parameters
    ----------
    problem : Problem
        Given, as the same object, to every planner.
    configs : iterable of QPConfig
    repeats : int
        Timed full plans per QP configuration (after one warm-up; see
        :func:`iamp.comparison.timing.measure` for ``budget_s``).
    pmp_repeats : int, optional
        Timed PMP plans (default ``max(20, 10·repeats)``; the PMP is cheap).
    warmup : int
        Untimed plans before the timed ones (each configuration).
    problems : dict, optional
        ``label → Problem`` to hand a *different* problem to one planner (used to test that
        the identical-problem check catches it).
    qp_pairs : bool
        Also judge OSQP/Clarabel and native/cvxpy pairs of the same hold and ``N``.
    progress : callable, optional
        Called as ``progress(done, total)`` after each run (the PMP and every configuration).
    """
    problems = problems or {}
    configs = list(configs)
    skipped: list[str] = []
    if problem.limits is not None and problem.limits.jerk is not None:  # ZOH's input jumps at every node
        from iamp.planners.qp.limits import check_hold

        zoh = [c for c in configs if c.hold == "zoh"]
        if len(zoh) == len(configs) and zoh:
            check_hold(problem.limits, "zoh")  # the one refusal (ScenarioError naming limits.jerk)
        configs = [c for c in configs if c.hold != "zoh"]
        skipped = [f"{c.label}: a jerk bound needs a continuous input (ZOH's jumps at every node)" for c in zoh]
    runs = [run_pmp(problems.get("pmp", problem), pmp_repeats or max(20, 10 * repeats), warmup=max(warmup, 1),
                    budget_s=budget_s)]
    if progress is not None:
        progress(1, len(configs) + 1)
    for k, cfg in enumerate(configs):
        runs.append(run_qp(problems.get(cfg.label, problem), cfg, repeats=repeats, warmup=warmup, budget_s=budget_s))
        if progress is not None:
            progress(k + 2, len(configs) + 1)
    pmp = runs[0]
    tables: dict[tuple[int, str], tuple[NDArray[np.int_], NDArray[np.float64]]] = {}
    if problem.limits is not None and not problem.limits.empty:  # SPEC §14: the bounded rules B0-B6
        agreement = [compare_bounded_pmp_qp(problem, pmp, r) for r in runs[1:]]
    else:
        agreement = [compare_pmp_qp(problem, pmp, r, tables) for r in runs[1:]]
    if qp_pairs:
        qps = runs[1:]
        for a, b in itertools.combinations(qps, 2):
            ca, cb = a.config, b.config
            if ca is not None and cb is not None and (ca.hold, ca.steps, ca.contact) == (cb.hold, cb.steps, cb.contact):
                agreement.append(compare_qp_qp(problem, a, b))
    return ProblemComparison(name or problem.name, problem, runs, agreement, skipped=skipped)
