//! Projected Jacobi on the GPU (notes §6.2): every iteration is `u = W r + q` then the update of
//! every contact (`jacobi_update.wgsl`); the loop and its stopping rules are in `driver.rs`.

use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::driver::{initial_impulses, iterate};
use super::kernels::{bind, dispatch, groups, storage};
use super::layout::to_f32_pairs;
use super::operator::GpuOperator;
use crate::problem::ContactProblem;
use crate::solvers::{SolveReport, SolverKind, SolverOptions};

pub fn solve(
    ctx: &GpuContext,
    p: &ContactProblem,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
) -> Result<SolveReport, GpuError> {
    let start = Instant::now();
    let nc = p.n_contacts();
    let (rotation, friction) = super::specialisation(p);
    let kernels = ctx.kernels(rotation, friction);
    let r = initial_impulses(p, r0);
    let step: Vec<f32> = p.w.diag_blocks().iter().map(|d| (opts.jacobi_omega * 2.0 / (d[0] + d[3])) as f32).collect();
    let mu: Vec<f32> = p.mu.iter().map(|&m| m as f32).collect();
    let r_buf = storage(ctx, "r", &to_f32_pairs(&r));
    let q_buf = storage(ctx, "q", &to_f32_pairs(&p.q));
    let u_buf = storage(ctx, "u", &vec![[0.0f32; 2]; nc]);
    let mu_buf = storage(ctx, "mu", &mu);
    let step_buf = storage(ctx, "step", &step);
    let op = GpuOperator::new(ctx, &kernels, &p.w, &r_buf, &q_buf, &u_buf);
    let update = bind(ctx, &kernels.jacobi_update, &[&u_buf, &mu_buf, &step_buf, &r_buf]);
    iterate(ctx, p, opts, SolverKind::Jacobi, start, r, &r_buf, 1, |pass| {
        op.record(&kernels, pass);
        dispatch(pass, &kernels.jacobi_update, &update, groups(nc));
    })
}
