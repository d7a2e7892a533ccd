//! CPU mirrors of the WGSL kernels, one file per kernel and named the same (as vello does), in
//! f32 with the kernels' order of operations, so that every GPU stage can be checked on its own.

pub mod anderson_dots;
pub mod anderson_fit;
pub mod anderson_mix;
pub mod apgd_momentum;
pub mod apgd_rebox;
pub mod apgd_scalars;
pub mod apgd_step;
pub mod body_accumulate;
pub mod bsr_product;
pub mod contact_gather;
pub mod cpg_direction;
pub mod cpg_gradient;
pub mod cpg_restart;
pub mod cpg_scalars;
pub mod cpg_update;
pub mod jacobi_fused;
pub mod jacobi_update;
pub mod natural_map;
pub mod nlgs_blocks;
pub mod nlgs_colour;
pub mod nlgs_colour_bsr;
pub mod reduce_dot;
pub mod reduce_final;
pub mod single_contact;
pub mod velocity_residual;

/// Mirror of `shaders/shared/masses.wgsl`: a body's packed `(1/m, 1/I)` as
/// `[1/m along x, 1/m along y, 1/I]`, zero along an axis whose sign bit marks it held.
#[inline]
pub fn inverse_masses(packed: [f32; 2]) -> [f32; 3] {
    let m = packed[0].abs();
    let along = |held: f32| if held.is_sign_negative() { 0.0 } else { m };
    [along(packed[0]), along(packed[1]), packed[1].abs()]
}
