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
