//! Deterministic dot products on the GPU: `reduce_dot.wgsl` writes one partial sum per chunk of
//! 1,024 entries, `reduce_final.wgsl` sums them into a slot of a scalars buffer. Fixed order
//! throughout: the same inputs give the same bits on every run.

use super::context::GpuContext;
use super::cpu::reduce_dot::n_partials;
use super::kernels::{bind, dispatch, uniform, Kernels};
use super::pool::{BindGroup, GpuBuffer};

/// A bound dot product `scalars[slot] = a · b` over `n` f32 entries.
pub struct Dot {
    first: BindGroup,
    second: BindGroup,
    groups: u32,
    _uniforms: [GpuBuffer; 2],
}

impl Dot {
    /// Binds `a · b` over `n` entries into `scalars[slot]` (two passes through `partials`).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        ctx: &GpuContext,
        k: &Kernels,
        a: &GpuBuffer,
        b: &GpuBuffer,
        n: usize,
        partials: &GpuBuffer,
        scalars: &GpuBuffer,
        slot: u32,
    ) -> Self {
        let groups = n_partials(n) as u32;
        let len = uniform(ctx, "len", &[n as u32, 0, 0, 0]);
        let job = uniform(ctx, "job", &[groups, slot, 0, 0]);
        let first = bind(ctx, &k.reduce_dot, &[("a", a), ("b", b), ("partials", partials), ("len", &len)]);
        let second = bind(ctx, &k.reduce_final, &[("partials", partials), ("scalars", scalars), ("job", &job)]);
        Self { first, second, groups, _uniforms: [len, job] }
    }

    /// Records both passes.
    pub fn record(&self, k: &Kernels, pass: &mut wgpu::ComputePass) {
        dispatch(pass, &k.reduce_dot, &self.first, self.groups);
        dispatch(pass, &k.reduce_final, &self.second, 1);
    }
}

/// Entries of the partials buffer needed for `n` entries.
pub fn partials_len(n: usize) -> usize {
    n_partials(n)
}
