//! Mirror of `shaders/velocity_residual.wgsl`: the largest |F(c r_a, u_a)| per chunk of 1,024
//! contacts, F the natural map (so the same f32 operations per contact; a maximum has no order).

use super::single_contact::project_cone;

const CHUNK: usize = 1024;

/// The CPU mirror of `velocity_residual`: one partial maximum per chunk of contacts.
pub fn velocity_residual(r: &[[f32; 2]], u: &[[f32; 2]], mu: &[f32], c: &[f32]) -> Vec<f32> {
    let n = mu.len();
    (0..n_groups(n))
        .map(|g| {
            (g * CHUNK..((g + 1) * CHUNK).min(n)).fold(0.0f32, |worst, a| {
                let (m, ua) = (mu[a], u[a]);
                let ra = [c[a] * r[a][0], c[a] * r[a][1]];
                let p = project_cone([ra[0] - (ua[0] + m * ua[1].abs()), ra[1] - ua[1]], m);
                let f = [ra[0] - p[0], ra[1] - p[1]];
                worst.max((f[0] * f[0] + f[1] * f[1]).sqrt())
            })
        })
        .collect()
}

/// Workgroups of `velocity_residual` for `n` contacts (one per 1,024).
pub fn n_groups(n: usize) -> usize {
    n.div_ceil(CHUNK).max(1)
}
