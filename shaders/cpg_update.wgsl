// r ← projection of r + α d on the box C(μ r̃_n) with status memory (LMGC90 `proj_cone`,
// notes §4.2); changed[a] = 1 when the contact's status moved. Status: 0 open, 1 stick,
// 2 slide r_t = +μ r_n, 3 slide r_t = −μ r_n. CPU mirror: src/gpu/cpu/cpg_update.rs

#import grid

@group(0) @binding(0) var<storage, read> scalars: array<f32>;
@group(0) @binding(1) var<storage, read> d: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> mu: array<f32>;
@group(0) @binding(3) var<storage, read_write> r: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> status: array<u32>;
@group(0) @binding(5) var<storage, read_write> changed: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&mu)) {
        return;
    }
    let alpha = scalars[6];
    let x = r[a] + alpha * d[a];
    let m = mu[a];
    let previous = status[a];
    var out = x;
    var st = 1u;
    if (x.x <= 0.0) {
        out = vec2<f32>(0.0, 0.0);
        st = 0u;
    } else if (m > 0.0 && x.y <= -m * x.x) {
        out = vec2<f32>(x.x, -m * x.x);
        st = 3u;
    } else if (m > 0.0 && x.y >= m * x.x) {
        out = vec2<f32>(x.x, m * x.x);
        st = 2u;
    } else if (m == 0.0) {
        out = vec2<f32>(x.x, 0.0);
    } else if (d[a].y == 0.0 && previous == 2u) {
        out = vec2<f32>(x.x, m * x.x);
        st = 2u;
    } else if (d[a].y == 0.0 && previous == 3u) {
        out = vec2<f32>(x.x, -m * x.x);
        st = 3u;
    }
    r[a] = out;
    changed[a] = select(0.0, 1.0, st != previous);
    status[a] = st;
}
