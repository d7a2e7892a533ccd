// u = B v + q, one invocation per contact: the relative velocity (u_n, u_t) of each contact.
// CPU mirror: src/gpu/cpu/contact_gather.rs

override ROTATION: bool = true;
override FRICTION: bool = true;

struct Contact {
    n: vec2<f32>,
    i: u32,
    j: u32,
    levers: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> contacts: array<Contact>;
@group(0) @binding(1) var<storage, read> v: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> q: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> u: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    // Past 65,535 workgroups the dispatch is a 2D grid of rows (kernels.rs `dispatch`).
    let gid = vec3<u32>(grid.x + grid.y * groups.x * 64u, 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&q)) {
        return;
    }
    let c = contacts[a];
    let vi = v[c.i];
    var dv = vi.xy;
    var wj = 0.0;
    if (c.j != 0xffffffffu) {
        let vj = v[c.j];
        dv = dv - vj.xy;
        wj = vj.z;
    }
    var un = dot(c.n, dv);
    var ut = 0.0;
    if (FRICTION) {
        ut = dot(vec2<f32>(-c.n.y, c.n.x), dv);
    }
    if (ROTATION) {
        un = un + c.levers.x * vi.z - c.levers.z * wj;
        if (FRICTION) {
            ut = ut + c.levers.y * vi.z - c.levers.w * wj;
        }
    }
    u[a] = vec2<f32>(un, ut) + q[a];
}
