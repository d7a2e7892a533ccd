//! Mirror of `shaders/bsr_product.wgsl`: `u = W r + q` for an explicit block-sparse `W`.

use crate::gpu::layout::BsrLayout;

/// The CPU mirror of `bsr_product`: the same bindings and order of operations in f32.
pub fn bsr_product(w: &BsrLayout, r: &[[f32; 2]], q: &[[f32; 2]], u: &mut [[f32; 2]]) {
    for a in 0..q.len() {
        let mut acc = q[a];
        for k in w.row_ptr[a] as usize..w.row_ptr[a + 1] as usize {
            let b = w.blocks[k];
            let rb = r[w.cols[k] as usize];
            acc = [acc[0] + (b[0] * rb[0] + b[1] * rb[1]), acc[1] + (b[2] * rb[0] + b[3] * rb[1])];
        }
        u[a] = acc;
    }
}
