//! Mirror of `shaders/cpg_gradient.wgsl`: tangent-cone projections w (of −s∘u) and z (of d).

/// The CPU mirror of `cpg_gradient`: the same bindings and order of operations in f32.
pub fn cpg_gradient(
    u: &[[f32; 2]],
    scale: &[[f32; 2]],
    d: &[[f32; 2]],
    status: &[u32],
    mu: &[f32],
    w: &mut [[f32; 2]],
    z: &mut [[f32; 2]],
) {
    for a in 0..mu.len() {
        let g = [-scale[a][0] * u[a][0], -scale[a][1] * u[a][1]];
        let p = d[a];
        let (mut wa, mut za) = match status[a] {
            0 if g[0] > 0.0 => ([g[0], 0.0], [p[0].max(0.0), 0.0]),
            0 => ([0.0, 0.0], [0.0, 0.0]),
            1 => (g, p),
            2 => {
                let wt = g[1].min(0.0);
                ([g[0], wt], [p[0], if wt != 0.0 { p[1].min(0.0) } else { 0.0 }])
            }
            _ => {
                let wt = g[1].max(0.0);
                ([g[0], wt], [p[0], if wt != 0.0 { p[1].max(0.0) } else { 0.0 }])
            }
        };
        if mu[a] == 0.0 {
            wa[1] = 0.0;
            za[1] = 0.0;
        }
        w[a] = wa;
        z[a] = za;
    }
}
