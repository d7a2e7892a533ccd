// Anderson mixing, third stage, one invocation per contact, as anderson_fit decided:
// RESTART puts back the last sweep's plain output; RECORD keeps this sweep's residual and output
// as the last ones; PUSH also writes their differences into the ring slot; MIX then replaces
// the output by r − Σ γ_j Δr_j, landed on the cone. Whatever the action, the result is where
// the next sweep starts (`before`).
// CPU mirror: src/gpu/cpu/anderson_mix.rs

#import grid
#import single_contact
#import mixer

@group(0) @binding(0) var<storage, read_write> r: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read_write> before: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> last_residual: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> last_impulse: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> d_residual: array<vec2<f32>>; // slot j's contact a at j · nc + a
@group(0) @binding(5) var<storage, read_write> d_impulse: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read> mu: array<f32>;
@group(0) @binding(7) var<storage, read> mixer: Mixer;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let a = element_index(grid, groups);
    let nc = arrayLength(&mu);
    if (a >= nc) {
        return;
    }
    let action = mixer.action;
    var out = r[a];
    if (action == RESTART) {
        out = last_impulse[a];
    } else {
        let f = out - before[a];
        if (action != RECORD) {
            let slot = mixer.slot;
            let new_d_impulse = out - last_impulse[a];
            d_residual[slot * nc + a] = f - last_residual[a];
            d_impulse[slot * nc + a] = new_d_impulse;
            last_residual[a] = f;
            last_impulse[a] = out;
            if (action == MIX) {
                var x = out;
                for (var i = 0u; i < mixer.count; i = i + 1u) {
                    let j = mixer.order[i];
                    x = x - mixer.gamma[i] * select(d_impulse[j * nc + a], new_d_impulse, j == slot);
                }
                out = sc_project_cone(x, mu[a]);
            }
        } else {
            last_residual[a] = f;
            last_impulse[a] = out;
        }
    }
    r[a] = out;
    before[a] = out;
}
