//! The one error measure every solver is judged by (notes §7.1): the natural-map residual with
//! De Saxcé's correction, normalised by `max(‖q‖, ‖r‖, ‖u‖)` as current Siconos does (safe when
//! `q → 0`); when that scale is below machine epsilon the raw norm is returned.

use super::cone::natural_map;
use rayon::prelude::*;

use super::{ContactProblem, Mat2};
use crate::parallel::{chunked_sum, parallel, CHUNK};

/// Error of `r` given `u = W r + q` (no operator product).
/// Sums run in fixed chunks ([`chunked_sum`]): the same bits on any number of threads.
pub fn natural_map_error(q: &[f64], mu: &[f64], r: &[f64], u: &[f64]) -> f64 {
    let nc = mu.len();
    let sum = chunked_sum(nc, |a| {
        let f = natural_map([r[2 * a], r[2 * a + 1]], [u[2 * a], u[2 * a + 1]], mu[a]);
        f[0] * f[0] + f[1] * f[1]
    });
    let norm = |x: &[f64]| chunked_sum(nc, |a| x[2 * a] * x[2 * a] + x[2 * a + 1] * x[2 * a + 1]).sqrt();
    let scale = norm(q).max(norm(r)).max(norm(u));
    if scale > f64::EPSILON {
        sum.sqrt() / scale
    } else {
        sum.sqrt()
    }
}

/// Error of `r` for a problem (one operator product); also returns `u`.
pub fn error_of(problem: &ContactProblem, r: &[f64]) -> (f64, Vec<f64>) {
    let u = problem.velocity(r);
    (natural_map_error(&problem.q, &problem.mu, r, &u), u)
}

/// The largest per-contact residual in velocity units, relative to the largest free velocity:
/// `max_α ‖F(W_αα,nn r_α, u_α)‖ / max|q|` (the natural map with De Saxcé's correction, its impulse
/// turned into the velocity it would give the contact alone; the cone is invariant under that
/// scaling). Unlike the 2-norm error, no single contact can hide among many: it bounds the
/// velocity violation, hence the penetration per step, at every contact. Raw when `q` vanishes.
pub fn velocity_error(diag: &[Mat2], q: &[f64], mu: &[f64], r: &[f64], u: &[f64]) -> f64 {
    let residual = |a: usize| {
        let c = diag[a][0];
        let f = natural_map([c * r[2 * a], c * r[2 * a + 1]], [u[2 * a], u[2 * a + 1]], mu[a]);
        (f[0] * f[0] + f[1] * f[1]).sqrt()
    };
    // A maximum is the same whatever the order: threads change nothing.
    let worst = if parallel(mu.len()) {
        (0..mu.len()).into_par_iter().with_min_len(CHUNK).map(residual).reduce(|| 0.0, f64::max)
    } else {
        (0..mu.len()).map(residual).fold(0.0, f64::max)
    };
    let scale = q.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if scale > f64::EPSILON {
        worst / scale
    } else {
        worst
    }
}
