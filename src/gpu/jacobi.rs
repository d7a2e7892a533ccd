//! Projected Jacobi on the GPU (notes §6.2): every iteration is `u = W r + q` then the update of
//! every contact, all recorded in one submit of K iterations; `r` comes back every K iterations
//! and its error is evaluated in f64 on the CPU with the core's measure. K grows while the error
//! is far from the tolerance. f32 has a floor: when the error stops improving the solve ends and
//! says so.

use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::kernels::{bind, groups, read_back, storage};
use super::layout::{to_f32_pairs, to_f64};
use super::operator::GpuOperator;
use crate::problem::cone::project_cone;
use crate::problem::residual::error_of;
use crate::problem::{ContactProblem, Delassus};
use crate::solvers::{HistoryPoint, SolveReport, SolverKind, SolverOptions};

/// Iterations without a 1 % improvement of the best error before the solve is declared stalled
/// at the f32 floor: at least this many, and at least as many as it took to get there.
const STALLED_ITERATIONS: usize = 500;

pub fn solve(ctx: &GpuContext, p: &ContactProblem, opts: &SolverOptions, r0: Option<&[f64]>) -> Result<SolveReport, GpuError> {
    let start = Instant::now();
    let nc = p.n_contacts();
    let (rotation, friction) = match &p.w {
        Delassus::MatrixFree(op) => (op.dofs().rotation, op.dofs().friction),
        Delassus::Sparse(_) => (true, true),
    };
    let kernels = ctx.kernels(rotation, friction);
    let mut r: Vec<f64> = match r0 {
        Some(r) if r.len() == 2 * nc && r.iter().all(|x| x.is_finite()) => r.to_vec(),
        _ => vec![0.0; 2 * nc],
    };
    for a in 0..nc {
        let ra = project_cone([r[2 * a], r[2 * a + 1]], p.mu[a]);
        r[2 * a] = ra[0];
        r[2 * a + 1] = ra[1];
    }
    let step: Vec<f32> = p.w.diag_blocks().iter().map(|d| (opts.jacobi_omega * 2.0 / (d[0] + d[3])) as f32).collect();
    let mu: Vec<f32> = p.mu.iter().map(|&m| m as f32).collect();
    let r_buf = storage(ctx, "r", &to_f32_pairs(&r));
    let q_buf = storage(ctx, "q", &to_f32_pairs(&p.q));
    let u_buf = storage(ctx, "u", &vec![[0.0f32; 2]; nc]);
    let mu_buf = storage(ctx, "mu", &mu);
    let step_buf = storage(ctx, "step", &step);
    let op = GpuOperator::new(ctx, &kernels, &p.w, &r_buf, &q_buf, &u_buf);
    let update = bind(ctx, &kernels.jacobi_update, &[&u_buf, &mu_buf, &step_buf, &r_buf]);

    let (mut error, _) = error_of(p, &r);
    let mut history = vec![HistoryPoint { iteration: 0, seconds: start.elapsed().as_secs_f64(), w_products: 0, error }];
    let (mut best, mut best_r) = (error, r.clone());
    // The last error that improved on its predecessor mark by 1 %, and when.
    let (mut mark, mut improved_at) = (error, 0usize);
    let mut iterations = 0usize;
    let mut batch = 8usize;
    let stop_reason;
    loop {
        if error <= opts.tol {
            stop_reason = format!("converged: error {error:.3e} <= tol {:.1e}", opts.tol);
            break;
        }
        if iterations >= opts.max_iter {
            stop_reason = format!("not converged: max_iter = {} reached", opts.max_iter);
            break;
        }
        if iterations - improved_at >= STALLED_ITERATIONS.max(improved_at) {
            stop_reason = format!("not converged: stalled at {best:.3e} (the f32 floor of this problem on the GPU)");
            break;
        }
        let k = batch.min(opts.max_iter - iterations);
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("jacobi") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("jacobi"), timestamp_writes: None });
            for _ in 0..k {
                op.record(&kernels, &mut pass);
                pass.set_pipeline(&kernels.jacobi_update);
                pass.set_bind_group(0, &update, &[]);
                pass.dispatch_workgroups(groups(nc), 1, 1);
            }
        }
        ctx.queue.submit([encoder.finish()]);
        iterations += k;
        r = to_f64(&read_back::<[f32; 2]>(ctx, &r_buf, nc).map_err(GpuError::Runtime)?);
        if r.iter().any(|x| !x.is_finite()) {
            stop_reason = "diverged: non-finite impulses".to_string();
            break;
        }
        error = error_of(p, &r).0;
        history.push(HistoryPoint { iteration: iterations, seconds: start.elapsed().as_secs_f64(), w_products: iterations, error });
        if error < 0.99 * mark {
            (mark, improved_at) = (error, iterations);
        }
        if error < best {
            best = error;
            best_r.clone_from(&r);
        }
        // Far from the tolerance, read back less often.
        batch = if error > 100.0 * opts.tol { (2 * batch).min(512) } else { 16 };
    }
    let mut r = if error <= best { r } else { best_r };
    // f32 impulses meet the f64 cone only to rounding: land them on it exactly.
    for a in 0..nc {
        let ra = project_cone([r[2 * a], r[2 * a + 1]], p.mu[a]);
        r[2 * a] = ra[0];
        r[2 * a + 1] = ra[1];
    }
    let (error, u) = error_of(p, &r);
    Ok(SolveReport {
        solver: SolverKind::Jacobi,
        converged: error <= opts.tol,
        iterations,
        error,
        seconds: start.elapsed().as_secs_f64(),
        w_products: iterations + 1,
        history,
        stop_reason,
        r,
        u,
    })
}
