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
    var push = vec3<f32>(0.0);
    for (var e = body_start[k]; e < body_start[k + 1u]; e = e + 1u) {
        let a = listed_contact(body_list[e]);
        push = push + contact_push(contacts[a], r[a], listed_as_j(body_list[e]));
    }
    v[k] = vec4<f32>(inverse_masses(inv_mass[k]) * push, 0.0);
}
