//! Projected Jacobi on the GPU (notes §6.2): every iteration is `u = W r + q` then the update of
//! every contact (`jacobi_update.wgsl`); the loop and its stopping rules are in `driver.rs`.

use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::driver::{initial_impulses, iterate, PerIteration};
use super::kernels::{bind, dispatch, groups, storage};
use super::layout::to_f32_pairs;
use super::operator::GpuProblem;
use crate::problem::ContactProblem;
use crate::solvers::{SolveReport, SolverKind, SolverOptions};

/// Projected Jacobi on the GPU in f32 (the driver judges it in f64).
pub fn solve(
    ctx: &GpuContext,
    p: &ContactProblem,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
) -> Result<SolveReport, GpuError> {
    let start = Instant::now();
    let nc = p.n_contacts();
    let gp = GpuProblem::upload(ctx, p);
    let kernels = &gp.kernels;
    let r = initial_impulses(p, r0);
    let step: Vec<f32> = p.w.diag_blocks().iter().map(|d| (opts.jacobi_omega * 2.0 / (d[0] + d[3])) as f32).collect();
    let r_buf = storage(ctx, "r", &to_f32_pairs(&r));
    let u_buf = storage(ctx, "u", &vec![[0.0f32; 2]; nc]);
    let step_buf = storage(ctx, "step", &step);
    let op = gp.product(ctx, &r_buf, &gp.q, &u_buf);
    let update =
        bind(ctx, &kernels.jacobi_update, &[("u", &u_buf), ("mu", &gp.mu), ("step", &step_buf), ("r", &r_buf)]);
    iterate(ctx, p, &gp, opts, SolverKind::Jacobi, start, r, &r_buf, PerIteration::products(1), |pass| {
        op.record(kernels, pass);
        dispatch(pass, &kernels.jacobi_update, &update, groups(nc));
    })
}
