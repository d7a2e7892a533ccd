//! Mirror of `shaders/jacobi_update.wgsl`: `r ← Π_K(r − η (u_n + μ|u_t|, u_t))` per contact.

fn project_cone(x: [f32; 2], m: f32) -> [f32; 2] {
    if x[0] >= 0.0 && x[1].abs() <= m * x[0] {
        x
    } else if m * x[1].abs() <= -x[0] {
        [0.0, 0.0]
    } else {
        let rn = (x[0] + m * x[1].abs()) / (1.0 + m * m);
        [rn, x[1].signum() * m * rn]
    }
}

pub fn jacobi_update(u: &[[f32; 2]], mu: &[f32], step: &[f32], r: &mut [[f32; 2]]) {
    for a in 0..mu.len() {
        let (ua, m, s) = (u[a], mu[a], step[a]);
        let x = [r[a][0] - s * (ua[0] + m * ua[1].abs()), r[a][1] - s * ua[1]];
        r[a] = project_cone(x, m);
    }
}
