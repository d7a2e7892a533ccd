//! Mirror of `shaders/cpg_update.wgsl`: projection with status memory of r + α d.

/// The CPU mirror of `cpg_update`: the same bindings and order of operations in f32.
pub fn cpg_update(
    scalars: &[f32],
    d: &[[f32; 2]],
    mu: &[f32],
    r: &mut [[f32; 2]],
    status: &mut [u32],
    changed: &mut [f32],
) {
    let alpha = scalars[6];
    for a in 0..mu.len() {
        let x = [r[a][0] + alpha * d[a][0], r[a][1] + alpha * d[a][1]];
        let m = mu[a];
        let previous = status[a];
        let (out, st) = if x[0] <= 0.0 {
            ([0.0, 0.0], 0)
        } else if m > 0.0 && x[1] <= -m * x[0] {
            ([x[0], -m * x[0]], 3)
        } else if m > 0.0 && x[1] >= m * x[0] {
            ([x[0], m * x[0]], 2)
        } else if m == 0.0 {
            ([x[0], 0.0], 1)
        } else if d[a][1] == 0.0 && previous == 2 {
            ([x[0], m * x[0]], 2)
        } else if d[a][1] == 0.0 && previous == 3 {
            ([x[0], -m * x[0]], 3)
        } else {
            (x, 1)
        };
        r[a] = out;
        changed[a] = if st != previous { 1.0 } else { 0.0 };
        status[a] = st;
    }
}
