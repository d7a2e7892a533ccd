//! Mirror of `shaders/nlgs_blocks.wgsl`: the blocks of one block colour, each swept `inner`
//! times colour by colour. Blocks of a colour share no moving body and contacts of a colour
//! none either, so running them in order is the parallel result.

use super::nlgs_colour::nlgs_colour;
use crate::gpu::colouring::BlockColouring;
use crate::gpu::layout::MatrixFreeLayout;

/// The CPU mirror of `nlgs_blocks`: block colour `block_colour` of `blocks`, in f32.
#[allow(clippy::too_many_arguments)]
pub fn nlgs_blocks(
    op: &MatrixFreeLayout,
    (diag, q, mu): (&[[f32; 4]], &[[f32; 2]], &[f32]),
    blocks: &BlockColouring,
    block_colour: usize,
    inner: usize,
    threshold: f32,
    r: &mut [[f32; 2]],
    v: &mut [[f32; 4]],
) {
    for &b in blocks.blocks.colour(block_colour) {
        for _ in 0..inner {
            for c in 0..blocks.colours {
                nlgs_colour(op, diag, q, mu, blocks.contacts(b as usize, c), threshold, r, v);
            }
        }
    }
}
