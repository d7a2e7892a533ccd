// New Tresca thresholds s = μ max(γ_n, 0), γ projected on the new box, momentum restarted
// (y = γ, θ = 1). CPU mirror: src/gpu/cpu/apgd_rebox.rs

#import grid

@group(0) @binding(0) var<storage, read> mu: array<f32>;
@group(0) @binding(1) var<storage, read_write> gamma: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> y: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> s: array<f32>;
@group(0) @binding(4) var<storage, read_write> scalars: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a == 0u) {
        scalars[1] = 1.0;
    }
    if (a >= arrayLength(&mu)) {
        return;
    }
    let x = gamma[a];
    let rn = max(x.x, 0.0);
    let t = mu[a] * rn;
    let p = vec2<f32>(rn, clamp(x.y, -t, t));
    s[a] = t;
    gamma[a] = p;
    y[a] = p;
}
