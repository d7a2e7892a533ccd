//! Mirror of `shaders/contact_gather.wgsl`: `u = B v + q` per contact.

use crate::gpu::layout::{MatrixFreeLayout, NO_ANTAGONIST};

/// The CPU mirror of `contact_gather`: the same bindings and order of operations in f32.
pub fn contact_gather(op: &MatrixFreeLayout, v: &[[f32; 4]], q: &[[f32; 2]], u: &mut [[f32; 2]]) {
    for (a, ua) in u.iter_mut().enumerate().take(op.contacts.len()) {
        *ua = contact_velocity(op, v, q, a);
    }
}

/// `u_a = B_a v + q_a` for one contact, as the kernels compute it (shared with the mirrors of
/// the NLGS colour and the fused Jacobi iteration).
pub(crate) fn contact_velocity(op: &MatrixFreeLayout, v: &[[f32; 4]], q: &[[f32; 2]], a: usize) -> [f32; 2] {
    let [un, ut] = gather_one(op, v, a);
    [un + q[a][0], ut + q[a][1]]
}

/// `B_a v` for one contact, as the kernels compute it.
fn gather_one(op: &MatrixFreeLayout, v: &[[f32; 4]], a: usize) -> [f32; 2] {
    {
        let c = &op.contacts[a];
        let vi = v[c.i as usize];
        let mut dv = [vi[0], vi[1]];
        let mut wj = 0.0f32;
        if c.j != NO_ANTAGONIST {
            let vj = v[c.j as usize];
            dv = [dv[0] - vj[0], dv[1] - vj[1]];
            wj = vj[2];
        }
        let mut un = c.n[0] * dv[0] + c.n[1] * dv[1];
        let mut ut = 0.0f32;
        if op.friction {
            ut = -c.n[1] * dv[0] + c.n[0] * dv[1];
        }
        if op.rotation {
            un = un + c.levers[0] * vi[2] - c.levers[2] * wj;
            if op.friction {
                ut = ut + c.levers[1] * vi[2] - c.levers[3] * wj;
            }
        }
        [un, ut]
    }
}
