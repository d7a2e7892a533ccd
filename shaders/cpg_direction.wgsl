// d ← w + β z. CPU mirror: src/gpu/cpu/cpg_direction.rs

@group(0) @binding(0) var<storage, read> scalars: array<f32>;
@group(0) @binding(1) var<storage, read> w: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> z: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> d: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let a = gid.x;
    if (a >= arrayLength(&w)) {
        return;
    }
    d[a] = w[a] + scalars[7] * z[a];
}
