// One contact's NLGS update on the matrix-free operator: its velocity from the body velocities
// v = M⁻¹ Bᵀ r, the single-contact solve, and the impulse change scattered into v. It declares
// the bindings every matrix-free NLGS kernel reads (0–7, the contacts' colour order among them);
// a kernel that imports it numbers its own from 8, and imports `masses` before it. The caller guarantees that no other invocation
// touches the contact's moving bodies meanwhile. With a threshold (the work list's sweeps), a
// contact whose residual in velocity units is within it is left alone: converged contacts do not
// drift; it returns whether it updated the contact (the work list's sweeps count their updates).
// CPU mirror: src/gpu/cpu/nlgs_colour.rs

@group(0) @binding(0) var<storage, read> contacts: array<Contact>;
@group(0) @binding(1) var<storage, read> inv_mass: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> diag: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> q: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> mu: array<f32>;
@group(0) @binding(5) var<storage, read> order: array<u32>;
@group(0) @binding(6) var<storage, read_write> r: array<vec2<f32>>;
@group(0) @binding(7) var<storage, read_write> v: array<vec4<f32>>;

fn scatter(k: u32, s: f32, f: vec2<f32>, torque: f32) {
    let packed = inv_mass[k];
    if (packed.x == 0.0 && packed.y == 0.0) {
        return; // a fixed body: several contacts of one colour may touch it
    }
    let im = inverse_masses(packed);
    var dv = v[k];
    dv = vec4<f32>(dv.x + s * im.x * f.x, dv.y + s * im.y * f.y, dv.z + s * im.z * torque, 0.0);
    v[k] = dv;
}

fn nlgs_update(a: u32, threshold: f32) -> bool {
    let c = contacts[a];
    let t = vec2<f32>(-c.n.y, c.n.x);
    var vj = vec4<f32>(0.0);
    if (c.j != NO_BODY) {
        vj = v[c.j];
    }
    let w = diag[a];
    let ra = r[a];
    let u = relative_velocity(c, v[c.i], vj) + q[a];
    if (threshold > 0.0 && sc_velocity_residual(w.x, ra, u, mu[a]) <= threshold) {
        return false;
    }
    let q_local = u - vec2<f32>(w.x * ra.x + w.y * ra.y, w.z * ra.x + w.w * ra.y);
    let rn = solve_single_contact(w, q_local, mu[a]);
    let d = rn - ra;
    r[a] = rn;
    var f = d.x * c.n;
    if (FRICTION) {
        f = f + d.y * t;
    }
    var ti = 0.0;
    var tj = 0.0;
    if (ROTATION) {
        ti = d.x * c.levers.x;
        tj = d.x * c.levers.z;
        if (FRICTION) {
            ti = ti + d.y * c.levers.y;
            tj = tj + d.y * c.levers.w;
        }
    }
    scatter(c.i, 1.0, f, ti);
    if (c.j != NO_BODY) {
        scatter(c.j, -1.0, f, tj);
    }
    return true;
}
