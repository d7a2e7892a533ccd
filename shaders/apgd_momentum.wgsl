// APGD momentum: y = next (restart) or next + β (next − γ); then γ = next.
// CPU mirror: src/gpu/cpu/apgd_momentum.rs

@group(0) @binding(0) var<storage, read> scalars: array<f32>;
@group(0) @binding(1) var<storage, read> next: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> gamma: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> y: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    // Past 65,535 workgroups the dispatch is a 2D grid of rows (kernels.rs `dispatch`).
    let gid = vec3<u32>(grid.x + grid.y * groups.x * 64u, 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&next)) {
        return;
    }
    let n = next[a];
    if (scalars[3] > 0.0) {
        y[a] = n;
    } else {
        y[a] = n + scalars[2] * (n - gamma[a]);
    }
    gamma[a] = n;
}
