// First pass of a deterministic dot product: workgroup g sums a[i]·b[i] over its chunk of
// 1024 entries in a fixed order (4 strided loads per thread, then a fixed tree), writing
// partials[g]. No atomics: the result does not depend on scheduling.
// CPU mirror: src/gpu/cpu/reduce_dot.rs

#import tree_sum

const PER_THREAD: u32 = 4u;

@group(0) @binding(0) var<storage, read> a: array<f32>;
@group(0) @binding(1) var<storage, read> b: array<f32>;
@group(0) @binding(2) var<storage, read_write> partials: array<f32>;
@group(0) @binding(3) var<uniform> len: vec4<u32>; // x: number of entries

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let n = len.x;
    let base = wid.x * WG * PER_THREAD;
    var s = 0.0;
    for (var k = 0u; k < PER_THREAD; k = k + 1u) {
        let i = base + k * WG + lid.x;
        if (i < n) {
            s = s + a[i] * b[i];
        }
    }
    let total = tree_sum(lid.x, s);
    if (lid.x == 0u) {
        partials[wid.x] = total;
    }
}
