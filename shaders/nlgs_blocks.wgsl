// A block sweep of graph-coloured NLGS on the matrix-free operator: each workgroup takes one
// block of contacts (contiguous in the contacts' spatial order) and sweeps it `inner` times,
// colour by colour, with a barrier between colours; the blocks of one dispatch share no moving
// body. One dispatch thus does `inner` sweeps of its blocks where colour sweeps need a dispatch
// per colour and sweep: a disturbance crosses a block within the dispatch, and a GPU step that
// waits on its dispatches' latency makes fewer of them.
// CPU mirror: src/gpu/cpu/nlgs_blocks.rs

#import single_contact
#import contact
#import masses
#import nlgs_update

// The blocks of one block colour: `count` entries of `block_order` from `first`, each swept
// `inner` times over its `colours` colour ranges; `threshold` as for colour sweeps.
struct Blocks {
    first: u32,
    count: u32,
    threshold: f32,
    inner: u32,
    colours: u32,
}

// Bindings 0–7: nlgs_update's (`order`: every contact, block by block, colour by colour).
@group(0) @binding(8) var<storage, read> colour_start: array<u32>;
@group(0) @binding(9) var<storage, read> block_order: array<u32>;
@group(0) @binding(10) var<uniform> blocks: Blocks;

const BLOCK_WORKGROUP: u32 = 256u;

@compute @workgroup_size(256)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let base = block_order[blocks.first + group.x] * (blocks.colours + 1u);
    for (var sweep = 0u; sweep < blocks.inner; sweep++) {
        for (var c = 0u; c < blocks.colours; c++) {
            let end = colour_start[base + c + 1u];
            for (var k = colour_start[base + c] + lane; k < end; k += BLOCK_WORKGROUP) {
                _ = nlgs_update(order[k], blocks.threshold);
            }
            // The colour's updates, in v and r, seen by the whole workgroup before the next.
            storageBarrier();
            workgroupBarrier();
        }
    }
}
