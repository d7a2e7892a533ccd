//! Mirror of `shaders/anderson_mix.wgsl`: the mixer's action on each contact.

use super::anderson_fit::{Mixer, MIX, RECORD, RESTART};
use super::single_contact::project_cone;

/// The mixer's vectors, 2 per contact (the histories: slot `j`'s contact `a` at `j · nc + a`).
#[derive(Clone)]
pub struct MixerVectors {
    /// The sweep's output, replaced by the next iterate.
    pub r: Vec<[f32; 2]>,
    /// Where the sweep started; then where the next one starts.
    pub before: Vec<[f32; 2]>,
    /// The last sweep's residual.
    pub last_residual: Vec<[f32; 2]>,
    /// The last sweep's output.
    pub last_impulse: Vec<[f32; 2]>,
    /// Differences of residuals, by slot.
    pub d_residual: Vec<[f32; 2]>,
    /// Differences of outputs, by slot.
    pub d_impulse: Vec<[f32; 2]>,
}

fn sub(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// The CPU mirror of `anderson_mix` (a contact index per invocation, as the kernel has it).
#[allow(clippy::needless_range_loop)]
pub fn anderson_mix(x: &mut MixerVectors, mu: &[f32], m: &Mixer) {
    let nc = mu.len();
    for a in 0..nc {
        let mut out = x.r[a];
        if m.action == RESTART {
            out = x.last_impulse[a];
        } else {
            let f = sub(out, x.before[a]);
            if m.action != RECORD {
                let slot = m.slot as usize;
                let new_d_impulse = sub(out, x.last_impulse[a]);
                x.d_residual[slot * nc + a] = sub(f, x.last_residual[a]);
                x.d_impulse[slot * nc + a] = new_d_impulse;
                x.last_residual[a] = f;
                x.last_impulse[a] = out;
                if m.action == MIX {
                    let mut y = out;
                    for i in 0..m.count as usize {
                        let j = m.order[i] as usize;
                        let d = if j == slot { new_d_impulse } else { x.d_impulse[j * nc + a] };
                        y = [y[0] - m.gamma[i] * d[0], y[1] - m.gamma[i] * d[1]];
                    }
                    out = project_cone(y, mu[a]);
                }
            } else {
                x.last_residual[a] = f;
                x.last_impulse[a] = out;
            }
        }
        x.r[a] = out;
        x.before[a] = out;
    }
}
