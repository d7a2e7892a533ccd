// Second pass of a deterministic dot product: one workgroup sums the partials in a fixed order
// and writes scalars[slot]. CPU mirror: src/gpu/cpu/reduce_final.rs

const WG: u32 = 256u;

@group(0) @binding(0) var<storage, read> partials: array<f32>;
@group(0) @binding(1) var<storage, read_write> scalars: array<f32>;
@group(0) @binding(2) var<uniform> job: vec4<u32>; // x: number of partials, y: slot

var<workgroup> tree: array<f32, 256>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_id) lid: vec3<u32>) {
    var s = 0.0;
    for (var i = lid.x; i < job.x; i = i + WG) {
        s = s + partials[i];
    }
    tree[lid.x] = s;
    workgroupBarrier();
    for (var half = WG / 2u; half > 0u; half = half / 2u) {
        if (lid.x < half) {
            tree[lid.x] = tree[lid.x] + tree[lid.x + half];
        }
        workgroupBarrier();
    }
    if (lid.x == 0u) {
        scalars[job.y] = tree[0];
    }
}
