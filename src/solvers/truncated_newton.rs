//! Truncated nonsmooth Newton with Gauss–Seidel smoothing for 2D Coulomb friction (after
//! TNNMG: Gräser, Sack & Sander 2009; Gräser & Kornhuber 2009), notes §11.1.
//!
//! Each iteration is one NLGS sweep, which alone converges (first order), followed by a Newton
//! correction of the Tresca problem that the sweep's normal impulses define (thresholds
//! `s = μ r_n` frozen): minimise the energy `½ rᵀ W r + qᵀ r` over the components the sweep left
//! free (normals of closed contacts, tangents of sticking ones) with every other component
//! truncated, `(W_II + δ D_I) c_I = −(W r + q)_I`, by a sparse Cholesky factorisation (faer)
//! refreshed only when the free set changes. The correction is projected on the Tresca box and
//! its step is the exact minimiser of the energy along it, so no step raises the energy of the
//! frozen problem; the next sweep brings the impulses back into the Coulomb cone and updates
//! the thresholds. Where the free set has settled, an iteration solves it exactly; where it has
//! not, the sweep does the work it would have done alone.

use super::conjugate_gradient::ConjugateGradient;
use super::monitor::Monitor;
use super::nlgs::forward_sweep;
use super::sparse_cholesky::PatternCholesky;
use super::{SolveReport, SolverKind, SolverOptions};
use crate::problem::residual::problem_error;
use crate::problem::{dot, BlockSparse, ContactProblem};

/// Regularisation of the free block relative to its diagonal: redundant contacts make `W_II`
/// singular. Raised ×100 while the factorisation fails.
const DELTA: f64 = 1e-8;

/// The Tresca system's matrix on `W`'s pattern: `W` on the free set, identity elsewhere.
struct TrescaSystem {
    cholesky: PatternCholesky,
    free: Vec<bool>,
    delta: f64,
}

impl TrescaSystem {
    fn new(w: &BlockSparse) -> Result<Self, String> {
        Ok(Self { cholesky: PatternCholesky::new(w)?, free: Vec::new(), delta: DELTA })
    }

    /// Factorises the system of the free set `free` (unless it is the one factorised already).
    fn factorise(&mut self, w: &BlockSparse, free: &[bool]) -> bool {
        if self.cholesky.is_factorised() && self.free == free {
            return true;
        }
        let entry = |row: usize, col: usize, value: f64, delta: f64| match (free[row] && free[col], row == col) {
            (true, true) => value * (1.0 + delta),
            (true, false) => value,
            (false, true) => 1.0,
            (false, false) => 0.0,
        };
        let factorised = self.cholesky.factorise_regularised(w, &mut self.delta, entry);
        if factorised {
            self.free = free.to_vec();
        }
        factorised
    }

    /// Solves in place (`rhs` zero on the truncated components).
    fn solve(&self, rhs: &mut [f64]) {
        self.cholesky.solve(rhs);
    }
}

/// Contacts above which the correction is solved by masked CG on `W` products instead of a
/// factorisation (memory and fill grow faster than the problem).
const DIRECT_LIMIT: usize = 30_000;
/// CG products per correction on the matrix-free path.
const CG_PRODUCTS: usize = 30;
/// With friction, a correction whose energy-minimising step is shorter than this is not taken:
/// the energy is only that of the frozen thresholds, and a short step says the free set is far
/// from the solution's (measured: frictional deposits give steps of 1e-7–1e-2 that raise the
/// error; on the 7,002-contact Siconos file steps in 0.05–0.5 keep it from 1e-10). Without
/// friction the energy is the problem's own, and every step that lowers it is taken.
const MIN_FRICTIONAL_STEP: f64 = 0.5;
/// Most sweeps between two tries after refused corrections (the interval doubles on each).
const MAX_INTERVAL: usize = 256;

/// With friction, a correction after which the next sweep leaves the error more than this many
/// times what it was before the correction is undone (impulses restored, next try postponed).
/// A correction may raise the error for a while and still pay (the 7,002-contact Siconos file
/// reaches 1e-8 through such ones; undoing any growth over 5× loses that), but one that multiplies
/// it by 15 sent a rotating-drum step from 1e-4 to 1e-3 for good (BENCHMARKS.md).
const ROLLBACK_GROWTH: f64 = 10.0;

/// How the correction's linear system is solved.
enum Correction {
    /// Sparse Cholesky on `W`'s pattern, refreshed when the free set changes.
    Direct(BlockSparse, Box<TrescaSystem>),
    /// CG on `W` products restricted to the free set.
    MatrixFree(Box<ConjugateGradient>),
}

/// Solves from `r` by truncated nonsmooth Newton: an NLGS sweep, then a Newton correction of the Tresca problem it defines (direct factorisation for small problems, CG beyond).
pub fn solve(p: &ContactProblem, opts: &SolverOptions, r: Vec<f64>) -> SolveReport {
    solve_with(p, opts, r, p.n_contacts() <= DIRECT_LIMIT)
}

