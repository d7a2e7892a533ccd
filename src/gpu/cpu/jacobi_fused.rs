//! Mirror of `shaders/jacobi_fused.wgsl`: one projected-Jacobi iteration per body, from
//! `(r_in, v_in)` to `(r_out, v_out)`.

use super::body_accumulate::{add, body_contacts, body_velocity, contact_push};
use super::contact_gather::contact_velocity;
use super::jacobi_update::jacobi_one;
use crate::gpu::layout::MatrixFreeLayout;

/// The CPU mirror of `jacobi_fused`: the same bindings and order of operations in f32. Each
/// contact is updated by each of its bodies, as the kernel does, and written by its body i.
pub fn jacobi_fused(
    op: &MatrixFreeLayout,
    q: &[[f32; 2]],
    mu: &[f32],
    step: &[f32],
    (r_in, v_in): (&[[f32; 2]], &[[f32; 4]]),
    r_out: &mut [[f32; 2]],
    v_out: &mut [[f32; 4]],
) {
    for (k, out) in v_out.iter_mut().enumerate().take(op.inv_mass.len()) {
        let mut push = [0.0f32; 3];
        for (a, is_j) in body_contacts(op, k) {
            let rn = jacobi_one(r_in[a], contact_velocity(op, v_in, q, a), mu[a], step[a]);
            if !is_j {
                r_out[a] = rn;
            }
            add(&mut push, contact_push(op, &op.contacts[a], rn, is_j));
        }
        *out = body_velocity(op, k, push);
    }
}
