//! Mirror of `shaders/natural_map.wgsl`: per-contact F = r − Π_K(r − ũ).

use super::single_contact::project_cone;

/// The CPU mirror of `natural_map`: the same bindings and order of operations in f32.
pub fn natural_map(r: &[[f32; 2]], u: &[[f32; 2]], mu: &[f32], f: &mut [[f32; 2]]) {
    for a in 0..mu.len() {
        let (ra, ua, m) = (r[a], u[a], mu[a]);
        let p = project_cone([ra[0] - (ua[0] + m * ua[1].abs()), ra[1] - ua[1]], m);
        f[a] = [ra[0] - p[0], ra[1] - p[1]];
    }
}
