// u = W r + q for an explicit 2×2-block sparse W (problems read from files), one invocation per
// block row. CPU mirror: src/gpu/cpu/bsr_product.rs

#import grid

@group(0) @binding(0) var<storage, read> row_ptr: array<u32>;
@group(0) @binding(1) var<storage, read> cols: array<u32>;
@group(0) @binding(2) var<storage, read> blocks: array<vec4<f32>>; // (nn, nt, tn, tt)
@group(0) @binding(3) var<storage, read> r: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> q: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read_write> u: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&q)) {
        return;
    }
    var acc = q[a];
    for (var k = row_ptr[a]; k < row_ptr[a + 1u]; k = k + 1u) {
        let w = blocks[k];
        let rb = r[cols[k]];
        acc = acc + vec2<f32>(w.x * rb.x + w.y * rb.y, w.z * rb.x + w.w * rb.y);
    }
    u[a] = acc;
}
