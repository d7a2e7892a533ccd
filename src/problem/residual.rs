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
    natural_map_error_rolling(q, mu, &[], r, u)
}

/// [`natural_map_error`] with rolling resistance (`rolling` = η per contact, empty when off):
/// each contact's rolling row adds `r_r − clamp(r_r − u_r, ±η r_n)` to the residual (zero
/// exactly when `|r_r| ≤ η r_n` and r_r resists the rolling velocity), and its entries to the
/// scale.
pub fn natural_map_error_rolling(q: &[f64], mu: &[f64], rolling: &[f64], r: &[f64], u: &[f64]) -> f64 {
    let nc = mu.len();
    let roll = |a: usize| {
        if rolling.is_empty() {
            return 0.0;
        }
        let (rr, bound) = (r[2 * nc + a], rolling[a] * r[2 * a].max(0.0));
        let f = rr - (rr - u[2 * nc + a]).clamp(-bound, bound);
        f * f
    };
    let sum = chunked_sum(nc, |a| {
        let f = natural_map([r[2 * a], r[2 * a + 1]], [u[2 * a], u[2 * a + 1]], mu[a]);
        f[0] * f[0] + f[1] * f[1] + roll(a)
    });
    let norm = |x: &[f64]| {
        let tail = |a: usize| if rolling.is_empty() { 0.0 } else { x[2 * nc + a] * x[2 * nc + a] };
        chunked_sum(nc, |a| x[2 * a] * x[2 * a] + x[2 * a + 1] * x[2 * a + 1] + tail(a)).sqrt()
    };
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
    (problem_error(problem, r, &u), u)
}

/// The error of `r` for `problem` given `u = W r + q`, rolling rows included.
pub fn problem_error(problem: &ContactProblem, r: &[f64], u: &[f64]) -> f64 {
    natural_map_error_rolling(&problem.q, &problem.mu, &problem.rolling, r, u)
}

/// The largest per-contact residual in velocity units, relative to the largest free velocity:
/// `max_α ‖F(W_αα,nn r_α, u_α)‖ / max|q|` (the natural map with De Saxcé's correction, its impulse
/// turned into the velocity it would give the contact alone; the cone is invariant under that
/// scaling). Unlike the 2-norm error, no single contact can hide among many: it bounds the
/// velocity violation, hence the penetration per step, at every contact. Raw when `q` vanishes.
pub fn velocity_error(diag: &[Mat2], q: &[f64], mu: &[f64], r: &[f64], u: &[f64]) -> f64 {
    velocity_error_rolling(diag, q, mu, &[], r, u)
}

/// [`velocity_error`] with rolling rows (`rolling` = η per contact, empty when off): the rolling
/// impulse is scaled by the same `W_α,nn`, so `c r_r − clamp(c r_r − u_r, ±η c r_n)` joins the
/// contact's residual.
pub fn velocity_error_rolling(diag: &[Mat2], q: &[f64], mu: &[f64], rolling: &[f64], r: &[f64], u: &[f64]) -> f64 {
    let nc = mu.len();
    let residual = |a: usize| {
        let c = diag[a][0];
        let f = natural_map([c * r[2 * a], c * r[2 * a + 1]], [u[2 * a], u[2 * a + 1]], mu[a]);
        let roll = match rolling.get(a) {
            Some(eta) => {
                let (rr, bound) = (c * r[2 * nc + a], eta * c * r[2 * a].max(0.0));
                rr - (rr - u[2 * nc + a]).clamp(-bound, bound)
            }
            None => 0.0,
        };
        (f[0] * f[0] + f[1] * f[1] + roll * roll).sqrt()
    };
    // A maximum is the same whatever the order: threads change nothing.
    let worst = if parallel(nc) {
        (0..nc).into_par_iter().with_min_len(CHUNK).map(residual).reduce(|| 0.0, f64::max)
    } else {
        (0..nc).map(residual).fold(0.0, f64::max)
    };
    let scale = q.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if scale > f64::EPSILON {
        worst / scale
    } else {
        worst
    }
}
