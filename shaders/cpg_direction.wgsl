// d ← w + β z. CPU mirror: src/gpu/cpu/cpg_direction.rs

#import grid

@group(0) @binding(0) var<storage, read> scalars: array<f32>;
@group(0) @binding(1) var<storage, read> w: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> z: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> d: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&w)) {
        return;
    }
    d[a] = w[a] + scalars[7] * z[a];
}
