// A contact of the matrix-free operator as src/gpu/operator.rs lays it out, its velocity, and
// the pipeline constants that compile rotation and friction out of a scene without them.
// CPU mirror: MatrixFree::gather_one (src/problem/matrix_free.rs).

override ROTATION: bool = true;
override FRICTION: bool = true;

// The antagonist of a contact with a fixed obstacle.
const NO_BODY: u32 = 0xffffffffu;

struct Contact {
    n: vec2<f32>,
    i: u32,
    j: u32,            // NO_BODY: a fixed obstacle
    levers: vec4<f32>, // (ρi×n, ρi×t, ρj×n, ρj×t)
}

// B_a v: the relative velocity (u_n, u_t) of contact c from the velocities (v_x, v_y, ω, 0) of
// its bodies (vj zero for a fixed obstacle); u_t = 0 without friction.
fn relative_velocity(c: Contact, vi: vec4<f32>, vj: vec4<f32>) -> vec2<f32> {
    let dv = vi.xy - vj.xy;
    var un = dot(c.n, dv);
    var ut = 0.0;
    if (FRICTION) {
        ut = dot(vec2<f32>(-c.n.y, c.n.x), dv);
    }
    if (ROTATION) {
        un = un + c.levers.x * vi.z - c.levers.z * vj.z;
        if (FRICTION) {
            ut = ut + c.levers.y * vi.z - c.levers.w * vj.z;
        }
    }
    return vec2<f32>(un, ut);
}

// A body→contact list entry (body_accumulate, jacobi_fused): the contact's index, and whether the
// body is the contact's j (the entry's top bit).
fn listed_contact(entry: u32) -> u32 {
    return entry & 0x7fffffffu;
}

fn listed_as_j(entry: u32) -> bool {
    return (entry >> 31u) == 1u;
}

// B_aᵀ r_a as one of contact c's bodies receives it, (p_x, p_y, torque): body i when `is_j` is
// false, body j (the opposite sign) when it is true.
fn contact_push(c: Contact, ra: vec2<f32>, is_j: bool) -> vec3<f32> {
    let s = select(1.0, -1.0, is_j);
    var f = ra.x * c.n;
    if (FRICTION) {
        f = f + ra.y * vec2<f32>(-c.n.y, c.n.x);
    }
    var tq = 0.0;
    if (ROTATION) {
        let g = select(c.levers.xy, c.levers.zw, is_j);
        tq = ra.x * g.x;
        if (FRICTION) {
            tq = tq + ra.y * g.y;
        }
    }
    return s * vec3<f32>(f, tq);
}
