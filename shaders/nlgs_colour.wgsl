// One colour of a graph-coloured NLGS sweep on the matrix-free operator (notes §6.3): contacts of
// one colour share no moving body, so they are solved in parallel with exact Gauss–Seidel
// semantics (each by `nlgs_update`, shared/nlgs_update.wgsl). With a threshold (the work list's
// sweeps) the contacts updated are counted into `updates[0]`, once a workgroup: the solve's
// iterations then count sweeps' worth of updates, as the CPU's list does.
// CPU mirror: src/gpu/cpu/nlgs_colour.rs

#import grid
#import single_contact
#import contact
#import range
#import masses
#import nlgs_update

// Bindings 0–7: nlgs_update's.
@group(0) @binding(8) var<uniform> range: Range;
@group(0) @binding(9) var<storage, read_write> updates: array<atomic<u32>>;

var<workgroup> updated: atomic<u32>;

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) grid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let k = element_index(grid, groups);
    if (k < range.count && nlgs_update(order[range.start + k], range.threshold) && range.threshold > 0.0) {
        atomicAdd(&updated, 1u);
    }
    // One global atomic a workgroup, not one a contact.
    workgroupBarrier();
    if (lane == 0u) {
        let n = atomicLoad(&updated);
        if (n > 0u) {
            atomicAdd(&updates[0], n);
        }
    }
}
