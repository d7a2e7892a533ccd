//! Mirror of `shaders/apgd_rebox.wgsl`: new thresholds, γ on the new box, y = γ, θ = 1.

/// The CPU mirror of `apgd_rebox`: the same bindings and order of operations in f32.
pub fn apgd_rebox(mu: &[f32], gamma: &mut [[f32; 2]], y: &mut [[f32; 2]], s: &mut [f32], scalars: &mut [f32]) {
    scalars[1] = 1.0;
    for a in 0..mu.len() {
        let rn = gamma[a][0].max(0.0);
        let t = mu[a] * rn;
        let p = [rn, if t >= 0.0 { gamma[a][1].clamp(-t, t) } else { f32::NAN }];
        s[a] = t;
        gamma[a] = p;
        y[a] = p;
    }
}
