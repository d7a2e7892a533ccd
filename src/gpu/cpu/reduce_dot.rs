//! Mirror of `shaders/reduce_dot.wgsl` (first pass) — the same chunks and tree, so the same f32 sum.

const WG: usize = 256;
const PER_THREAD: usize = 4;

/// Fixed-order tree sum of 256 values, as the kernels do it.
pub(crate) fn tree_sum(mut tree: [f32; WG]) -> f32 {
    let mut half = WG / 2;
    while half > 0 {
        for t in 0..half {
            tree[t] += tree[t + half];
        }
        half /= 2;
    }
    tree[0]
}

/// Number of partial sums for `n` entries.
pub fn n_partials(n: usize) -> usize {
    n.div_ceil(WG * PER_THREAD).max(1)
}

/// The CPU mirror of `reduce_dot`: the same bindings and order of operations in f32.
pub fn reduce_dot(a: &[f32], b: &[f32]) -> Vec<f32> {
    let n = a.len();
    (0..n_partials(n))
        .map(|g| {
            let mut tree = [0.0f32; WG];
            for (t, slot) in tree.iter_mut().enumerate() {
                let mut s = 0.0f32;
                for k in 0..PER_THREAD {
                    let i = g * WG * PER_THREAD + k * WG + t;
                    if i < n {
                        s += a[i] * b[i];
                    }
                }
                *slot = s;
            }
            tree_sum(tree)
        })
        .collect()
}
