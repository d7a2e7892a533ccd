// The scalar steps of CPG/PCPG (notes §4.2), one invocation. Slots of `scalars`:
// 0 u·d, 1 u·w, 2 d·Wd, 3 changed faces, 4 Wd·w, 5 num, 6 α, 7 β, 8 restart.
// stage 0: restart from the projected gradient when −u·d ≤ 0 (d is no descent direction);
// stage 1: α = num / d·Wd; stage 2: β = −Wd·w / d·Wd, or 0 when the active set moved.
// CPU mirror: src/gpu/cpu/cpg_scalars.rs

@group(0) @binding(0) var<storage, read_write> scalars: array<f32>;
@group(0) @binding(1) var<uniform> stage: vec4<u32>;

@compute @workgroup_size(1)
fn main() {
    if (stage.x == 0u) {
        let num1 = -scalars[0];
        let restart = num1 <= 0.0;
        scalars[8] = select(0.0, 1.0, restart);
        scalars[5] = select(num1, -scalars[1], restart);
    } else if (stage.x == 1u) {
        let num = scalars[5];
        let delta = scalars[2];
        scalars[6] = select(0.0, num / delta, num > 0.0 && delta > 0.0);
    } else {
        let delta = scalars[2];
        scalars[7] = select(-scalars[4] / delta, 0.0, scalars[3] > 0.0 || !(delta > 0.0));
    }
}
