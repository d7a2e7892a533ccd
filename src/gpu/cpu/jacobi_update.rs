//! Mirror of `shaders/jacobi_update.wgsl`: `r ← Π_K(r − η (u_n + μ|u_t|, u_t))` per contact.

use super::single_contact::project_cone;

/// The CPU mirror of `jacobi_update`: the same bindings and order of operations in f32.
pub fn jacobi_update(u: &[[f32; 2]], mu: &[f32], step: &[f32], r: &mut [[f32; 2]]) {
    for a in 0..mu.len() {
        let (ua, m, s) = (u[a], mu[a], step[a]);
        let x = [r[a][0] - s * (ua[0] + m * ua[1].abs()), r[a][1] - s * ua[1]];
        r[a] = project_cone(x, m);
    }
}
