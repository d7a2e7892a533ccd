//! Timings of the GPU kernels without read-backs: `n` products, Jacobi iterations or NLGS sweeps
//! recorded in one submit, waited for, divided by `n`. Used by `moreau bench` and the criterion benches.
//! On the software adapter these numbers describe lavapipe, not a GPU.

use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::jacobi::{steps, FusedJacobi};
use super::kernels::{bind, dispatch, groups, storage, submit};
use super::nlgs::ColouredSweep;
use super::operator::GpuProblem;
use crate::problem::ContactProblem;

/// Seconds per `W` product and per projected-Jacobi iteration (product + update).
pub struct KernelTimes {
    /// Seconds per product.
    pub product: f64,
    /// Seconds per Jacobi iteration.
    pub jacobi_iteration: f64,
}

fn run(ctx: &GpuContext, n: usize, mut record: impl FnMut(&mut wgpu::ComputePass)) -> Result<f64, GpuError> {
    let start = Instant::now();
    submit(ctx, "timing", |pass| {
        for _ in 0..n {
            record(pass);
        }
    });
    ctx.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| GpuError::Runtime(e.to_string()))?;
    Ok(start.elapsed().as_secs_f64() / n as f64)
}

/// Times `n` products and `n` Jacobi iterations of `p` on the GPU, as the GPU's Jacobi solve
/// records them (one `jacobi_fused` dispatch on the matrix-free operator).
pub fn kernel_times(ctx: &GpuContext, p: &ContactProblem, n: usize) -> Result<KernelTimes, GpuError> {
    let nc = p.n_contacts();
    let gp = GpuProblem::upload(ctx, p);
    let kernels = &gp.kernels;
    let r = storage(ctx, "r", &vec![[0.0f32; 2]; nc]);
    let u = storage(ctx, "u", &vec![[0.0f32; 2]; nc]);
    let step = storage(ctx, "step", &steps(p, 0.5));
    let op = gp.product(ctx, &r, &gp.q, &u);
    run(ctx, 3, |pass| op.record(kernels, pass))?; // warm-up: pipeline creation, first-use costs
    let product = run(ctx, n, |pass| op.record(kernels, pass))?;
    let jacobi_iteration = match FusedJacobi::new(ctx, &gp, &step, &r) {
        Some(fused) => {
            let mut leg = 0;
            let mut iteration = |pass: &mut wgpu::ComputePass| {
                fused.record(pass, leg);
                leg = 1 - leg;
            };
            run(ctx, 2, &mut iteration)?;
            run(ctx, n, iteration)?
        }
        None => {
            let update = bind(ctx, &kernels.jacobi_update, &[("u", &u), ("mu", &gp.mu), ("step", &step), ("r", &r)]);
            run(ctx, n, |pass| {
                op.record(kernels, pass);
                dispatch(pass, &kernels.jacobi_update, &update, groups(nc));
            })?
        }
    };
    Ok(KernelTimes { product, jacobi_iteration })
}

/// A coloured NLGS sweep of `p` on the GPU, timed from r = 0 (`n` in one submit, no check).
pub struct SweepTimes {
    /// Seconds per sweep (a dispatch per colour).
    pub sweep: f64,
    /// Colours in the sweep.
    pub colours: usize,
    /// Seconds per dispatch of the largest colour alone, `n` of them in one submit: a sweep far
    /// above `colours` times this is not bound by its dispatches.
    pub largest_colour: f64,
    /// The Anderson mixer's stages, when a depth was asked for.
    pub mixing: Option<MixingTimes>,
}

/// The Anderson mixer's stages after a sweep, each timed alone (`n` in one submit), and a sweep
/// with its mixing: where a mixed GPU sweep's extra time goes.
pub struct MixingTimes {
    /// Seconds per dispatch of each stage: the fit's dot products, the fit, the mix, and the
    /// velocities' rebuild at its full size (matrix-free `W`; a mix or a restart needs it).
    pub stages: [f64; 4],
    /// Seconds per sweep followed by its mixing, as the solve records them.
    pub mixed_sweep: f64,
}

/// Times `n` coloured NLGS sweeps of `p`, and `n` dispatches of its largest colour: what a GPU
/// solve's sweep costs before its checks, and how much of it the dispatches' count explains.
/// With `depth` > 0, also the mixer of `depth` sweeps after them, stage by stage.
pub fn nlgs_sweep_times(ctx: &GpuContext, p: &ContactProblem, n: usize, depth: usize) -> Result<SweepTimes, GpuError> {
    let gp = GpuProblem::upload(ctx, p);
    let r0 = vec![[0.0f32; 2]; p.n_contacts()];
    let r = storage(ctx, "r", &r0);
    let sweep = ColouredSweep::new(ctx, p, &gp, &r, 0.0, 0);
    let (colours, largest) = sweep.colours();
    run(ctx, 3, |pass| sweep.record(pass))?; // warm-up, as for the products
    let (sweep_time, largest_colour) =
        (run(ctx, n, |pass| sweep.record(pass))?, run(ctx, n, |pass| sweep.record_colour(pass, largest))?);
    let mixing = match depth {
        0 => None,
        _ => {
            let mixer = super::anderson::GpuAnderson::new(ctx, &gp, &r0, &r, depth, sweep.velocities());
            let mixed = |pass: &mut wgpu::ComputePass| {
                sweep.record(pass);
                mixer.record(pass);
            };
            run(ctx, 3, mixed)?;
            let mixed_sweep = run(ctx, n, mixed)?;
            let mut stages = [0.0; 4];
            for (k, time) in stages.iter_mut().enumerate() {
                *time = run(ctx, n, |pass| mixer.record_stage(pass, k))?;
            }
            Some(MixingTimes { stages, mixed_sweep })
        }
    };
    Ok(SweepTimes { sweep: sweep_time, colours, largest_colour, mixing })
}

/// A round of block sweeps of `p` (`inner` sweeps of each block a dispatch, a dispatch per block
/// colour), timed from r = 0 (`n` in one submit, no check): seconds a round, and its dispatches.
pub fn block_round_time(
    ctx: &GpuContext,
    p: &ContactProblem,
    n: usize,
    inner: usize,
) -> Result<(f64, usize), GpuError> {
    let gp = GpuProblem::upload(ctx, p);
    let r = storage(ctx, "r", &vec![[0.0f32; 2]; p.n_contacts()]);
    let sweep = ColouredSweep::new(ctx, p, &gp, &r, 0.0, inner);
    run(ctx, 3, |pass| sweep.record(pass))?;
    Ok((run(ctx, n, |pass| sweep.record(pass))?, sweep.colours().0))
}
