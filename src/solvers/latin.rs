//! LATIN (Ladevèze; Alart–Dureisseix–Renouf 2006), the augmented-Lagrangian / Douglas–Rachford
//! form with a diagonal search direction `k` (notes §5). Unknowns: impulses `z` and velocities
//! `w`. Each iteration alternates
//! * a linear stage on `w = W z + q` along `(w − ŵ) + k (z − ẑ) = 0`: `(W + k) z = ŵ + k ẑ − q`,
//!   solved by preconditioned CG on the matrix-free operator (warm-started, inexact at first);
//! * a local stage on the contact law along `(ŵ − w) − k (ẑ − z) = 0`, exact per contact because
//!   the diagonal `k` decouples Signorini from the tangential law: with `σ = z − w/k`,
//!   `ẑ_n = max(σ_n, 0)`, `ẑ_t = clamp(σ_t, ±μ ẑ_n)`, `ŵ = k (ẑ − σ)`.
//!
//! `k = factor · diag(W)` per component (compliance units), or one `k = factor · mean diag(W)`
//! with `latin_k_mean` (the founding paper offers both). The factor is given, or chosen
//! ([`LatinK::Auto`]): without friction the problem is a QP and the augmented-Lagrangian optimum
//! `√(λ_min λ_max)` of `W` scaled by that basis, on the contacts expected closed, predicts the
//! best factor (a few Lanczos products); with friction it does not (BENCHMARKS.md: 10–100× below
//! the best factor, which itself moves from 0.25 to 4 between two steps of one flow), so the
//! factor stays 1. The returned impulse is `ẑ`, which always lies in the cone.

use super::conjugate_gradient::ConjugateGradient;
use super::monitor::Monitor;
use super::{SolveReport, SolverKind, SolverOptions};
use crate::parallel::{chunked_sum, copied, for_each_item_pair, for_each_value};
use crate::problem::{norm, spectrum, ContactProblem};

/// LATIN's search-direction factor: given, or chosen by the solver from the problem.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum LatinK {
    /// `k = factor × diag(W)` (or × its mean).
    Factor(f64),
    /// Frictionless: `√(λ_min λ_max)` of the scaled `W` on the contacts expected closed; with
    /// friction: 1.
    Auto,
}

impl std::str::FromStr for LatinK {
    type Err = String;

    /// `auto` or a factor, finite and > 0.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(LatinK::Auto),
            _ => match s.parse::<f64>() {
                Ok(f) if f.is_finite() && f > 0.0 => Ok(LatinK::Factor(f)),
                _ => Err(format!("{s}: expected `auto` or a factor, finite and > 0")),
            },
        }
    }
}

impl std::fmt::Display for LatinK {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LatinK::Factor(x) => write!(f, "{x}"),
            LatinK::Auto => f.write_str("auto"),
        }
    }
}

