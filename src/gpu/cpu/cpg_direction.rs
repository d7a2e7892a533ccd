//! Mirror of `shaders/cpg_direction.wgsl`: d ← w + β z.

/// The CPU mirror of `cpg_direction`: the same bindings and order of operations in f32.
pub fn cpg_direction(scalars: &[f32], w: &[[f32; 2]], z: &[[f32; 2]], d: &mut [[f32; 2]]) {
    let beta = scalars[7];
    for a in 0..w.len() {
        d[a] = [w[a][0] + beta * z[a][0], w[a][1] + beta * z[a][1]];
    }
}
