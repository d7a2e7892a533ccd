//! The dual projected conjugate gradient (FETI-C, founding paper §3.1): the projected CG of
//! [`crate::solvers::cpg`] applied to the dual of the Signorini problem (eq. 17.4),
//! `min_{w ≥ 0} ½ wᵀ F w + wᵀ q_F` with the flexibility `F = B K⁻¹ Bᵀ = M⁻¹`, whose gradient is
//! the gap `z = F w + q_F`. The unknowns are the contact forces; the gaps follow from them.
//! This is the bridge the paper draws: FETI-C's interface problem and a granular step
//! `u = W r + q` with `W = B M⁻¹ Bᵀ` are the same problem, solved by the same algorithm.

use super::Lcp;
use crate::solvers::{cpg, SolveReport, SolverOptions};

/// A dual solve, mapped back to the primal unknowns.
pub struct DualSolution {
    /// The solver's own report on the dual problem (its `r` are the forces `w`, its `u` the gaps `z`).
    pub report: SolveReport,
    /// Gaps after deformation.
    pub z: Vec<f64>,
    /// Contact forces.
    pub w: Vec<f64>,
}

/// Solves the dual `dual` (`z = F w + q_F`) from zero forces.
pub fn solve(dual: &Lcp, opts: &SolverOptions) -> DualSolution {
    let problem = dual.to_contact_problem();
    let report = cpg::solve(&problem, opts, vec![0.0; 2 * dual.n], false);
    let w = report.r.iter().step_by(2).copied().collect();
    let z = report.u.iter().step_by(2).copied().collect();
    DualSolution { report, z, w }
}

/// Gaps of a dual iterate (forces interleaved as the solver holds them).
pub fn gaps_of(dual: &Lcp, forces: &[f64]) -> Vec<f64> {
    let w: Vec<f64> = forces.iter().step_by(2).copied().collect();
    dual.complement(&w)
}
