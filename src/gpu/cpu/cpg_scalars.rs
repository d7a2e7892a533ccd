//! Mirror of `shaders/cpg_scalars.wgsl`. Slots: 0 u·d, 1 u·w, 2 d·Wd, 3 changed faces, 4 Wd·w,
//! 5 num, 6 α, 7 β, 8 restart.

/// The CPU mirror of `cpg_scalars`: the same bindings and order of operations in f32.
pub fn cpg_scalars(scalars: &mut [f32], stage: u32) {
    match stage {
        0 => {
            let num1 = -scalars[0];
            let restart = num1 <= 0.0;
            scalars[8] = if restart { 1.0 } else { 0.0 };
            scalars[5] = if restart { -scalars[1] } else { num1 };
        }
        1 => {
            let (num, delta) = (scalars[5], scalars[2]);
            scalars[6] = if num > 0.0 && delta > 0.0 { num / delta } else { 0.0 };
        }
        _ => {
            let delta = scalars[2];
            // delta ≤ 0 or NaN: no conjugation (as the kernel's `!(delta > 0.0)`).
            scalars[7] = if scalars[3] > 0.0 || delta.is_nan() || delta <= 0.0 { 0.0 } else { -scalars[4] / delta };
        }
    }
}
