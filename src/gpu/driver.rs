//! The loop every GPU solver shares: record K iterations per submit, then estimate the error on
//! the GPU (`natural_map.wgsl` and three deterministic reductions: only three numbers come back);
//! when the estimate reaches the tolerance, read `r` back and judge it in f64 on the CPU with the
//! core's measure — that f64 error alone decides convergence. Under `criterion = velocity`,
//! whose measure the natural-map estimate does not bound, every check reads `r` back and judges
//! it in f64 (the CPU's [`JudgedMeasure`]). Stop at the tolerance, at
//! max_iter, or when the error stops improving (the f32 floor, reported). K doubles while the
//! error is more than 100 × tol away.

use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::kernels::{bind, dispatch, groups, read_back, storage, submit};
use super::layout::to_f64;
use super::operator::{GpuOperator, GpuProblem};
use super::pool::{BindGroup, GpuBuffer};
use super::reduce::{partials_len, Dot};
use crate::problem::cone::project_cone;
use crate::problem::residual::{error_of, gap_term};
use crate::problem::ContactProblem;
use crate::solvers::stopping::{JudgedMeasure, StallWatch, StopReason};
use crate::solvers::{HistoryPoint, SolveReport, SolverKind, SolverOptions, StopCriterion};

/// The f64 starting impulses, projected on the cone (warm start, else zero).
pub fn initial_impulses(p: &ContactProblem, r0: Option<&[f64]>) -> Vec<f64> {
    let nc = p.n_contacts();
    let mut r: Vec<f64> = match r0 {
        Some(r) if r.len() == 2 * nc && r.iter().all(|x| x.is_finite()) => r.to_vec(),
        _ => vec![0.0; 2 * nc],
    };
    land_on_cone(p, &mut r);
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
    gp: &GpuProblem,
    opts: &SolverOptions,
    kind: SolverKind,
    start: Instant,
    mut r: Vec<f64>,
    r_buf: &GpuBuffer,
    products_per_iteration: usize,
    record: impl Fn(&mut wgpu::ComputePass),
) -> Result<SolveReport, GpuError> {
    let nc = p.n_contacts();
    let checker = Checker::new(ctx, p, gp, r_buf);
    let measure = JudgedMeasure::new(p, opts.criterion);
    let judge = |r: &[f64]| {
        let (natural, u) = error_of(p, r);
        (measure.of(p, r, &u, natural), natural, u)
    };
    let every_check_exact = opts.criterion == StopCriterion::Velocity;
    let (mut error, ..) = judge(&r);
    let mut history = vec![HistoryPoint { iteration: 0, seconds: start.elapsed().as_secs_f64(), w_products: 0, error }];
    let (mut best, mut best_r) = (error, r.clone());
    let mut stall = StallWatch::new(error);
    let mut iterations = 0usize;
    let mut batch = 8usize;
    let (stop, stop_reason);
    loop {
        if error <= opts.tol {
            (stop, stop_reason) =
                (StopReason::Converged, format!("converged: error {error:.3e} <= tol {:.1e}", opts.tol));
            break;
        }
        if iterations >= opts.max_iter {
            (stop, stop_reason) = (StopReason::MaxIter, format!("not converged: max_iter = {} reached", opts.max_iter));
            break;
        }
        if let Some(mark) = stall.stalled(iterations) {
            (stop, stop_reason) = (
                StopReason::Stalled,
                format!("not converged: stalled near {mark:.3e} (the f32 floor of this problem on the GPU)"),
            );
            break;
        }
        let k = batch.min(opts.max_iter - iterations);
        submit(ctx, kind.name(), |pass| {
            for _ in 0..k {
                record(pass);
            }
        });
        iterations += k;
        let estimate = checker.estimate(ctx)?;
        if !estimate.is_finite() {
            (stop, stop_reason) = (StopReason::Diverged, "diverged: non-finite impulses".to_string());
            break;
        }
        // Near the tolerance the f32 estimate is not trusted either way: judge in f64.
        let exact = every_check_exact || estimate <= 2.0 * opts.tol;
        if exact {
            r = to_f64(&read_back::<[f32; 2]>(ctx, r_buf, nc).map_err(GpuError::Runtime)?);
            // Judge what would be returned: f32 impulses (and APGD's lagging box) landed on the f64 cone.
            land_on_cone(p, &mut r);
            error = judge(&r).0;
        } else {
            error = estimate;
        }
        history.push(HistoryPoint {
            iteration: iterations,
            seconds: start.elapsed().as_secs_f64(),
            w_products: products_per_iteration * iterations + 1,
            error,
        });
        stall.record(iterations, error);
        if exact && error < best {
            best = error;
            best_r.clone_from(&r);
        }
        // Far from the tolerance, read back less often.
        batch = if error > 100.0 * opts.tol { (2 * batch).min(512) } else { 16 };
    }
    // The impulses the GPU holds now, judged in f64; the best f64-judged ones if those were better.
    let mut r = to_f64(&read_back::<[f32; 2]>(ctx, r_buf, nc).map_err(GpuError::Runtime)?);
    land_on_cone(p, &mut r);
    let (mut judged, mut error, mut u) = judge(&r);
    if (judged.is_nan() || judged > best) && best.is_finite() {
        r = best_r;
        (judged, error, u) = judge(&r);
    }
    let converged = judged <= opts.tol;
    Ok(SolveReport {
        solver: kind,
        converged,
        iterations,
        error,
        judged_error: judged,
        seconds: start.elapsed().as_secs_f64(),
        w_products: products_per_iteration * iterations + 1,
        history,
        stop: if converged {
            StopReason::Converged
        } else if stop == StopReason::Converged {
            StopReason::Stalled
        } else {
            stop
        },
        stop_reason,
        notes: Vec::new(),
        parts: Vec::new(),
        gpu_dispatches: 0,
        gpu_bytes: 0,
        r,
        u,
        iterates: Vec::new(),
    })
}

