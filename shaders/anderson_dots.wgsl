// Anderson mixing of the NLGS sweeps (notes §6; CPU: src/solvers/anderson.rs), first stage:
// per workgroup of 1,024 entries, the partial sums of every dot product the fit needs. With
// f = r − before (this sweep's residual) and d = f − last_residual (its change since the last
// sweep): f·f, d·d, d·f, then d·Δf_j and f·Δf_j for each of the `depth` history slots j. Nothing
// else is written: anderson_fit decides what the history keeps, anderson_mix writes it.
// CPU mirror: src/gpu/cpu/anderson_dots.rs

#import tree_sum

const PER_THREAD: u32 = 4u;
// 3 + 2 · the deepest history the GPU mixes (backend::GPU_MAX_ANDERSON = 8).
const MAX_SUMS: u32 = 19u;

@group(0) @binding(0) var<storage, read> r: array<f32>;
@group(0) @binding(1) var<storage, read> before: array<f32>;
@group(0) @binding(2) var<storage, read> last_residual: array<f32>;
@group(0) @binding(3) var<storage, read> d_residual: array<f32>; // slot j's entry i at j · n + i
@group(0) @binding(4) var<storage, read_write> partials: array<f32>; // workgroup g's sum c at g · sums + c
@group(0) @binding(5) var<uniform> shape: vec4<u32>; // x: n entries, y: depth

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let n = shape.x;
    let depth = shape.y;
    let sums = 3u + 2u * depth;
    var s: array<f32, MAX_SUMS>;
    let base = wid.x * WG * PER_THREAD;
    for (var k = 0u; k < PER_THREAD; k = k + 1u) {
        let i = base + k * WG + lid.x;
        if (i < n) {
            let f = r[i] - before[i];
            let d = f - last_residual[i];
            s[0] = s[0] + f * f;
            s[1] = s[1] + d * d;
            s[2] = s[2] + d * f;
            for (var j = 0u; j < depth; j = j + 1u) {
                let h = d_residual[j * n + i];
                s[3u + j] = s[3u + j] + d * h;
                s[3u + depth + j] = s[3u + depth + j] + f * h;
            }
        }
    }
    for (var c = 0u; c < sums; c = c + 1u) {
        let total = tree_sum(lid.x, s[c]);
        if (lid.x == 0u) {
            partials[wid.x * sums + c] = total;
        }
        // Every invocation has read the tree before the next sum overwrites it.
        workgroupBarrier();
    }
}
