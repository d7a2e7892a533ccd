//! Mirror of `shaders/nlgs_colour.wgsl`: one colour of a coloured NLGS sweep (matrix-free).
//! Contacts of a colour are independent, so running them in order is the parallel result.
//! With a `threshold` > 0 (the work list's sweeps) a contact whose residual in velocity units is
//! within it is left alone, and the contacts updated are counted.

use super::contact_gather::contact_velocity;
use super::single_contact::{solve_single_contact, velocity_residual};
use crate::gpu::layout::{MatrixFreeLayout, NO_ANTAGONIST};

/// The CPU mirror of `nlgs_colour`: the same bindings and order of operations in f32. Returns
/// the contacts updated when `threshold` > 0 (what the kernel adds to its counter), else 0.
#[allow(clippy::too_many_arguments)]
pub fn nlgs_colour(
    op: &MatrixFreeLayout,
    diag: &[[f32; 4]],
    q: &[[f32; 2]],
    mu: &[f32],
    contacts_of_colour: &[u32],
    threshold: f32,
    r: &mut [[f32; 2]],
    v: &mut [[f32; 4]],
) -> u32 {
    let mut updated = 0;
    for &a in contacts_of_colour {
        let a = a as usize;
        let c = &op.contacts[a];
        let t = [-c.n[1], c.n[0]];
        let w = diag[a];
        let ra = r[a];
        let u = contact_velocity(op, v, q, a);
        if threshold > 0.0 && velocity_residual(w[0], ra, u, mu[a]) <= threshold {
            continue;
        }
        let q_local = [u[0] - (w[0] * ra[0] + w[1] * ra[1]), u[1] - (w[2] * ra[0] + w[3] * ra[1])];
        let rn = solve_single_contact(w, q_local, mu[a]);
        let d = [rn[0] - ra[0], rn[1] - ra[1]];
        r[a] = rn;
        let mut f = [d[0] * c.n[0], d[0] * c.n[1]];
        if op.friction {
            f = [f[0] + d[1] * t[0], f[1] + d[1] * t[1]];
        }
        let (mut ti, mut tj) = (0.0f32, 0.0f32);
        if op.rotation {
            ti = d[0] * c.levers[0];
            tj = d[0] * c.levers[2];
            if op.friction {
                ti += d[1] * c.levers[1];
                tj += d[1] * c.levers[3];
            }
        }
        let mut scatter = |k: usize, s: f32, torque: f32| {
            let packed = op.inv_mass[k];
            if packed[0] == 0.0 && packed[1] == 0.0 {
                return;
            }
            let im = super::inverse_masses(packed);
            let x = v[k];
            v[k] = [x[0] + s * im[0] * f[0], x[1] + s * im[1] * f[1], x[2] + s * im[2] * torque, 0.0];
        };
        scatter(c.i as usize, 1.0, ti);
        if c.j != NO_ANTAGONIST {
            scatter(c.j as usize, -1.0, tj);
        }
        updated += 1;
    }
    if threshold > 0.0 {
        updated
    } else {
        0
    }
}
