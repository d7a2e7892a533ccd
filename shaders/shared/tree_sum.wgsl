// A workgroup's sum in a fixed tree: the same bits whatever the scheduling (no atomics).
// Call from uniform control flow. CPU mirror: src/gpu/cpu/reduce_dot.rs.

const WG: u32 = 256u;

var<workgroup> tree: array<f32, 256>;

// The sum of every invocation's `s` (`lid`: its local index), returned to all of them.
fn tree_sum(lid: u32, s: f32) -> f32 {
    tree[lid] = s;
    workgroupBarrier();
    for (var half = WG / 2u; half > 0u; half = half / 2u) {
        if (lid < half) {
            tree[lid] = tree[lid] + tree[lid + half];
        }
        workgroupBarrier();
    }
    return tree[0];
}

// The largest of every invocation's `m` (`lid`: its local index), returned to all of them; a
// maximum is the same whatever the order. Shares the workgroup's `tree`.
fn tree_max(lid: u32, m: f32) -> f32 {
    tree[lid] = m;
    workgroupBarrier();
    for (var half = WG / 2u; half > 0u; half = half / 2u) {
        if (lid < half) {
            tree[lid] = max(tree[lid], tree[lid + half]);
        }
        workgroupBarrier();
    }
    return tree[0];
}
