// APGD's scalar step, one invocation: restart when g·(next − γ) > 0 (O'Donoghue–Candès),
// else θ⁺ = (−θ² + θ √(θ² + 4)) / 2 and β = θ (1 − θ) / (θ² + θ⁺).
// scalars: 0 g·diff, 1 θ, 2 β, 3 restart. CPU mirror: src/gpu/cpu/apgd_scalars.rs

@group(0) @binding(0) var<storage, read_write> scalars: array<f32>;

@compute @workgroup_size(1)
fn main() {
    let theta = scalars[1];
    var theta_next = 0.5 * (-theta * theta + theta * sqrt(theta * theta + 4.0));
    let beta = theta * (1.0 - theta) / (theta * theta + theta_next);
    let restart = scalars[0] > 0.0;
    if (restart) {
        theta_next = 1.0;
    }
    scalars[1] = theta_next;
    scalars[2] = beta;
    scalars[3] = select(0.0, 1.0, restart);
}
