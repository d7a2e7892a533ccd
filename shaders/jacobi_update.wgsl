// Projected Jacobi update of every contact from u = W r + q (notes §6.2):
// r ← Π_K(r − η (u_n + μ|u_t|, u_t)), De Saxcé's ũ so the fixed point is exact Coulomb.
// CPU mirror: src/gpu/cpu/jacobi_update.rs

#import grid
#import single_contact

@group(0) @binding(0) var<storage, read> u: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read> mu: array<f32>;
@group(0) @binding(2) var<storage, read> step: array<f32>;
@group(0) @binding(3) var<storage, read_write> r: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&mu)) {
        return;
    }
    let ua = u[a];
    let m = mu[a];
    let x = r[a] - step[a] * vec2<f32>(ua.x + m * abs(ua.y), ua.y);
    r[a] = sc_project_cone(x, m);
}
