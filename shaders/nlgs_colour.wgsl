// One colour of a graph-coloured NLGS sweep on the matrix-free operator (notes §6.3): contacts of
// one colour share no moving body, so they are solved in parallel with exact Gauss–Seidel
// semantics (each by `nlgs_update`, shared/nlgs_update.wgsl).
// CPU mirror: src/gpu/cpu/nlgs_colour.rs

#import grid
#import single_contact
#import contact
#import range
#import masses
#import nlgs_update

// Bindings 0–7: nlgs_update's.
@group(0) @binding(8) var<uniform> range: Range;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    if (gid.x >= range.count) {
        return;
    }
    nlgs_update(order[range.start + gid.x], range.threshold);
}
