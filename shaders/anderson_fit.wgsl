// Anderson mixing, second stage (one workgroup): sums the partials of anderson_dots in a fixed
// order, then one invocation runs the mixer's logic as src/solvers/anderson.rs does on the CPU:
// - a mixed iterate whose sweep residual exceeds the reference is dropped (RESTART: back to the
//   last sweep's plain output, history forgotten);
// - the first sweep after a restart only records its residual and output (RECORD);
// - otherwise the new differences take a ring slot, the Gram matrix gains their row, and
//   γ = argmin ‖f − Σ γ_j Δf_j‖ by Cholesky on the normal equations (MIX), or no mixing when
//   they are singular (PUSH).
// It writes the decision for anderson_mix and the dispatch of the velocities' rebuild (the
// whole grid after RESTART or MIX, none otherwise).
// CPU mirror: src/gpu/cpu/anderson_fit.rs

#import mixer

const MAX_SUMS: u32 = 19u;
// The normal equations' diagonal shift, relative to their largest diagonal entry: f32's
// counterpart of the CPU's 1e-10.
const SHIFT: f32 = 1e-6;

@group(0) @binding(0) var<storage, read> partials: array<f32>;
@group(0) @binding(1) var<storage, read_write> mixer: Mixer;
@group(0) @binding(2) var<storage, read_write> rebuild: array<u32>; // (x, y, z) workgroups
@group(0) @binding(3) var<uniform> job: vec4<u32>; // x: partials' workgroups, y: depth, (z, w): rebuild grid

var<workgroup> total: array<f32, MAX_SUMS>;

@compute @workgroup_size(64)
fn main(@builtin(local_invocation_id) lid: vec3<u32>) {
    let depth = job.y;
    let sums = 3u + 2u * depth;
    if (lid.x < sums) {
        var s = 0.0;
        for (var g = 0u; g < job.x; g = g + 1u) {
            s = s + partials[g * sums + lid.x];
        }
        total[lid.x] = s;
    }
    workgroupBarrier();
    if (lid.x != 0u) {
        return;
    }
    let norm = sqrt(total[0]);
    var action = RECORD;
    if (mixer.mixed == 1u && norm > mixer.reference) {
        action = RESTART;
        mixer.count = 0u;
        mixer.has_last = 0u;
        mixer.mixed = 0u;
        mixer.restarts = mixer.restarts + 1u;
    } else {
        if (mixer.mixed == 1u) {
            mixer.reference = norm;
        } else {
            mixer.reference = min(mixer.reference, norm);
        }
        if (mixer.has_last == 0u) {
            mixer.has_last = 1u;
            mixer.mixed = 0u;
        } else {
            action = push_and_fit(depth);
        }
    }
    mixer.action = action;
    let rebuild_all = action == RESTART || action == MIX;
    rebuild[0] = select(0u, job.z, rebuild_all);
    rebuild[1] = select(1u, job.w, rebuild_all);
    rebuild[2] = 1u;
}

// Takes a ring slot for the new differences, updates the Gram matrix, fits γ: MIX or PUSH.
fn push_and_fit(depth: u32) -> u32 {
    var slot = mixer.count;
    if (mixer.count == depth) {
        slot = mixer.order[0];
        for (var i = 1u; i < depth; i = i + 1u) {
            mixer.order[i - 1u] = mixer.order[i];
        }
        mixer.count = depth - 1u;
    }
    for (var i = 0u; i < mixer.count; i = i + 1u) {
        let j = mixer.order[i];
        let g = total[3u + j];
        mixer.gram[slot * depth + j] = g;
        mixer.gram[j * depth + slot] = g;
    }
    mixer.gram[slot * depth + slot] = total[1];
    mixer.order[mixer.count] = slot;
    mixer.count = mixer.count + 1u;
    mixer.slot = slot;
    // The normal equations over the slots in use, oldest first: A γ = b with b_i = Δf_i · f.
    let m = mixer.count;
    var a: array<f32, 64>;
    var b: array<f32, MAX_DEPTH>;
    var largest = 0.0;
    for (var i = 0u; i < m; i = i + 1u) {
        let si = mixer.order[i];
        for (var j = 0u; j < m; j = j + 1u) {
            a[i * MAX_DEPTH + j] = mixer.gram[si * depth + mixer.order[j]];
        }
        b[i] = select(total[3u + depth + si], total[2], si == slot);
        largest = max(largest, a[i * MAX_DEPTH + i]);
    }
    for (var i = 0u; i < m; i = i + 1u) {
        a[i * MAX_DEPTH + i] = a[i * MAX_DEPTH + i] + SHIFT * largest;
    }
    // Cholesky, lower triangle in place.
    for (var i = 0u; i < m; i = i + 1u) {
        for (var j = 0u; j <= i; j = j + 1u) {
            var s = a[i * MAX_DEPTH + j];
            for (var k = 0u; k < j; k = k + 1u) {
                s = s - a[i * MAX_DEPTH + k] * a[j * MAX_DEPTH + k];
            }
            if (i == j) {
                if (!(s > 0.0)) {
                    mixer.mixed = 0u;
                    return PUSH;
                }
                a[i * MAX_DEPTH + i] = sqrt(s);
            } else {
                a[i * MAX_DEPTH + j] = s / a[j * MAX_DEPTH + j];
            }
        }
    }
    var y: array<f32, MAX_DEPTH>;
    for (var i = 0u; i < m; i = i + 1u) {
        var s = b[i];
        for (var k = 0u; k < i; k = k + 1u) {
            s = s - a[i * MAX_DEPTH + k] * y[k];
        }
        y[i] = s / a[i * MAX_DEPTH + i];
    }
    var finite = true;
    for (var step = 0u; step < m; step = step + 1u) {
        let i = m - 1u - step;
        var s = y[i];
        for (var k = i + 1u; k < m; k = k + 1u) {
            s = s - a[k * MAX_DEPTH + i] * mixer.gamma[k];
        }
        let x = s / a[i * MAX_DEPTH + i];
        // f32 has no isFinite: a NaN fails the comparison, an infinity exceeds the largest float.
        finite = finite && abs(x) <= 3.4e38;
        mixer.gamma[i] = x;
    }
    if (!finite) {
        mixer.mixed = 0u;
        return PUSH;
    }
    mixer.mixed = 1u;
    return MIX;
}
