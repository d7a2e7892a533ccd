//! LATIN (Ladevèze; Alart–Dureisseix–Renouf 2006), the augmented-Lagrangian / Douglas–Rachford
//! form with a diagonal search direction `k` (notes §5). Unknowns: impulses `z` and velocities
//! `w`. Each iteration alternates
//! * a linear stage on `w = W z + q` along `(w − ŵ) + k (z − ẑ) = 0`: `(W + k) z = ŵ + k ẑ − q`,
//!   solved by preconditioned CG on the matrix-free operator (warm-started, inexact at first);
//! * a local stage on the contact law along `(ŵ − w) − k (ẑ − z) = 0`, exact per contact because
//!   the diagonal `k` decouples Signorini from the tangential law: with `σ = z − w/k`,
//!   `ẑ_n = max(σ_n, 0)`, `ẑ_t = clamp(σ_t, ±μ ẑ_n)`, `ŵ = k (ẑ − σ)`.
//!
//! `k = latin_k · diag(W)` per component (compliance units), or one `k = latin_k · mean diag(W)`
//! with `latin_k_mean` (the founding paper offers both). The returned impulse is `ẑ`, which
//! always lies in the cone.

use super::conjugate_gradient::ConjugateGradient;
use super::monitor::Monitor;
use super::{SolveReport, SolverKind, SolverOptions};
use crate::problem::{norm, ContactProblem};

/// Solves from `r0` by LATIN.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, r0: Vec<f64>) -> SolveReport {
    let nc = p.n_contacts();
    let n = 2 * nc;
    let diag: Vec<f64> = p.w.diag_blocks().iter().flat_map(|d| [d[0], if d[3] > 0.0 { d[3] } else { d[0] }]).collect();
    let mean = diag.iter().sum::<f64>() / diag.len().max(1) as f64;
    let k: Vec<f64> = diag.iter().map(|&d| opts.latin_k * if opts.latin_k_mean { mean } else { d }).collect();
    let mut monitor = Monitor::new(p, opts, SolverKind::Latin, &r0);
    let mut z = r0;
    let mut w = p.velocity(&z);
    monitor.w_products += 1;
    let (mut z_hat, mut w_hat) = (vec![0.0; n], vec![0.0; n]);
    local_stage(&p.mu, &k, &z, &w, &mut z_hat, &mut w_hat);
    let mut rhs = vec![0.0; n];
    // Jacobi-preconditioned CG on (W + diag(k)) z = rhs.
    let mut cg = ConjugateGradient::new(n);
    let cg_diag: Vec<f64> = p.w.diag_blocks().iter().flat_map(|d| [d[0], d[3]]).zip(&k).map(|(d, k)| d + k).collect();
    let apply = |v: &[f64], out: &mut [f64]| {
        p.w.apply(v, out);
        out.iter_mut().zip(k.iter().zip(v)).for_each(|(o, (k, v))| *o += k * v);
    };
    let mut inner_tol: f64 = 1e-2;
    loop {
        for i in 0..n {
            rhs[i] = w_hat[i] + k[i] * z_hat[i] - p.q[i];
        }
        monitor.w_products += cg.solve(apply, Some(&cg_diag), &rhs, &mut z, inner_tol, 10 * n.max(10) + 1);
        for i in 0..n {
            w[i] = w_hat[i] + k[i] * (z_hat[i] - z[i]);
        }
        let previous = z_hat.clone();
        local_stage(&p.mu, &k, &z, &w, &mut z_hat, &mut w_hat);
        let change = {
            let d: f64 = z_hat.iter().zip(&previous).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
            d / norm(&z_hat).max(f64::MIN_POSITIVE)
        };
        // The linear stage needs to be only as accurate as the outer iteration is.
        inner_tol = (0.1 * change).clamp(1e-15, 1e-2);
        if monitor.observe(&z_hat, None) {
            break;
        }
    }
    monitor.finish(z_hat)
}

/// Exact projection of `(z, w)` onto the contact law along the search direction `k`.
fn local_stage(mu: &[f64], k: &[f64], z: &[f64], w: &[f64], z_hat: &mut [f64], w_hat: &mut [f64]) {
    for (a, &m) in mu.iter().enumerate() {
        let (i, j) = (2 * a, 2 * a + 1);
        let sn = z[i] - w[i] / k[i];
        let st = z[j] - w[j] / k[j];
        let zn = sn.max(0.0);
        let s = m * zn;
        let zt = crate::problem::cone::clamp_symmetric(st, s);
        z_hat[i] = zn;
        z_hat[j] = zt;
        w_hat[i] = k[i] * (zn - sn);
        w_hat[j] = k[j] * (zt - st);
    }
}
