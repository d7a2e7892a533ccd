//! The one error measure every solver is judged by (notes §7.1): the natural-map residual with
//! De Saxcé's correction, normalised by `max(‖q‖, ‖r‖, ‖u‖)` as current Siconos does (safe when
//! `q → 0`); when that scale is below machine epsilon the raw norm is returned.

use super::cone::natural_map;
use super::{norm, ContactProblem};

/// Error of `r` given `u = W r + q` (no operator product).
pub fn natural_map_error(q: &[f64], mu: &[f64], r: &[f64], u: &[f64]) -> f64 {
    let mut sum = 0.0;
    for (a, &m) in mu.iter().enumerate() {
        let f = natural_map([r[2 * a], r[2 * a + 1]], [u[2 * a], u[2 * a + 1]], m);
        sum += f[0] * f[0] + f[1] * f[1];
    }
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
