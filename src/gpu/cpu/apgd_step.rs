//! Mirror of `shaders/apgd_step.wgsl`: next = Π_box(y − g/L), diff = next − γ.

/// The CPU mirror of `apgd_step`: the same bindings and order of operations in f32.
pub fn apgd_step(
    scalars: &[f32],
    g: &[[f32; 2]],
    y: &[[f32; 2]],
    gamma: &[[f32; 2]],
    s: &[f32],
    next: &mut [[f32; 2]],
    diff: &mut [[f32; 2]],
) {
    for a in 0..s.len() {
        let x = [y[a][0] - scalars[4] * g[a][0], y[a][1] - scalars[4] * g[a][1]];
        let n = [x[0].max(0.0), if s[a] >= 0.0 { x[1].clamp(-s[a], s[a]) } else { f32::NAN }];
        next[a] = n;
        diff[a] = [n[0] - gamma[a][0], n[1] - gamma[a][1]];
    }
}
