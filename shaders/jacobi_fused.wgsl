// One projected-Jacobi iteration in one dispatch, one invocation per body (notes §6.2): for each
// contact in the body's list, u = B v + q from the velocities v_in, then r ← Π_K(r − η (u_n +
// μ|u_t|, u_t)) from r_in (contact_gather and jacobi_update, the same arithmetic), and the body's
// v_out = M⁻¹ Bᵀ r_out summed from the new impulses in its list's order (body_accumulate's sum).
// A contact between two bodies is updated by both to the same bits, and written by body i. Reading
// (r_in, v_in) and writing (r_out, v_out), an iteration needs no other pass: the solver alternates
// two pairs of buffers, where the three kernels are three dispatches an iteration.
// CPU mirror: src/gpu/cpu/jacobi_fused.rs

#import grid
#import single_contact
#import contact
#import masses

@group(0) @binding(0) var<storage, read> contacts: array<Contact>;
@group(0) @binding(1) var<storage, read> body_start: array<u32>;
@group(0) @binding(2) var<storage, read> body_list: array<u32>; // contact index, top bit set when the body is j
@group(0) @binding(3) var<storage, read> inv_mass: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> q: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read> mu: array<f32>;
@group(0) @binding(6) var<storage, read> step: array<f32>;
@group(0) @binding(7) var<storage, read> r_in: array<vec2<f32>>;
@group(0) @binding(8) var<storage, read> v_in: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> r_out: array<vec2<f32>>;
@group(0) @binding(10) var<storage, read_write> v_out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = element_index(grid, groups);
    if (k >= arrayLength(&inv_mass)) {
        return;
    }
    var push = vec3<f32>(0.0);
    for (var e = body_start[k]; e < body_start[k + 1u]; e = e + 1u) {
        let a = listed_contact(body_list[e]);
        let is_j = listed_as_j(body_list[e]);
        let c = contacts[a];
        var vj = vec4<f32>(0.0);
        if (c.j != NO_BODY) {
            vj = v_in[c.j];
        }
        let ua = relative_velocity(c, v_in[c.i], vj) + q[a];
        let m = mu[a];
        let rn = sc_project_cone(r_in[a] - step[a] * vec2<f32>(ua.x + m * abs(ua.y), ua.y), m);
        if (!is_j) {
            r_out[a] = rn;
        }
        push = push + contact_push(c, rn, is_j);
    }
    v_out[k] = vec4<f32>(inverse_masses(inv_mass[k]) * push, 0.0);
}
