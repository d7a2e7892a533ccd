// APGD gradient step (notes §6.4): next = Π_box(y − g / L) on the Tresca box r_n ≥ 0,
// |r_t| ≤ s, and diff = next − γ for the restart test. g = W y + q comes from the operator.
// scalars: 0 g·diff, 1 θ, 2 β, 3 restart, 4 1/L. CPU mirror: src/gpu/cpu/apgd_step.rs

#import grid

@group(0) @binding(0) var<storage, read> scalars: array<f32>;
@group(0) @binding(1) var<storage, read> g: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> y: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> gamma: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> s: array<f32>;
@group(0) @binding(5) var<storage, read_write> next: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read_write> diff: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&s)) {
        return;
    }
    let x = y[a] - scalars[4] * g[a];
    let n = vec2<f32>(max(x.x, 0.0), clamp(x.y, -s[a], s[a]));
    next[a] = n;
    diff[a] = n - gamma[a];
}
