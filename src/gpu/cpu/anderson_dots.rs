//! Mirror of `shaders/anderson_dots.wgsl`: the partial sums of the Anderson fit's dot products,
//! per chunk of 1,024 entries, in the kernel's order (per-thread sums, then fixed trees).

use super::reduce_dot::{n_partials, tree_sum};

const WG: usize = 256;
const PER_THREAD: usize = 4;

/// Sums per workgroup for a history of `depth` slots: f·f, d·d, d·f, d·Δf_j, f·Δf_j.
pub fn n_sums(depth: usize) -> usize {
    3 + 2 * depth
}

/// Workgroups (partials) for `n` entries.
pub fn n_groups(n: usize) -> usize {
    n_partials(n)
}

/// The CPU mirror of `anderson_dots`: `d_residual` holds `depth` slots of `r.len()` entries.
pub fn anderson_dots(r: &[f32], before: &[f32], last_residual: &[f32], d_residual: &[f32], depth: usize) -> Vec<f32> {
    let n = r.len();
    let sums = n_sums(depth);
    let mut partials = Vec::with_capacity(n_groups(n) * sums);
    for g in 0..n_groups(n) {
        let mut per_thread = vec![vec![0.0f32; sums]; WG];
        for (t, s) in per_thread.iter_mut().enumerate() {
            for k in 0..PER_THREAD {
                let i = g * WG * PER_THREAD + k * WG + t;
                if i < n {
                    let f = r[i] - before[i];
                    let d = f - last_residual[i];
                    s[0] += f * f;
                    s[1] += d * d;
                    s[2] += d * f;
                    for j in 0..depth {
                        let h = d_residual[j * n + i];
                        s[3 + j] += d * h;
                        s[3 + depth + j] += f * h;
                    }
                }
            }
        }
        partials.extend((0..sums).map(|c| tree_sum(std::array::from_fn(|t| per_thread[t][c]))));
    }
    partials
}
