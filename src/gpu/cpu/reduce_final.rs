//! Mirror of `shaders/reduce_final.wgsl` (second pass).

use super::reduce_dot::tree_sum;

/// The CPU mirror of `reduce_final`: the same bindings and order of operations in f32.
pub fn reduce_final(partials: &[f32]) -> f32 {
    let mut tree = [0.0f32; 256];
    for (t, slot) in tree.iter_mut().enumerate() {
        let mut s = 0.0f32;
        let mut i = t;
        while i < partials.len() {
            s += partials[i];
            i += 256;
        }
        *slot = s;
    }
    tree_sum(tree)
}
