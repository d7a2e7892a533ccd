//! Mirror of `shaders/anderson_fit.wgsl`: the mixer's decision after a sweep, in f32.

use bytemuck::{Pod, Zeroable};

/// The deepest history the GPU mixes (the kernels' arrays).
pub const MAX_DEPTH: usize = 8;
/// Actions of `anderson_mix` (shaders/shared/mixer.wgsl).
pub const RECORD: u32 = 0;
/// Store the differences, no mixing.
pub const PUSH: u32 = 1;
/// Back to the last plain output, history forgotten.
pub const RESTART: u32 = 2;
/// Store the differences and mix.
pub const MIX: u32 = 3;
/// The normal equations' relative diagonal shift.
const SHIFT: f32 = 1e-6;

/// The mixer's state on the GPU (`struct Mixer` of shaders/shared/mixer.wgsl, field by field).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Mixer {
    /// Ring slots in use.
    pub count: u32,
    /// Whether a last residual and output are kept.
    pub has_last: u32,
    /// Whether the last iterate was mixed.
    pub mixed: u32,
    /// Mixings dropped so far.
    pub restarts: u32,
    /// What `anderson_mix` does with this sweep.
    pub action: u32,
    /// The slot this sweep's differences take.
    pub slot: u32,
    /// The sweep residual a mixed iterate must not exceed.
    pub reference: f32,
    /// Slots in use, oldest first.
    pub order: [u32; MAX_DEPTH],
    /// The fit, by position in `order`.
    pub gamma: [f32; MAX_DEPTH],
    /// `Δf_i · Δf_j` at `i · depth + j`.
    pub gram: [f32; MAX_DEPTH * MAX_DEPTH],
}

impl Mixer {
    /// A fresh mixer: nothing kept, no reference yet.
    pub fn new() -> Self {
        Self { reference: f32::INFINITY, ..Zeroable::zeroed() }
    }
}

impl Default for Mixer {
    fn default() -> Self {
        Self::new()
    }
}

/// The CPU mirror of `anderson_fit`: sums `partials` (from `anderson_dots`, `groups` of them),
/// updates `m`, and returns the rebuild dispatch (`grid` or none).
pub fn anderson_fit(partials: &[f32], groups: usize, depth: usize, m: &mut Mixer, grid: [u32; 2]) -> [u32; 3] {
    let sums = 3 + 2 * depth;
    let total: Vec<f32> = (0..sums)
        .map(|c| {
            let mut s = 0.0f32;
            for g in 0..groups {
                s += partials[g * sums + c];
            }
            s
        })
        .collect();
    let norm = total[0].sqrt();
    let mut action = RECORD;
    if m.mixed == 1 && norm > m.reference {
        action = RESTART;
        m.count = 0;
        m.has_last = 0;
        m.mixed = 0;
        m.restarts += 1;
    } else {
        m.reference = if m.mixed == 1 { norm } else { m.reference.min(norm) };
        if m.has_last == 0 {
            m.has_last = 1;
            m.mixed = 0;
        } else {
            action = push_and_fit(m, &total, depth);
        }
    }
    m.action = action;
    match action {
        RESTART | MIX => [grid[0], grid[1], 1],
        _ => [0, 1, 1],
    }
}

fn push_and_fit(mx: &mut Mixer, total: &[f32], depth: usize) -> u32 {
    let mut slot = mx.count as usize;
    if mx.count as usize == depth {
        slot = mx.order[0] as usize;
        mx.order.copy_within(1..depth, 0);
        mx.count = depth as u32 - 1;
    }
    for i in 0..mx.count as usize {
        let j = mx.order[i] as usize;
        let g = total[3 + j];
        mx.gram[slot * depth + j] = g;
        mx.gram[j * depth + slot] = g;
    }
    mx.gram[slot * depth + slot] = total[1];
    mx.order[mx.count as usize] = slot as u32;
    mx.count += 1;
    mx.slot = slot as u32;
    let m = mx.count as usize;
    let mut a = [0.0f32; MAX_DEPTH * MAX_DEPTH];
    let mut b = [0.0f32; MAX_DEPTH];
    let mut largest = 0.0f32;
    for i in 0..m {
        let si = mx.order[i] as usize;
        for j in 0..m {
            a[i * MAX_DEPTH + j] = mx.gram[si * depth + mx.order[j] as usize];
        }
        b[i] = if si == slot { total[2] } else { total[3 + depth + si] };
        largest = largest.max(a[i * MAX_DEPTH + i]);
    }
    for i in 0..m {
        a[i * MAX_DEPTH + i] += SHIFT * largest;
    }
    for i in 0..m {
        for j in 0..=i {
            let mut s = a[i * MAX_DEPTH + j];
            for k in 0..j {
                s -= a[i * MAX_DEPTH + k] * a[j * MAX_DEPTH + k];
            }
            if i == j {
                if s.is_nan() || s <= 0.0 {
                    mx.mixed = 0;
                    return PUSH;
                }
                a[i * MAX_DEPTH + i] = s.sqrt();
            } else {
                a[i * MAX_DEPTH + j] = s / a[j * MAX_DEPTH + j];
            }
        }
    }
    let mut y = [0.0f32; MAX_DEPTH];
    for i in 0..m {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * MAX_DEPTH + k] * y[k];
        }
        y[i] = s / a[i * MAX_DEPTH + i];
    }
    let mut finite = true;
    for i in (0..m).rev() {
        let mut s = y[i];
        for k in i + 1..m {
            s -= a[k * MAX_DEPTH + i] * mx.gamma[k];
        }
        let x = s / a[i * MAX_DEPTH + i];
        finite = finite && x.abs() <= 3.4e38;
        mx.gamma[i] = x;
    }
    if !finite {
        mx.mixed = 0;
        return PUSH;
    }
    mx.mixed = 1;
    MIX
}
