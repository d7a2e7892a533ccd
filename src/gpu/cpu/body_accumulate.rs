//! Mirror of `shaders/body_accumulate.wgsl`: `v = M⁻¹ Bᵀ r` per body, over its contact list.

use crate::gpu::layout::{MatrixFreeLayout, J_SIDE};

/// The CPU mirror of `body_accumulate`: the same bindings and order of operations in f32.
pub fn body_accumulate(op: &MatrixFreeLayout, r: &[[f32; 2]], v: &mut [[f32; 4]]) {
    for (k, out) in v.iter_mut().enumerate().take(op.inv_mass.len()) {
        let (mut p, mut torque) = ([0.0f32; 2], 0.0f32);
        for &entry in &op.body_list[op.body_start[k] as usize..op.body_start[k + 1] as usize] {
            let a = (entry & !J_SIDE) as usize;
            let is_j = entry & J_SIDE != 0;
            let c = &op.contacts[a];
            let ra = r[a];
            let s = if is_j { -1.0f32 } else { 1.0 };
            let mut f = [ra[0] * c.n[0], ra[0] * c.n[1]];
            if op.friction {
                f = [f[0] + ra[1] * -c.n[1], f[1] + ra[1] * c.n[0]];
            }
            p = [p[0] + s * f[0], p[1] + s * f[1]];
            if op.rotation {
                let g = if is_j { [c.levers[2], c.levers[3]] } else { [c.levers[0], c.levers[1]] };
                let mut tq = ra[0] * g[0];
                if op.friction {
                    tq += ra[1] * g[1];
                }
                torque += s * tq;
            }
        }
        let im = super::inverse_masses(op.inv_mass[k]);
        *out = [im[0] * p[0], im[1] * p[1], im[2] * torque, 0.0];
    }
}
