//! Mirror of `shaders/body_accumulate.wgsl`: `v = M⁻¹ Bᵀ r` per body, over its contact list.

use crate::gpu::layout::{GpuContact, MatrixFreeLayout, J_SIDE};

/// The CPU mirror of `body_accumulate`: the same bindings and order of operations in f32.
pub fn body_accumulate(op: &MatrixFreeLayout, r: &[[f32; 2]], v: &mut [[f32; 4]]) {
    for (k, out) in v.iter_mut().enumerate().take(op.inv_mass.len()) {
        let mut push = [0.0f32; 3];
        for (a, is_j) in body_contacts(op, k) {
            add(&mut push, contact_push(op, &op.contacts[a], r[a], is_j));
        }
        *out = body_velocity(op, k, push);
    }
}

/// Body `k`'s contacts in its list's order, and whether the body is their `j`.
pub(crate) fn body_contacts(op: &MatrixFreeLayout, k: usize) -> impl Iterator<Item = (usize, bool)> + '_ {
    let list = &op.body_list[op.body_start[k] as usize..op.body_start[k + 1] as usize];
    list.iter().map(|&entry| ((entry & !J_SIDE) as usize, entry & J_SIDE != 0))
}

/// Mirror of `contact_push` (`shaders/shared/contact.wgsl`): `B_aᵀ r_a` as body i (or j, the
/// opposite sign, when `is_j`) of contact `c` receives it, `(p_x, p_y, torque)`.
pub(crate) fn contact_push(op: &MatrixFreeLayout, c: &GpuContact, ra: [f32; 2], is_j: bool) -> [f32; 3] {
    let s = if is_j { -1.0f32 } else { 1.0 };
    let mut f = [ra[0] * c.n[0], ra[0] * c.n[1]];
    if op.friction {
        f = [f[0] + ra[1] * -c.n[1], f[1] + ra[1] * c.n[0]];
    }
    let mut tq = 0.0f32;
    if op.rotation {
        let g = if is_j { [c.levers[2], c.levers[3]] } else { [c.levers[0], c.levers[1]] };
        tq = ra[0] * g[0];
        if op.friction {
            tq += ra[1] * g[1];
        }
    }
    [s * f[0], s * f[1], s * tq]
}

/// `sum += x`, component by component.
pub(crate) fn add(sum: &mut [f32; 3], x: [f32; 3]) {
    (0..3).for_each(|d| sum[d] += x[d]);
}

/// Body `k`'s velocity `M⁻¹ p` from its summed push `p`.
pub(crate) fn body_velocity(op: &MatrixFreeLayout, k: usize, push: [f32; 3]) -> [f32; 4] {
    let im = super::inverse_masses(op.inv_mass[k]);
    [im[0] * push[0], im[1] * push[1], im[2] * push[2], 0.0]
}
