// One colour of a graph-coloured NLGS sweep on the matrix-free operator (notes §6.3): contacts of
// one colour share no moving body, so they are solved in parallel with exact Gauss–Seidel
// semantics (each by `nlgs_update`, shared/nlgs_update.wgsl).
// CPU mirror: src/gpu/cpu/nlgs_colour.rs

#import grid
#import single_contact
#import contact
#import range
#import nlgs_update

@group(0) @binding(0) var<storage, read> contacts: array<Contact>;
@group(0) @binding(1) var<storage, read> inv_mass: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> diag: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> q: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> mu: array<f32>;
@group(0) @binding(5) var<storage, read> order: array<u32>;
@group(0) @binding(6) var<storage, read_write> r: array<vec2<f32>>;
@group(0) @binding(7) var<storage, read_write> v: array<vec4<f32>>;
@group(0) @binding(8) var<uniform> range: Range;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    if (gid.x >= range.count) {
        return;
    }
    nlgs_update(order[range.start + gid.x], range.threshold);
}
