"""Every tolerance the tests and the comparison use, in one table.

Relative tolerances compare against ``max(1, |reference|)`` unless said otherwise.  Each
entry says what it bounds and why it is this size.
"""

TOLERANCES: dict[str, float] = {
    # PMP: conditions solved by a dense linear solve -> machine precision times the scale.
    "pmp_condition_residual": 1e-9,
    # Hamiltonian-jump residual at t* (Newton/root polish stops at ~1e-11 relative to J).
    "pmp_hjump_at_optimum": 1e-7,
    # Central finite differences of J (step 1e-5 s) against r = dJ/dt.
    "fd_gradient_rel": 1e-5,
    # FOH QP vs PMP at the same grid contact times (SPEC §3.1).
    "foh_clarabel_cost_rel": 1e-9,
    "foh_osqp_cost_rel": 1e-6,
    "foh_clarabel_state_abs": 1e-7,
    "foh_osqp_state_abs": 1e-4,
    # QP multiplier nu vs PMP jump Phi (SPEC §3.3), relative to max(1, |Phi|).
    "dual_clarabel_rel": 1e-6,
    "dual_osqp_rel": 1e-4,
    # ZOH gap ratio per halving of h (SPEC §3.2: ~4).
    "zoh_ratio_low": 3.5,
    "zoh_ratio_high": 4.5,
    # Agreement with an independent solution (issue: done means).
    "independent_cost_rel": 1e-6,
    "independent_contact_time_abs": 1e-4,
    "independent_jump_rel": 1e-4,
    # QP contact search against the continuous optimum.
    "refine_cost_rel": 1e-6,
    "sweep_osqp_cost_rel": 1e-5,
}


# ------------------------------------------------------------------------------------------
# compare/agreement.py — the verdict rules of `iamp compare` (see that module's docstring).
# "_rel" entries are relative to the scale named in the rule; one pair of values per solver:
# what the configured settings reach with ample margin (measured ~1e-12 for Clarabel and for
# a polished OSQP solve), while a loose OSQP (eps_abs 1e-2, no polish) misses them by orders.
# ------------------------------------------------------------------------------------------
TOLERANCES.update({
    # QP cost vs its exact reference at the QP's own contact times, relative to |J_ref|.
    "cmp_cost_rel_clarabel": 1e-9,
    "cmp_cost_rel_osqp": 1e-6,
    # nodal states and inputs vs the reference, relative to max(1, max|reference value|).
    "cmp_state_rel_clarabel": 1e-8,
    "cmp_state_rel_osqp": 1e-6,
    # multipliers nu vs the reference jumps, relative to max(1, max|reference jump|).
    "cmp_jump_rel_clarabel": 1e-6,
    "cmp_jump_rel_osqp": 1e-4,
    # KKT residuals recomputed from the QP data (primal, dual, gap; each relative, see
    # iamp.planners.qp.backends.kkt_residuals).
    "cmp_kkt_rel_clarabel": 1e-9,
    "cmp_kkt_rel_osqp": 1e-7,
    # boundary and collision-constraint residuals of a QP trajectory, relative to
    # max(1, max|boundary state|).
    "cmp_residual_rel_clarabel": 1e-9,
    "cmp_residual_rel_osqp": 1e-7,
    # grid contact times of two QP runs on the same grid are the same node: |dt| / tf.
    "cmp_node_time_rel": 1e-12,
})

# ------------------------------------------------------------------------------------------
# PMP self-verification (iamp.planners.pmp.verify): every check is dimensionless, in the
# units t_f (time) and L (the problem's largest position, iamp.planners.pmp.scale).
# ------------------------------------------------------------------------------------------
TOLERANCES.update({
    # trailing x_poly terms with |c_k| t_f^k below this fraction of the largest term are
    # dropped: 100x below the rounding error (1.1e-16) of evaluating the kept terms.
    "pmp_poly_negligible_rel": 1e-18,
    # backward error |Mz - r| / (|M||z| + |r|) of the jump system: LU's bound is
    # ~ n*eps*growth ~ 1e-14 for m <= 16; 100x margin.
    "pmp_linear_system_rel": 1e-12,
    # boundary, corner, H-minimisation and co-state-jump residuals in scaled units: the
    # piecewise cubics carry ~cond(M)*eps, cond up to ~1e5 for close contact times.
    "pmp_scaled_residual": 1e-9,
    # Hamiltonian-jump residual r_i over the size of its terms |Phi_x|(|v_x|+|xdot_s|)+|Phi_y||v_y|:
    # the root polish reaches ~1e-13; a double root (J'' = 0) only ~sqrt(eps).
    "pmp_hjump_rel": 1e-7,
    # closed-form J(t*) vs the exact integral of |u|^2 of the trajectory (both sums of
    # positive terms, ~1e-15 apart): catches a jump/coefficient mix-up.
    "pmp_cost_consistency_rel": 1e-10,
    # branch and bound: a box is discarded when its lower bound on J is within this
    # fraction of the best J found; OPTIMAL then means global to this relative accuracy.
    "pmp_global_certificate_rel": 1e-9,
})


# ------------------------------------------------------------------------------------------
# Bounded PMP (iamp.planners.pmp.bounded, SPEC §14), dimensionless per axis (time over t_f,
# lengths over the axis' data scale, inputs over that scale / t_f²).
# ------------------------------------------------------------------------------------------
TOLERANCES.update({
    # boundary, corner, saturation law, switching times, box, H constant between contact
    # times: the semi-smooth Newton stops at 1e-12 and the knots integrate exactly; 1000x margin.
    "pmp_bounded_residual": 1e-9,
    # primal cost ½∫|u|² against the dual value D(λ) (relative to J): = λᵀF, ~1e-12 at the
    # Newton tolerance.
    "pmp_bounded_gap_rel": 1e-9,
    # a physical bound holds when the exact peak is within this fraction of max(1, |bound|)
    # beyond it (rounding of the peak evaluation only).
    "limits_bound_rel": 1e-9,
})


# ------------------------------------------------------------------------------------------
# compare/agreement/bounded_pair.py — a pmp / QP pair of a problem with [limits] (rule B6):
# the QP's excess over the bounded PMP at the same contact times, J_QP - J_b(t_Q), within a
# derived two-sided bracket 0 <= J_QP - J_b(t_Q) <= D for both holds (the ZOH and FOH rows are
# an exact restriction of the continuous problem; D from a plan of the QP built from the PMP's
# input, bounded_pair.upper_plan), judged with the cmp_cost_rel_* limits: no tolerance of its
# own (the fitted cmp_bounded_zoh_ratio_low/high and cmp_bounded_foh_ratio are removed).
# ------------------------------------------------------------------------------------------


def tol(name: str) -> float:
    """Look up a tolerance by name (KeyError names the missing entry)."""
    return TOLERANCES[name]
