// The item an element-wise invocation works on: past 65,535 workgroups of 64 the dispatch is a
// 2D grid of rows (kernels.rs `dispatch`), numbered row by row.
fn element_index(grid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return grid.x + grid.y * groups.x * 64u;
}
