//! Mirror of `shaders/velocity_residual.wgsl`: per chunk of 1,024 contacts, the largest
//! |F(c r_a, u_a)|, F the natural map (the same f32 operations per contact; a maximum has no
//! order), and the sum of |r| + |u| in the kernel's lanes and tree (the same f32 sum), which a
//! diverged iterate makes non-finite.

use super::reduce_dot::tree_sum;
use super::single_contact::velocity_residual as contact_residual;

const WG: usize = 256;
const PER_THREAD: usize = 4;
const CHUNK: usize = WG * PER_THREAD;

/// The CPU mirror of `velocity_residual`: per chunk of contacts, its largest residual and its
/// finiteness witness.
pub fn velocity_residual(r: &[[f32; 2]], u: &[[f32; 2]], mu: &[f32], c: &[f32]) -> Vec<[f32; 2]> {
    let n = mu.len();
    (0..n_groups(n))
        .map(|g| {
            let mut worst = 0.0f32;
            let mut lanes = [0.0f32; WG];
            for (t, lane) in lanes.iter_mut().enumerate() {
                for k in 0..PER_THREAD {
                    let a = g * CHUNK + k * WG + t;
                    if a < n {
                        worst = worst.max(contact_residual(c[a], r[a], u[a], mu[a]));
                        let size = [r[a][0].abs() + u[a][0].abs(), r[a][1].abs() + u[a][1].abs()];
                        *lane += size[0] + size[1];
                    }
                }
            }
            [worst, tree_sum(lanes)]
        })
        .collect()
}

/// Workgroups of `velocity_residual` for `n` contacts (one per 1,024).
pub fn n_groups(n: usize) -> usize {
    n.div_ceil(CHUNK).max(1)
}
