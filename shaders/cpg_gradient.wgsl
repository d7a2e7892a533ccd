// Projection of the scaled negative gradient −s∘u and of the direction d onto the tangent cone
// of the box at r (LMGC90 `proj_facette`, notes §4.2), giving w and z.
// CPU mirror: src/gpu/cpu/cpg_gradient.rs

#import grid

@group(0) @binding(0) var<storage, read> u: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read> scale: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> d: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> status: array<u32>;
@group(0) @binding(4) var<storage, read> mu: array<f32>;
@group(0) @binding(5) var<storage, read_write> w: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read_write> z: array<vec2<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) grid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let gid = vec3<u32>(element_index(grid, groups), 0u, 0u);
    let a = gid.x;
    if (a >= arrayLength(&mu)) {
        return;
    }
    let g = -scale[a] * u[a];
    let p = d[a];
    var wa = vec2<f32>(0.0, 0.0);
    var za = vec2<f32>(0.0, 0.0);
    let st = status[a];
    if (st == 0u) {
        if (g.x > 0.0) {
            wa = vec2<f32>(g.x, 0.0);
            za = vec2<f32>(max(p.x, 0.0), 0.0);
        }
    } else if (st == 1u) {
        wa = g;
        za = p;
    } else if (st == 2u) {
        let wt = min(g.y, 0.0);
        wa = vec2<f32>(g.x, wt);
        za = vec2<f32>(p.x, select(0.0, min(p.y, 0.0), wt != 0.0));
    } else {
        let wt = max(g.y, 0.0);
        wa = vec2<f32>(g.x, wt);
        za = vec2<f32>(p.x, select(0.0, max(p.y, 0.0), wt != 0.0));
    }
    if (mu[a] == 0.0) {
        wa.y = 0.0;
        za.y = 0.0;
    }
    w[a] = wa;
    z[a] = za;
}
