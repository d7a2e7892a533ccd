//! Mirror of `shaders/nlgs_colour_bsr.wgsl`: one colour of a coloured NLGS sweep on an explicit
//! block-sparse `W`.

use super::single_contact::solve_single_contact;
use crate::gpu::layout::BsrLayout;

/// The CPU mirror of `nlgs_colour_bsr`: the same bindings and order of operations in f32.
pub fn nlgs_colour_bsr(
    w: &BsrLayout,
    diag: &[[f32; 4]],
    q: &[[f32; 2]],
    mu: &[f32],
    contacts_of_colour: &[u32],
    r: &mut [[f32; 2]],
) {
    for &a in contacts_of_colour {
        let a = a as usize;
        let mut q_local = q[a];
        for k in w.row_ptr[a] as usize..w.row_ptr[a + 1] as usize {
            let b = w.cols[k] as usize;
            if b != a {
                let blk = w.blocks[k];
                let rb = r[b];
                q_local =
                    [q_local[0] + (blk[0] * rb[0] + blk[1] * rb[1]), q_local[1] + (blk[2] * rb[0] + blk[3] * rb[1])];
            }
        }
        r[a] = solve_single_contact(diag[a], q_local, mu[a]);
    }
}
