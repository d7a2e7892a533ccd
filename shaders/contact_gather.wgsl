// u = B v + q, one invocation per contact: the relative velocity (u_n, u_t) of each contact.
// CPU mirror: src/gpu/cpu/contact_gather.rs

#import grid
#import contact

@group(0) @binding(0) var<storage, read> contacts: array<Contact>;
@group(0) @binding(1) var<storage, read> v: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> q: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> u: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&q)) {
        return;
    }
    let c = contacts[a];
    var vj = vec4<f32>(0.0);
    if (c.j != NO_BODY) {
        vj = v[c.j];
    }
    u[a] = relative_velocity(c, v[c.i], vj) + q[a];
}
