// v = M⁻¹ Bᵀ r, one invocation per body. Each body sums the impulses of its own contacts, read
// from a body→contact list in contact order: deterministic, no float atomics.
// CPU mirror: src/gpu/cpu/body_accumulate.rs

#import grid
#import contact
#import masses

@group(0) @binding(0) var<storage, read> contacts: array<Contact>;
@group(0) @binding(1) var<storage, read> body_start: array<u32>;
@group(0) @binding(2) var<storage, read> body_list: array<u32>; // contact index, top bit set when the body is j
@group(0) @binding(3) var<storage, read> inv_mass: array<vec2<f32>>; // (1/m, 1/I), held axes in the sign bits
@group(0) @binding(4) var<storage, read> r: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read_write> v: array<vec4<f32>>; // (v_x, v_y, ω, 0)

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let k = gid.x;
    if (k >= arrayLength(&inv_mass)) {
        return;
    }
    var p = vec2<f32>(0.0, 0.0);
    var torque = 0.0;
    for (var e = body_start[k]; e < body_start[k + 1u]; e = e + 1u) {
        let entry = body_list[e];
        let a = entry & 0x7fffffffu;
        let is_j = (entry >> 31u) == 1u;
        let c = contacts[a];
        let ra = r[a];
        let s = select(1.0, -1.0, is_j);
        var f = ra.x * c.n;
        if (FRICTION) {
            f = f + ra.y * vec2<f32>(-c.n.y, c.n.x);
        }
        p = p + s * f;
        if (ROTATION) {
            let g = select(c.levers.xy, c.levers.zw, is_j);
            var tq = ra.x * g.x;
            if (FRICTION) {
                tq = tq + ra.y * g.y;
            }
            torque = torque + s * tq;
        }
    }
    let im = inverse_masses(inv_mass[k]);
    v[k] = vec4<f32>(im.x * p.x, im.y * p.y, im.z * torque, 0.0);
}
