//! Anderson acceleration of the GPU's NLGS sweeps (`anderson = m`, m ≤ [`MAX_DEPTH`]): the same
//! mixer as the CPU's (`src/solvers/anderson.rs`: type II over the last m sweeps, landed on the
//! cones, a mixing dropped when its sweep residual exceeds the reference), run after each
//! sweep without reading anything back:
//! - `anderson_dots`: the fit's dot products, partial sums per 1,024 entries;
//! - `anderson_fit` (one workgroup): the decision and the fit γ, in a small state buffer;
//! - `anderson_mix`: the history written and the next iterate, contact by contact;
//! - on a matrix-free `W`, the body velocities rebuilt from the impulses (`body_accumulate`)
//!   after a mixing or a restart only: a dispatch whose size the fit writes. The CPU mixes the
//!   velocities instead (linear in r); rebuilding them keeps no velocity history on the GPU and
//!   no round-off builds up.
//!
//! In f32 the fit's normal equations carry a relative shift of 1e-6 (the CPU's: 1e-10). Where
//! the sweeps converge slowly on large impulses the residuals' differences come near the rounding
//! of `r` (the settled 10,000-disk pile: |Δf| 2–13 × ε|r|); the mixing then stalls, and the
//! backend goes on with plain GPU sweeps (`backend::plain_after_mixing`, BENCHMARKS.md). On an
//! H100 a mixed sweep costs twice a plain one (the dots and the fit about 20 µs each).

use super::context::GpuContext;
use super::cpu::anderson_dots::{n_groups, n_sums};
use super::cpu::anderson_fit::Mixer;
pub use super::cpu::anderson_fit::MAX_DEPTH;
use super::kernels::{bind, dispatch, dispatch_indirect, grid, groups, indirect_args, read_back, storage, uniform};
use super::operator::GpuProblem;
use super::pool::{BindGroup, GpuBuffer};

/// The mixer's buffers and its three (or four) bound stages.
pub struct GpuAnderson {
    kernels: std::sync::Arc<super::kernels::Kernels>,
    dots: BindGroup,
    fit: BindGroup,
    mix: BindGroup,
    dot_groups: u32,
    contact_groups: u32,
    /// The velocities' rebuild (`body_accumulate`'s bind group), its dispatch's arguments, and
    /// its full size in workgroups.
    rebuild: Option<(BindGroup, GpuBuffer, u32)>,
    state: GpuBuffer,
    _buffers: Vec<GpuBuffer>,
}

impl GpuAnderson {
    /// A mixer over `depth` sweeps (1 ≤ depth ≤ [`MAX_DEPTH`]) of the impulses in `r_buf`, which
    /// hold `r` now; `velocities`: the sweep's body-velocity rebuild (bind group, bodies).
    pub fn new(
        ctx: &GpuContext,
        gp: &GpuProblem,
        r: &[[f32; 2]],
        r_buf: &GpuBuffer,
        depth: usize,
        velocities: Option<(&BindGroup, usize)>,
    ) -> Self {
        assert!((1..=MAX_DEPTH).contains(&depth), "the GPU mixes 1 to {MAX_DEPTH} sweeps, not {depth}");
        let kernels = gp.kernels.clone();
        let nc = r.len();
        let n = 2 * nc;
        let zeros = vec![[0.0f32; 2]; nc];
        let history = vec![[0.0f32; 2]; depth * nc];
        let before = storage(ctx, "anderson before", r);
        let last_residual = storage(ctx, "anderson last residual", &zeros);
        let last_impulse = storage(ctx, "anderson last impulse", &zeros);
        let d_residual = storage(ctx, "anderson d residual", &history);
        let d_impulse = storage(ctx, "anderson d impulse", &history);
        let dot_groups = n_groups(n);
        let partials = storage(ctx, "anderson partials", &vec![0.0f32; dot_groups * n_sums(depth)]);
        let state = storage(ctx, "anderson state", &[Mixer::new()]);
        let shape = uniform(ctx, "anderson shape", &[n as u32, depth as u32, 0, 0]);
        let rebuild_grid = velocities.map_or([0, 1], |(_, bodies)| grid(groups(bodies)));
        let job = uniform(ctx, "anderson job", &[dot_groups as u32, depth as u32, rebuild_grid[0], rebuild_grid[1]]);
        let args = indirect_args(ctx, "anderson rebuild", &[0, 1, 1]);
        let dots = bind(
            ctx,
            &kernels.anderson_dots,
            &[
                ("r", r_buf),
                ("before", &before),
                ("last_residual", &last_residual),
                ("d_residual", &d_residual),
                ("partials", &partials),
                ("shape", &shape),
            ],
        );
        let fit = bind(
            ctx,
            &kernels.anderson_fit,
            &[("partials", &partials), ("mixer", &state), ("rebuild", &args), ("job", &job)],
        );
        let mix = bind(
            ctx,
            &kernels.anderson_mix,
            &[
                ("r", r_buf),
                ("before", &before),
                ("last_residual", &last_residual),
                ("last_impulse", &last_impulse),
                ("d_residual", &d_residual),
                ("d_impulse", &d_impulse),
                ("mu", &gp.mu),
                ("mixer", &state),
            ],
        );
        let rebuild = velocities.map(|(group, bodies)| (group.clone(), args, groups(bodies)));
        Self {
            kernels,
            dots,
            fit,
            mix,
            dot_groups: dot_groups as u32,
            contact_groups: groups(nc),
            rebuild,
            state,
            _buffers: vec![before, last_residual, last_impulse, d_residual, d_impulse, partials, shape, job],
        }
    }

    /// Records the mixing that follows a sweep.
    pub fn record(&self, pass: &mut wgpu::ComputePass) {
        let k = &self.kernels;
        dispatch(pass, &k.anderson_dots, &self.dots, self.dot_groups);
        dispatch(pass, &k.anderson_fit, &self.fit, 1);
        dispatch(pass, &k.anderson_mix, &self.mix, self.contact_groups);
        if let Some((group, args, _)) = &self.rebuild {
            dispatch_indirect(pass, &k.body_accumulate, group, args);
        }
    }

    /// Records stage `k` alone, for timings: the dots, the fit, the mix, or the velocities'
    /// rebuild at its full size (none without one).
    pub fn record_stage(&self, pass: &mut wgpu::ComputePass, k: usize) {
        let kernels = &self.kernels;
        match (k, &self.rebuild) {
            (0, _) => dispatch(pass, &kernels.anderson_dots, &self.dots, self.dot_groups),
            (1, _) => dispatch(pass, &kernels.anderson_fit, &self.fit, 1),
            (2, _) => dispatch(pass, &kernels.anderson_mix, &self.mix, self.contact_groups),
            (_, Some((group, _, full))) => dispatch(pass, &kernels.body_accumulate, group, *full),
            (_, None) => {}
        }
    }

    /// Mixings dropped so far (one small read-back).
    pub fn restarts(&self, ctx: &GpuContext) -> Result<u32, String> {
        Ok(read_back::<Mixer>(ctx, &self.state, 1)?[0].restarts)
    }
}
