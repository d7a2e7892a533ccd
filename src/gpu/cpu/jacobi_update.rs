//! Mirror of `shaders/jacobi_update.wgsl`: `r ← Π_K(r − η (u_n + μ|u_t|, u_t))` per contact.

use super::single_contact::project_cone;

/// The CPU mirror of `jacobi_update`: the same bindings and order of operations in f32.
pub fn jacobi_update(u: &[[f32; 2]], mu: &[f32], step: &[f32], r: &mut [[f32; 2]]) {
    for a in 0..mu.len() {
        r[a] = jacobi_one(r[a], u[a], mu[a], step[a]);
    }
}

/// One contact's projected-Jacobi update from its impulse `ra` and velocity `ua` (shared with
/// the mirror of `jacobi_fused`).
pub(crate) fn jacobi_one(ra: [f32; 2], ua: [f32; 2], m: f32, s: f32) -> [f32; 2] {
    project_cone([ra[0] - s * (ua[0] + m * ua[1].abs()), ra[1] - s * ua[1]], m)
}
