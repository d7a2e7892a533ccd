//! Mirror of `shaders/cpg_restart.wgsl`: d ← w on a restart.

/// The CPU mirror of `cpg_restart`: the same bindings and order of operations in f32.
pub fn cpg_restart(scalars: &[f32], w: &[[f32; 2]], d: &mut [[f32; 2]]) {
    if scalars[8] != 0.0 {
        d.copy_from_slice(w);
    }
}
