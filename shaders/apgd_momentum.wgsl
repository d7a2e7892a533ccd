// APGD momentum: y = next (restart) or next + β (next − γ); then γ = next.
// CPU mirror: src/gpu/cpu/apgd_momentum.rs

#import grid

@group(0) @binding(0) var<storage, read> scalars: array<f32>;
@group(0) @binding(1) var<storage, read> next: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> gamma: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> y: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
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
