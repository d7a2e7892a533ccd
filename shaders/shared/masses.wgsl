// A body's inverse masses as the kernels read them: two f32, (1/m, 1/I), eight bytes a body. A
// body that holds its velocity along x or y (hold_velocity) has the sign bit of the first or the
// second entry set, and an inverse mass of zero along that axis; the others pay one `abs` and
// two selects, not a wider record.
// CPU mirror: src/gpu/cpu/mod.rs (inverse_masses)

// (1/m along x, 1/m along y, 1/I).
fn inverse_masses(packed: vec2<f32>) -> vec3<f32> {
    let m = abs(packed.x);
    let held_x = (bitcast<u32>(packed.x) >> 31u) == 1u;
    let held_y = (bitcast<u32>(packed.y) >> 31u) == 1u;
    return vec3<f32>(select(m, 0.0, held_x), select(m, 0.0, held_y), abs(packed.y));
}
