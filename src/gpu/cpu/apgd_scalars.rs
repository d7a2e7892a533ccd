//! Mirror of `shaders/apgd_scalars.wgsl`: θ, β and the restart test.

/// The CPU mirror of `apgd_scalars`: the same bindings and order of operations in f32.
pub fn apgd_scalars(scalars: &mut [f32]) {
    let theta = scalars[1];
    let mut theta_next = 0.5 * (-theta * theta + theta * (theta * theta + 4.0).sqrt());
    let beta = theta * (1.0 - theta) / (theta * theta + theta_next);
    let restart = scalars[0] > 0.0;
    if restart {
        theta_next = 1.0;
    }
    scalars[1] = theta_next;
    scalars[2] = beta;
    scalars[3] = if restart { 1.0 } else { 0.0 };
}
