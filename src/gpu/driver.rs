//! The loop every GPU solver shares: record K iterations per submit, read `r` back, evaluate
//! its error in f64 on the CPU with the core's measure, stop at the tolerance, at max_iter, or
//! when f32 stops improving (the floor, reported). K doubles while the error is more than
//! 100 × tol away.

use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::kernels::read_back;
use super::layout::to_f64;
use crate::problem::cone::project_cone;
use crate::problem::residual::error_of;
use crate::problem::ContactProblem;
use crate::solvers::{HistoryPoint, SolveReport, SolverKind, SolverOptions};

/// Iterations without a 1 % improvement of the error before the solve is declared stalled at the
/// f32 floor: at least this many, and at least as many as it took to get there.
const STALLED_ITERATIONS: usize = 500;

/// The f64 starting impulses, projected on the cone (warm start, else zero).
pub fn initial_impulses(p: &ContactProblem, r0: Option<&[f64]>) -> Vec<f64> {
    let nc = p.n_contacts();
    let mut r: Vec<f64> = match r0 {
        Some(r) if r.len() == 2 * nc && r.iter().all(|x| x.is_finite()) => r.to_vec(),
        _ => vec![0.0; 2 * nc],
    };
    for a in 0..nc {
        let ra = project_cone([r[2 * a], r[2 * a + 1]], p.mu[a]);
        r[2 * a] = ra[0];
        r[2 * a + 1] = ra[1];
    }
    r
}

fn land_on_cone(p: &ContactProblem, r: &mut [f64]) {
    for a in 0..p.n_contacts() {
        let ra = project_cone([r[2 * a], r[2 * a + 1]], p.mu[a]);
        r[2 * a] = ra[0];
        r[2 * a + 1] = ra[1];
    }
}

/// Runs `record(pass)` (one iteration) until a stop; `r_buf` holds the impulses.
#[allow(clippy::too_many_arguments)]
pub fn iterate(
    ctx: &GpuContext,
    p: &ContactProblem,
    opts: &SolverOptions,
    kind: SolverKind,
    start: Instant,
    mut r: Vec<f64>,
    r_buf: &wgpu::Buffer,
    products_per_iteration: usize,
    record: impl Fn(&mut wgpu::ComputePass),
) -> Result<SolveReport, GpuError> {
    let nc = p.n_contacts();
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
        let mut encoder =
            ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(kind.name()) });
        {
            let mut pass = encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(kind.name()), timestamp_writes: None });
            for _ in 0..k {
                record(&mut pass);
            }
        }
        ctx.queue.submit([encoder.finish()]);
        iterations += k;
        r = to_f64(&read_back::<[f32; 2]>(ctx, r_buf, nc).map_err(GpuError::Runtime)?);
        // Judge what would be returned: f32 impulses (and APGD's lagging box) landed on the f64 cone.
        land_on_cone(p, &mut r);
        if r.iter().any(|x| !x.is_finite()) {
            stop_reason = "diverged: non-finite impulses".to_string();
            break;
        }
        error = error_of(p, &r).0;
        history.push(HistoryPoint {
            iteration: iterations,
            seconds: start.elapsed().as_secs_f64(),
            w_products: products_per_iteration * iterations + 1,
            error,
        });
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
    let r = if error <= best { r } else { best_r };
    let (error, u) = error_of(p, &r);
    Ok(SolveReport {
        solver: kind,
        converged: error <= opts.tol,
        iterations,
        error,
        seconds: start.elapsed().as_secs_f64(),
        w_products: products_per_iteration * iterations + 1,
        history,
        stop_reason,
        r,
        u,
    })
}
