// One colour of a graph-coloured NLGS sweep on an explicit block-sparse W (problem files):
// contacts of one colour have no W block between them, so each row reads only impulses that no
// other invocation of the dispatch writes.
// CPU mirror: src/gpu/cpu/nlgs_colour_bsr.rs

#import grid
#import single_contact
#import range

@group(0) @binding(0) var<storage, read> row_ptr: array<u32>;
@group(0) @binding(1) var<storage, read> cols: array<u32>;
@group(0) @binding(2) var<storage, read> blocks: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> diag: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> q: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read> mu: array<f32>;
@group(0) @binding(6) var<storage, read> order: array<u32>;
@group(0) @binding(7) var<storage, read_write> r: array<vec2<f32>>;
@group(0) @binding(8) var<uniform> range: Range;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    if (gid.x >= range.count) {
        return;
    }
    let a = order[range.start + gid.x];
    // Velocity of contact a without its own impulse: q + Σ_{b≠a} W_ab r_b.
    var q_local = q[a];
    for (var k = row_ptr[a]; k < row_ptr[a + 1u]; k = k + 1u) {
        let b = cols[k];
        if (b != a) {
            let w = blocks[k];
            let rb = r[b];
            q_local = q_local + vec2<f32>(w.x * rb.x + w.y * rb.y, w.z * rb.x + w.w * rb.y);
        }
    }
    r[a] = solve_single_contact(diag[a], q_local, mu[a]);
}
