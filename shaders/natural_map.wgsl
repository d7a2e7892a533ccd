// Per-contact natural-map residual F = r − Π_K(r − ũ), ũ = (u_n + μ|u_t|, u_t) (notes §7.1), for
// the on-GPU estimate of the error: the driver reduces |F|², |r|², |u|² with reduce_dot and reads
// back three numbers instead of r.
// CPU mirror: src/gpu/cpu/natural_map.rs

#import grid
#import single_contact

@group(0) @binding(0) var<storage, read> r: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read> u: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> mu: array<f32>;
@group(0) @binding(3) var<storage, read_write> f: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&mu)) {
        return;
    }
    let m = mu[a];
    let ua = u[a];
    let ra = r[a];
    f[a] = ra - sc_project_cone(ra - vec2<f32>(ua.x + m * abs(ua.y), ua.y), m);
}