/// [`solve`] with the correction factorised (`direct`) or by CG on `W` products.
fn solve_with(p: &ContactProblem, opts: &SolverOptions, mut r: Vec<f64>, direct: bool) -> SolveReport {
    let mut monitor = Monitor::new(p, opts, SolverKind::NlgsNewton, &r);
    let nc = p.n_contacts();
    let n = 2 * nc;
    let diag = p.w.diag_blocks();
    let mut correction_by = match direct {
        true => {
            let w = p.w.to_block_sparse();
            match TrescaSystem::new(&w) {
                Ok(system) => Correction::Direct(w, Box::new(system)),
                Err(_) => Correction::MatrixFree(Box::new(ConjugateGradient::new(n))),
            }
        }
        false => Correction::MatrixFree(Box::new(ConjugateGradient::new(n))),
    };
    let (mut u, mut correction, mut wd, mut rhs) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut free = vec![false; n];
    let mut thresholds = vec![0.0; nc];
    let (mut interval, mut next_try) = (1, 1);
    let frictionless = p.is_frictionless();
    // With friction, a taken correction is on probation for one sweep: (iteration it is judged
    // at, the error before it, the impulses before it).
    let mut probation: Option<(usize, f64, Vec<f64>)> = None;
    loop {
        forward_sweep(p, &diag, opts.omega, &mut r);
        monitor.w_products += 1;
        // Sweeps without a correction are watched as NLGS's are (light rule, check cadence).
        let due = probation.as_ref().map_or(next_try, |(at, _, _)| *at);
        if monitor.iteration() + 1 < due {
            if monitor.observe(&r, None) {
                break;
            }
            continue;
        }
        p.velocity_into(&r, &mut u);
        monitor.w_products += 1;
        if monitor.observe(&r, Some(&u)) {
            break;
        }
        // The monitor has just checked this iterate (it was handed `u`): its error, not a second pass.
        let error =
            if frictionless { 0.0 } else { monitor.checked_error().unwrap_or_else(|| problem_error(p, &r, &u)) };
        if let Some((_, before, saved)) = probation.take() {
            if error > ROLLBACK_GROWTH * before {
                // The sweeps after the correction did not recover it: back to before it.
                r.copy_from_slice(&saved);
                interval = (2 * interval).min(MAX_INTERVAL);
                next_try = monitor.iteration() + interval;
                continue;
            }
            interval = 1;
        }
        // The Tresca problem of thresholds s = μ r_n: normals of closed contacts and tangents
        // strictly inside their threshold are free; the rest stay where the sweep put them.
        for a in 0..nc {
            let (rn, rt) = (r[2 * a], r[2 * a + 1]);
            thresholds[a] = p.mu[a] * rn;
            free[2 * a] = rn > 0.0;
            free[2 * a + 1] = rn > 0.0 && rt.abs() < thresholds[a] * (1.0 - 1e-12);
        }
        for i in 0..n {
            rhs[i] = if free[i] { -u[i] } else { 0.0 };
        }
        let solved = match &mut correction_by {
            Correction::Direct(w, system) => {
                correction.copy_from_slice(&rhs);
                system.factorise(w, &free) && {
                    system.solve(&mut correction);
                    true
                }
            }
            Correction::MatrixFree(cg) => {
                // CG on P W P c = rhs (P the free mask) from c = 0.
                correction.iter_mut().for_each(|c| *c = 0.0);
                let masked = |v: &[f64], out: &mut [f64]| {
                    p.w.apply(v, out);
                    out.iter_mut().zip(&free).filter(|(_, f)| !**f).for_each(|(o, _)| *o = 0.0);
                };
                monitor.w_products += cg.solve(masked, None, &rhs, &mut correction, 1e-10, CG_PRODUCTS);
                true
            }
        };
        // Projected on the box (r_n ≥ 0, |r_t| ≤ s): d = P(r + c) − r, and the step that
        // minimises the energy along d, which d must decrease.
        let mut step = 0.0;
        if solved {
            for a in 0..nc {
                let (rn, rt, s) = (r[2 * a], r[2 * a + 1], thresholds[a]);
                correction[2 * a] = (rn + correction[2 * a]).max(0.0) - rn;
                correction[2 * a + 1] = (rt + correction[2 * a + 1]).clamp(-s, s) - rt;
            }
            p.w.apply(&correction, &mut wd);
            monitor.w_products += 1;
            let (slope, curvature) = (dot(&u, &correction), dot(&correction, &wd));
            if slope < 0.0 && curvature > 0.0 {
                step = (-slope / curvature).min(1.0);
            }
        }
        let taken = step > 0.0 && (frictionless || step >= MIN_FRICTIONAL_STEP);
        if taken && !frictionless {
            probation = Some((monitor.iteration() + 1, error, r.clone()));
        }
        if taken {
            for i in 0..n {
                r[i] += step * correction[i];
            }
        }
        if probation.is_none() {
            interval = if taken { 1 } else { (2 * interval).min(MAX_INTERVAL) };
        }
        next_try = monitor.iteration() + interval;
    }
    monitor.finish(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::generate::lattice_packing;

    /// Both ways of solving the correction reach 1e-10 on a lattice packing (redundant contacts:
    /// `W_II` singular), in fewer iterations than NLGS alone needs (far fewer when factorised).
    #[test]
    fn factorised_and_matrix_free_corrections_both_converge_on_a_lattice() {
        for mu in [0.0, 0.3] {
            let p = lattice_packing(16, 8, mu, 3);
            let opts = SolverOptions { tol: 1e-10, max_iter: 20_000, ..Default::default() };
            let zero = vec![0.0; 2 * p.n_contacts()];
            let nlgs = super::super::nlgs::solve(&p, &opts, zero.clone());
            for direct in [true, false] {
                let rep = solve_with(&p, &opts, zero.clone(), direct);
                assert!(rep.converged && rep.error <= 1e-10, "mu {mu} direct {direct}: {:.2e}", rep.error);
                // Measured: 6 / 13 against 1,841 without friction, 86 / 712 against 1,395 with.
                let factor = match (mu == 0.0, direct) {
                    (true, _) => 20,
                    (false, true) => 5,
                    (false, false) => 1,
                };
                assert!(
                    factor * rep.iterations < nlgs.iterations,
                    "mu {mu} direct {direct}: {} iterations against NLGS's {}",
                    rep.iterations,
                    nlgs.iterations
                );
            }
        }
    }
}
