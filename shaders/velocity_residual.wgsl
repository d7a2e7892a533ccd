// The on-GPU estimate of the velocity measure (the stopping test of `criterion = "velocity"` and
// "step-velocity"), in one pass: workgroup g takes the largest |F(c r_a, u_a)| over its chunk of
// 1,024 contacts, F the natural map of the contact's impulse turned into the velocity it would
// give the contact alone (c = W_aa,nn), and writes it to partials[g].x; the driver reads the
// partials back and takes the largest. WGSL may assume no NaN and a maximum may drop one, so
// partials[g].y sums |r| + |u| over the chunk in a fixed tree: a diverged iterate shows there,
// and the check needs no natural-map sums beside it.
// CPU mirror: src/gpu/cpu/velocity_residual.rs

#import tree_sum
#import single_contact

const PER_THREAD: u32 = 4u;

@group(0) @binding(0) var<storage, read> r: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read> u: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> mu: array<f32>;
@group(0) @binding(3) var<storage, read> c: array<f32>;
@group(0) @binding(4) var<storage, read_write> partials: array<vec2<f32>>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let n = arrayLength(&mu);
    let base = wid.x * WG * PER_THREAD;
    var worst = 0.0;
    var witness = 0.0;
    for (var k = 0u; k < PER_THREAD; k = k + 1u) {
        let a = base + k * WG + lid.x;
        if (a < n) {
            worst = max(worst, sc_velocity_residual(c[a], r[a], u[a], mu[a]));
            let size = abs(r[a]) + abs(u[a]);
            witness = witness + (size.x + size.y);
        }
    }
    let largest = tree_max(lid.x, worst);
    // Every invocation has read tree_max's answer before tree_sum writes the tree again.
    workgroupBarrier();
    let sum = tree_sum(lid.x, witness);
    if (lid.x == 0u) {
        partials[wid.x] = vec2<f32>(largest, sum);
    }
}
