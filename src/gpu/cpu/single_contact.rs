//! Mirror of `shaders/shared/single_contact.wgsl`: the exact single-contact solve in f32.

/// The projection on the cone of friction `m`, in f32 as the kernels do it.
pub fn project_cone(x: [f32; 2], m: f32) -> [f32; 2] {
    if x[0] >= 0.0 && x[1].abs() <= m * x[0] {
        x
    } else if m * x[1].abs() <= -x[0] {
        [0.0, 0.0]
    } else {
        let rn = (x[0] + m * x[1].abs()) / (1.0 + m * m);
        [rn, wgsl_sign(x[1]) * m * rn]
    }
}

/// WGSL's `sign` (0 at 0), unlike `f32::signum`.
fn wgsl_sign(x: f32) -> f32 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// The velocity test's term of one contact in f32, as the kernels take it: `|F(c r, u)|`, F the
/// natural map with De Saxcé's correction, `c = W_aa,nn`.
pub fn velocity_residual(c: f32, r: [f32; 2], u: [f32; 2], m: f32) -> f32 {
    let cr = [c * r[0], c * r[1]];
    let p = project_cone([cr[0] - (u[0] + m * u[1].abs()), cr[1] - u[1]], m);
    let f = [cr[0] - p[0], cr[1] - p[1]];
    (f[0] * f[0] + f[1] * f[1]).sqrt()
}

fn residual(w: [f32; 4], q: [f32; 2], m: f32, r: [f32; 2]) -> f32 {
    let u = [w[0] * r[0] + w[1] * r[1] + q[0], w[2] * r[0] + w[3] * r[1] + q[1]];
    let ut = [u[0] + m * u[1].abs(), u[1]];
    let p = project_cone([r[0] - ut[0], r[1] - ut[1]], m);
    let f = [r[0] - p[0], r[1] - p[1]];
    f[0] * f[0] + f[1] * f[1]
}

/// The exact single-contact solve in f32, as the kernels do it.
pub fn solve_single_contact(w: [f32; 4], q: [f32; 2], m: f32) -> [f32; 2] {
    if q[0] >= 0.0 {
        return [0.0, 0.0];
    }
    if m == 0.0 {
        return [-q[0] / w[0], 0.0];
    }
    let det = w[0] * w[3] - w[1] * w[2];
    let mut first = if q[1] > 0.0 { -1.0f32 } else { 1.0 };
    let mut stick = [0.0f32; 2];
    let has_stick = det > 1e-6 * (w[0] * w[3]).abs();
    if has_stick {
        stick = [-(w[3] * q[0] - w[1] * q[1]) / det, -(-w[2] * q[0] + w[0] * q[1]) / det];
        if stick[0] >= 0.0 && stick[1].abs() <= m * stick[0] {
            return stick;
        }
        first = if stick[1] > 0.0 { 1.0 } else { -1.0 };
    }
    for s in [first, -first] {
        let denom = w[0] + s * m * w[1];
        if denom > 0.0 {
            let rn = -q[0] / denom;
            let rt = s * m * rn;
            let ut = w[2] * rn + w[3] * rt + q[1];
            let scale = q[1].abs() + (w[2] * rn).abs() + (w[3] * rt).abs();
            if s * ut <= 1e-6 * scale {
                return [rn, rt];
            }
        }
    }
    let mut best = [0.0f32; 2];
    let mut best_e = residual(w, q, m, best);
    if has_stick {
        let c = project_cone(stick, m);
        let e = residual(w, q, m, c);
        if e < best_e {
            (best, best_e) = (c, e);
        }
    }
    for s in [1.0f32, -1.0] {
        let denom = w[0] + s * m * w[1];
        if denom != 0.0 {
            let rn = (-q[0] / denom).abs();
            let c = project_cone([rn, s * m * rn], m);
            let e = residual(w, q, m, c);
            if e < best_e {
                (best, best_e) = (c, e);
            }
        }
    }
    best
}
