//! Mirror of `shaders/apgd_momentum.wgsl`: y from next and γ, then γ = next.

/// The CPU mirror of `apgd_momentum`: the same bindings and order of operations in f32.
pub fn apgd_momentum(scalars: &[f32], next: &[[f32; 2]], gamma: &mut [[f32; 2]], y: &mut [[f32; 2]]) {
    for a in 0..next.len() {
        let n = next[a];
        y[a] = if scalars[3] > 0.0 {
            n
        } else {
            [n[0] + scalars[2] * (n[0] - gamma[a][0]), n[1] + scalars[2] * (n[1] - gamma[a][1])]
        };
        gamma[a] = n;
    }
}
