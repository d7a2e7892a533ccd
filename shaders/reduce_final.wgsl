// Second pass of a deterministic dot product: one workgroup sums the partials in a fixed order
// and writes scalars[slot]. CPU mirror: src/gpu/cpu/reduce_final.rs

#import tree_sum

@group(0) @binding(0) var<storage, read> partials: array<f32>;
@group(0) @binding(1) var<storage, read_write> scalars: array<f32>;
@group(0) @binding(2) var<uniform> job: vec4<u32>; // x: number of partials, y: slot

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_id) lid: vec3<u32>) {
    var s = 0.0;
    for (var i = lid.x; i < job.x; i = i + WG) {
        s = s + partials[i];
    }
    let total = tree_sum(lid.x, s);
    if (lid.x == 0u) {
        scalars[job.y] = total;
    }
}
