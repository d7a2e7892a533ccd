//! Mirror of `shaders/velocity_residual.wgsl`: the largest |F(c r_a, u_a)| per chunk of 1,024
//! contacts, F the natural map (so the same f32 operations per contact; a maximum has no order).

use super::single_contact::velocity_residual as contact_residual;

const CHUNK: usize = 1024;

/// The CPU mirror of `velocity_residual`: one partial maximum per chunk of contacts.
pub fn velocity_residual(r: &[[f32; 2]], u: &[[f32; 2]], mu: &[f32], c: &[f32]) -> Vec<f32> {
    let n = mu.len();
    (0..n_groups(n))
        .map(|g| {
            (g * CHUNK..((g + 1) * CHUNK).min(n))
                .fold(0.0f32, |worst, a| worst.max(contact_residual(c[a], r[a], u[a], mu[a])))
        })
        .collect()
}

/// Workgroups of `velocity_residual` for `n` contacts (one per 1,024).
pub fn n_groups(n: usize) -> usize {
    n.div_ceil(CHUNK).max(1)
}
