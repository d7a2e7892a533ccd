// Exact single-contact 2D Coulomb solve in f32 (notes §2), imported by the NLGS kernels:
// open, stick trial, then the sliding edge that opposes the sliding velocity; when no candidate
// satisfies the law (μ|W_nt| ≥ W_nn) the one with the smallest natural-map residual.
// CPU mirror: src/gpu/cpu/single_contact.rs (and, in f64, src/problem/cone.rs).

fn sc_project_cone(x: vec2<f32>, m: f32) -> vec2<f32> {
    if (x.x >= 0.0 && abs(x.y) <= m * x.x) {
        return x;
    }
    if (m * abs(x.y) <= -x.x) {
        return vec2<f32>(0.0, 0.0);
    }
    let rn = (x.x + m * abs(x.y)) / (1.0 + m * m);
    return vec2<f32>(rn, sign(x.y) * m * rn);
}

fn sc_residual(w: vec4<f32>, q: vec2<f32>, m: f32, r: vec2<f32>) -> f32 {
    let u = vec2<f32>(w.x * r.x + w.y * r.y, w.z * r.x + w.w * r.y) + q;
    let ut = vec2<f32>(u.x + m * abs(u.y), u.y);
    let f = r - sc_project_cone(r - ut, m);
    return dot(f, f);
}

// The velocity test's term of one contact: |F(c r, u)|, F the natural map with De Saxcé's
// correction of the impulse turned into the velocity it would give the contact alone
// (c = W_aa,nn). Mirrors: src/gpu/cpu/single_contact.rs, and in f64
// problem::residual::contact_velocity_residual.
fn sc_velocity_residual(c: f32, r: vec2<f32>, u: vec2<f32>, m: f32) -> f32 {
    let cr = c * r;
    return length(cr - sc_project_cone(cr - vec2<f32>(u.x + m * abs(u.y), u.y), m));
}

// w = (W_nn, W_nt, W_tn, W_tt); q = velocity of the contact without its own impulse.
fn solve_single_contact(w: vec4<f32>, q: vec2<f32>, m: f32) -> vec2<f32> {
    if (q.x >= 0.0) {
        return vec2<f32>(0.0, 0.0);
    }
    if (m == 0.0) {
        return vec2<f32>(-q.x / w.x, 0.0);
    }
    let det = w.x * w.w - w.y * w.z;
    var first = select(1.0, -1.0, q.y > 0.0);
    var stick = vec2<f32>(0.0, 0.0);
    let has_stick = det > 1e-6 * abs(w.x * w.w);
    if (has_stick) {
        stick = vec2<f32>(-(w.w * q.x - w.y * q.y) / det, -(-w.z * q.x + w.x * q.y) / det);
        if (stick.x >= 0.0 && abs(stick.y) <= m * stick.x) {
            return stick;
        }
        first = select(-1.0, 1.0, stick.y > 0.0);
    }
    for (var k = 0; k < 2; k = k + 1) {
        let s = select(-first, first, k == 0);
        let denom = w.x + s * m * w.y;
        if (denom > 0.0) {
            let rn = -q.x / denom;
            let rt = s * m * rn;
            let ut = w.z * rn + w.w * rt + q.y;
            let scale = abs(q.y) + abs(w.z * rn) + abs(w.w * rt);
            if (s * ut <= 1e-6 * scale) {
                return vec2<f32>(rn, rt);
            }
        }
    }
    // Degenerate block: the best of the candidates.
    var best = vec2<f32>(0.0, 0.0);
    var best_e = sc_residual(w, q, m, best);
    if (has_stick) {
        let c = sc_project_cone(stick, m);
        let e = sc_residual(w, q, m, c);
        if (e < best_e) {
            best = c;
            best_e = e;
        }
    }
    for (var k = 0; k < 2; k = k + 1) {
        let s = select(-1.0, 1.0, k == 0);
        let denom = w.x + s * m * w.y;
        if (denom != 0.0) {
            let rn = abs(-q.x / denom);
            let c = sc_project_cone(vec2<f32>(rn, s * m * rn), m);
            let e = sc_residual(w, q, m, c);
            if (e < best_e) {
                best = c;
                best_e = e;
            }
        }
    }
    return best;
}