/// Solves from `r0` by LATIN.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, r0: Vec<f64>) -> SolveReport {
    let nc = p.n_contacts();
    let n = 2 * nc;
    let diag: Vec<f64> = p.w.diag_blocks().iter().flat_map(|d| [d[0], if d[3] > 0.0 { d[3] } else { d[0] }]).collect();
    let mean = diag.iter().sum::<f64>() / diag.len().max(1) as f64;
    let basis: Vec<f64> = diag.iter().map(|&d| if opts.latin_k_mean { mean } else { d }).collect();
    let mut monitor = Monitor::new(p, opts, SolverKind::Latin, &r0);
    let factor = match opts.latin_k {
        LatinK::Factor(f) => f,
        LatinK::Auto => {
            let (factor, why, products) = automatic_factor(p, &basis, &r0);
            monitor.add_setup_products(products);
            let of = if opts.latin_k_mean { "mean diag(W)" } else { "diag(W)" };
            monitor.note(format!("LATIN search direction k = {factor:.3e} × {of} ({why})"));
            factor
        }
    };
    let k: Vec<f64> = basis.iter().map(|b| factor * b).collect();
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
        for_each_value(out, |i, o| *o += k[i] * v[i]);
    };
    let mut inner_tol: f64 = 1e-2;
    loop {
        for_each_value(&mut rhs, |i, x| *x = w_hat[i] + k[i] * z_hat[i] - p.q[i]);
        monitor.w_products += cg.solve(apply, Some(&cg_diag), &rhs, &mut z, inner_tol, 10 * n.max(10) + 1);
        for_each_value(&mut w, |i, x| *x = w_hat[i] + k[i] * (z_hat[i] - z[i]));
        let previous = copied(&z_hat);
        local_stage(&p.mu, &k, &z, &w, &mut z_hat, &mut w_hat);
        let change = {
            let d = chunked_sum(n, |i| (z_hat[i] - previous[i]) * (z_hat[i] - previous[i])).sqrt();
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

/// Lanczos steps of the automatic search direction (each one product with `W`).
const LANCZOS_STEPS: usize = 30;

/// The factor of [`LatinK::Auto`], why, and the products spent. Without friction:
/// `√(λ_min λ_max)` of `K^{-1/2} W K^{-1/2}` (`K` = `basis`) on the normals expected to carry
/// impulse — closed in `r0`, or on a cold start approaching (`q_n < 0`), or all of them — and 1
/// when the estimate fails. With friction: 1.
fn automatic_factor(p: &ContactProblem, basis: &[f64], r0: &[f64]) -> (f64, String, usize) {
    if !p.is_frictionless() {
        return (1.0, "friction: the frictionless optimum does not carry over".into(), 0);
    }
    let nc = p.n_contacts();
    let warm = (0..nc).any(|a| r0[2 * a] > 0.0);
    let mut active: Vec<bool> = (0..nc).map(|a| if warm { r0[2 * a] > 0.0 } else { p.q[2 * a] < 0.0 }).collect();
    if !active.contains(&true) {
        active.iter_mut().for_each(|x| *x = true);
    }
    let mask: Vec<f64> = (0..2 * nc).map(|i| f64::from(u8::from(i % 2 == 0 && active[i / 2]))).collect();
    let scale: Vec<f64> = basis.iter().zip(&mask).map(|(b, m)| m / b.sqrt()).collect();
    // A fixed pseudo-random start (no special structure to hide an end of the spectrum).
    let start: Vec<f64> = (0..2 * nc)
        .map(|i| mask[i] * (0.5 + ((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11) as f64 / (1u64 << 53) as f64))
        .collect();
    let mut x = vec![0.0; 2 * nc];
    let apply = |v: &[f64], out: &mut [f64]| {
        x.iter_mut().zip(v.iter().zip(&scale)).for_each(|(x, (v, s))| *x = v * s);
        p.w.apply(&x, out);
        out.iter_mut().zip(&scale).for_each(|(o, s)| *o *= s);
    };
    match spectrum::extreme_eigenvalues(2 * nc, apply, &start, LANCZOS_STEPS) {
        Some((lo, hi, products)) if lo > 0.0 && hi.is_finite() => {
            ((lo * hi).sqrt(), format!("√(λ_min λ_max), λ in [{lo:.3e}, {hi:.3e}]"), products)
        }
        Some((_, _, products)) => (1.0, "no positive spectrum estimate".into(), products),
        None => (1.0, "no spectrum estimate".into(), 0),
    }
}

/// Exact projection of `(z, w)` onto the contact law along the search direction `k`.
fn local_stage(mu: &[f64], k: &[f64], z: &[f64], w: &[f64], z_hat: &mut [f64], w_hat: &mut [f64]) {
    let n = 2 * mu.len();
    for_each_item_pair((&mut z_hat[..n], 2), (&mut w_hat[..n], 2), |a, z_hat, w_hat| {
        let (i, j) = (2 * a, 2 * a + 1);
        let sn = z[i] - w[i] / k[i];
        let st = z[j] - w[j] / k[j];
        let zn = sn.max(0.0);
        let zt = crate::problem::cone::clamp_symmetric(st, mu[a] * zn);
        z_hat.copy_from_slice(&[zn, zt]);
        w_hat.copy_from_slice(&[k[i] * (zn - sn), k[j] * (zt - st)]);
    });
}