/// The on-GPU error estimate: `u = W r + q`, per-contact residuals, and |F|², |r|², |u|² reduced
/// into three slots; the estimate is |F| / max(|q|, |r|, |u|) as the core measures it (|q| in f64,
/// gap terms left out as the core leaves them).
struct Checker {
    operator: GpuOperator,
    kernels: std::sync::Arc<super::kernels::Kernels>,
    residual: BindGroup,
    dots: [Dot; 3],
    scalars: GpuBuffer,
    q_norm: f64,
    gap_norm: f64,
    groups: u32,
    _buffers: Vec<GpuBuffer>,
}

impl Checker {
    fn new(ctx: &GpuContext, p: &ContactProblem, gp: &GpuProblem, r_buf: &GpuBuffer) -> Self {
        let nc = p.n_contacts();
        let kernels = gp.kernels.clone();
        let u = storage(ctx, "u check", &vec![[0.0f32; 2]; nc]);
        let f = storage(ctx, "f", &vec![[0.0f32; 2]; nc]);
        let scalars = storage(ctx, "check scalars", &[0.0f32; 4]);
        let partials = storage(ctx, "check partials", &vec![0.0f32; partials_len(2 * nc)]);
        let operator = gp.product(ctx, r_buf, &gp.q, &u);
        let residual = bind(ctx, &kernels.natural_map, &[("r", r_buf), ("u", &u), ("mu", &gp.mu), ("f", &f)]);
        let n = 2 * nc;
        let dots = [
            Dot::new(ctx, &kernels, &f, &f, n, &partials, &scalars, 0),
            Dot::new(ctx, &kernels, r_buf, r_buf, n, &partials, &scalars, 1),
            Dot::new(ctx, &kernels, &u, &u, n, &partials, &scalars, 2),
        ];
        // The core's scale leaves each open contact's gap term s out of q and u; |u − s| is not
        // reduced here, so |u| − |s| (at most |u − s|) stands in: the estimate can only grow.
        let q_norm = (0..p.q.len()).map(|k| (p.q[k] - gap_term(&p.gap_rate, k)).powi(2)).sum::<f64>().sqrt();
        let gap_norm = p.gap_rate.iter().map(|g| g * g).sum::<f64>().sqrt();
        let _buffers = vec![u, f, partials];
        Self { operator, kernels, residual, dots, scalars, q_norm, gap_norm, groups: groups(nc), _buffers }
    }

    fn estimate(&self, ctx: &GpuContext) -> Result<f64, GpuError> {
        let k = &self.kernels;
        submit(ctx, "check", |pass| {
            self.operator.record(k, pass);
            dispatch(pass, &k.natural_map, &self.residual, self.groups);
            for d in &self.dots {
                d.record(k, pass);
            }
        });
        let s = read_back::<f32>(ctx, &self.scalars, 3).map_err(GpuError::Runtime)?;
        let (f, r, u) = ((s[0] as f64).sqrt(), (s[1] as f64).sqrt(), (s[2] as f64).sqrt());
        let scale = self.q_norm.max(r).max(u - self.gap_norm);
        Ok(if scale > f64::EPSILON { f / scale } else { f })
    }
}
