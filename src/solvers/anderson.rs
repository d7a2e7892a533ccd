//! NLGS with Anderson acceleration (Walker & Ni 2011, type II), `--anderson m`: the forward sweep
//! is a fixed-point map `r ↦ G(r)`; the next iterate is the combination of the last `m` sweeps'
//! outputs whose residuals `G(r) − r` combine to the smallest norm, landed on the cones. Once
//! the contact statuses settle the map is affine and the mixing acts as GMRES on it.
//!
//! Safeguard: a mixed iterate whose sweep residual exceeds the reference (the last mixed
//! iterate's residual, or the smallest since then) is dropped — back to the plain sweep's
//! output, history forgotten (without it the mixing kept a rotating-drum step
//! at 4e-4 that plain NLGS solves). Sequential sweeps only; with rolling resistance the plain
//! NLGS runs instead, and the report's notes say so.

use super::monitor::Monitor;
use super::nlgs::forward_sweep;
use super::{SolveReport, SolverOptions};
use crate::problem::cone::project_cone;
use crate::problem::{dot, ContactProblem};

/// Solves from `r` by forward NLGS sweeps mixed over the last `opts.anderson` of them.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, mut r: Vec<f64>) -> SolveReport {
    if p.has_rolling() {
        let plain = SolverOptions { anderson: 0, ..opts.clone() };
        let mut report = super::nlgs::solve(p, &plain, r);
        report.notes.push("Anderson acceleration skipped: the problem has rolling rows (plain NLGS)".into());
        return report;
    }
    let mut monitor = Monitor::new(p, opts, super::SolverKind::Nlgs, &r);
    let n = 2 * p.n_contacts();
    let diag = p.w.diag_blocks();
    let mut history = History::new(opts.anderson);
    // `reference`: the residual a mixed iterate must not exceed — the last one after a mixed
    // step, the smallest since then after plain ones.
    let (mut output, mut reference, mut mixed) = (vec![0.0; n], f64::INFINITY, false);
    let mut restarts = 0;
    let mut plain_output = vec![0.0; n];
    loop {
        output.copy_from_slice(&r);
        forward_sweep(p, &diag, opts.omega, &mut output);
        monitor.w_products += 1;
        let residual: Vec<f64> = output.iter().zip(&r).map(|(g, x)| g - x).collect();
        let residual_norm = dot(&residual, &residual).sqrt();
        if mixed && residual_norm > reference {
            // The mixing did not help: the plain sweep's output instead, and a fresh history.
            r.copy_from_slice(&plain_output);
            history.clear();
            mixed = false;
            restarts += 1;
            if monitor.observe(&r, None) {
                break;
            }
            continue;
        }
        reference = if mixed { residual_norm } else { reference.min(residual_norm) };
        history.push(&residual, &output);
        plain_output.copy_from_slice(&output);
        r.copy_from_slice(&output);
        mixed = history.mix(&residual, &mut r);
        if mixed {
            for (a, &mu) in p.mu.iter().enumerate() {
                let ra = project_cone([r[2 * a], r[2 * a + 1]], mu);
                r[2 * a..2 * a + 2].copy_from_slice(&ra);
            }
        }
        if monitor.observe(&r, None) {
            break;
        }
    }
    monitor.note(format!("Anderson acceleration over {} sweeps, {restarts} restarts", opts.anderson));
    monitor.finish(r)
}

/// The last `depth` differences of sweep residuals and of sweep outputs, oldest first.
struct History {
    depth: usize,
    d_residual: Vec<Vec<f64>>,
    d_output: Vec<Vec<f64>>,
    last: Option<(Vec<f64>, Vec<f64>)>,
}

impl History {
    fn new(depth: usize) -> Self {
        Self { depth, d_residual: Vec::new(), d_output: Vec::new(), last: None }
    }

    fn clear(&mut self) {
        self.d_residual.clear();
        self.d_output.clear();
        self.last = None;
    }

    fn push(&mut self, residual: &[f64], output: &[f64]) {
        if let Some((last_residual, last_output)) = &self.last {
            self.d_residual.push(residual.iter().zip(last_residual).map(|(a, b)| a - b).collect());
            self.d_output.push(output.iter().zip(last_output).map(|(a, b)| a - b).collect());
            if self.d_residual.len() > self.depth {
                self.d_residual.remove(0);
                self.d_output.remove(0);
            }
        }
        self.last = Some((residual.to_vec(), output.to_vec()));
    }

    /// `r −= Σ γ_k Δoutput_k` with `γ = argmin ‖residual − Σ γ_k Δresidual_k‖`; false when
    /// there is no history or its least-squares system is singular.
    fn mix(&self, residual: &[f64], r: &mut [f64]) -> bool {
        let Some(gamma) = least_squares(&self.d_residual, residual) else { return false };
        for (c, d) in gamma.iter().zip(&self.d_output) {
            r.iter_mut().zip(d).for_each(|(x, d)| *x -= c * d);
        }
        true
    }
}

/// `argmin_γ ‖res − Σ γ_k d_k‖` by the normal equations (a relative shift of 1e-10) and
/// Cholesky; `None` without history or when singular.
fn least_squares(d: &[Vec<f64>], res: &[f64]) -> Option<Vec<f64>> {
    let m = d.len();
    if m == 0 {
        return None;
    }
    let mut a = vec![vec![0.0; m]; m];
    let mut b = vec![0.0; m];
    for i in 0..m {
        for j in 0..=i {
            a[i][j] = dot(&d[i], &d[j]);
            a[j][i] = a[i][j];
        }
        b[i] = dot(&d[i], res);
    }
    let shift = 1e-10 * (0..m).map(|i| a[i][i]).fold(0.0, f64::max);
    (0..m).for_each(|i| a[i][i] += shift);
    let mut l = vec![vec![0.0; m]; m];
    for i in 0..m {
        for j in 0..=i {
            let s = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if s <= 0.0 {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = vec![0.0; m];
    for i in 0..m {
        y[i] = (b[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = vec![0.0; m];
    for i in (0..m).rev() {
        x[i] = (y[i] - (i + 1..m).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_matches_a_hand_solved_fit() {
        // d1 = (1, 0, 1), d2 = (0, 1, 1), res = (1, 2, 3): γ = (1, 2) fits exactly.
        let d = vec![vec![1.0, 0.0, 1.0], vec![0.0, 1.0, 1.0]];
        let g = least_squares(&d, &[1.0, 2.0, 3.0]).unwrap();
        assert!((g[0] - 1.0).abs() < 1e-8 && (g[1] - 2.0).abs() < 1e-8, "{g:?}");
        assert!(least_squares(&[], &[1.0]).is_none());
        assert!(least_squares(&[vec![0.0, 0.0]], &[1.0, 1.0]).is_none());
    }
}
