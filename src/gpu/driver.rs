//! The loop every GPU solver shares: record K iterations per submit, then estimate the error on
//! the GPU (`natural_map.wgsl` and three deterministic reductions: only three numbers come back);
//! when the estimate reaches the tolerance, read `r` back and judge it in f64 on the CPU with the
//! core's measure — that f64 error alone decides convergence. Under the velocity tests, whose
//! measure the natural-map estimate does not bound, the estimate is that measure's own, in one
//! dispatch after the product (`velocity_residual.wgsl`: the largest residual of each 1,024
//! contacts comes back, with a sum that shows a diverged iterate), and the f64 judge is the
//! CPU's [`JudgedMeasure`]. Stop at the tolerance, at max_iter, or when the
//! error stops improving below 1e-3 (a plateau where f32 may be the limit, reported). K doubles
//! while the error is more than 100 × tol away; near tol it is [`near_tol_batch`]: √(4 × the
//! iterations run), 16 to 128.
//!
//! A check's numbers take a round trip (submit, wait, map) that costs dozens of sweeps on a
//! hardware GPU. The next batch is queued before they are waited for, so the GPU sweeps while
//! they travel, and each check keeps a copy of the impulses it judged: a solve that stops at a
//! check returns those, and the batch queued past it is dropped (the notes count its iterations).

use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::cpu::velocity_residual::n_groups as velocity_groups;
use super::kernels::{bind, dispatch, encode_pass, groups, read_back, storage, submit, submit_and_read, PendingRead};
use super::layout::to_f64;
use super::operator::{GpuOperator, GpuProblem};
use super::pool::{BindGroup, GpuBuffer};
use super::reduce::{partials_len, Dot};
use crate::problem::cone::{project_cone, project_each};
use crate::problem::residual::{error_of, gap_term};
use crate::problem::ContactProblem;
use crate::solvers::stopping::{velocity_scale, JudgedMeasure, StallWatch, StopReason};
use crate::solvers::{GpuChecks, HistoryPoint, SolveReport, SolverKind, SolverOptions, StopCriterion};

/// The f64 starting impulses, projected on the cone (warm start, else zero).
pub fn initial_impulses(p: &ContactProblem, r0: Option<&[f64]>) -> Vec<f64> {
    let nc = p.n_contacts();
    let mut r: Vec<f64> = match r0 {
        Some(r) if r.len() == 2 * nc && r.iter().all(|x| x.is_finite()) => r.to_vec(),
        _ => vec![0.0; 2 * nc],
    };
    project_each(&mut r, &p.mu, project_cone);
    r
}

/// A plateau of the error above this is the method's slow progress, not the f32 floor (f32
/// iterations reach 1e-5 on the problems measured, `backend::F32_FLOOR`): the GPU goes on
/// iterating, where handing the solve to f64 on the CPU would only make the same sweeps slower
/// (the sandbox's third step, stalled near 2.4e-2 after 1,000 GPU sweeps, then took 25 s on 16
/// CPU cores for 19,000 sweeps to 8.5e-3). Only a plateau below it stops the GPU part, and only
/// when `gpu_plateau_stops` (plain sweeps after a stalled mixing run past plateaus).
const F32_PLATEAU_CEILING: f64 = 1e-3;

/// What one round of a GPU solver (one call of its `record`) does: `W` products (for the report),
/// sweeps' worth of work (the batches between checks are counted in sweeps, so that a round of
/// several sweeps, a round of block sweeps, is not run as far past tol as the same count of
/// sweeps) and the iterations it counts as.
#[derive(Clone)]
pub struct PerIteration {
    /// `W` products (or their equivalent) an iteration, as reported, makes.
    pub products: usize,
    /// Sweeps' worth of contact updates a round makes.
    pub sweeps: usize,
    /// Iterations a round counts as in the report and against `max_iter`: 1, or 2 for projected
    /// Jacobi's pair of one-dispatch iterations (`jacobi_fused`, which alternates two buffers).
    pub iterations: usize,
    /// The work list's thresholded sweeps: the count of contacts they updated (one u32,
    /// cumulative). The solve's iterations are then sweeps' worth of those updates, as on the
    /// CPU's list, and its rounds are bounded by [`ROUNDS_PER_COUNTED_ITERATION`] × `max_iter`.
    pub updates: Option<GpuBuffer>,
}

impl PerIteration {
    /// An iteration of `products` products and one sweep's worth of work.
    pub fn products(products: usize) -> Self {
        Self { products, sweeps: 1, iterations: 1, updates: None }
    }
}

/// Rounds of thresholded sweeps a solve may run per iteration of `max_iter` when its iterations
/// count updates: a round that updates few contacts still costs its dispatches. On an H200 a
/// round of the 10,000-disk pile's colours cost 25–32 µs and a full sweep on 16 CPU cores 0.29 ms,
/// of the sandbox's 44 µs and 1.15 ms: 32 rounds, 1.2–2.8 CPU sweeps, an iteration keep a GPU
/// solve's worst case near the CPU's. (The deposit's steps took up to 10,112 rounds.)
pub const ROUNDS_PER_COUNTED_ITERATION: usize = 32;

/// The batch between checks once the error is within 100 × tol, after `run` iterations (rounds of
/// a work list): √(4 × run), from 16 to 128. The batch queued past the check that stops is
/// dropped, so it is kept short against what the solve has already run (at most 2/√run of it);
/// a check costs a product and a round trip, so they are spaced out as the solve goes on. (A
/// batch that doubled while the error stayed near tol ran the 10,000-disk pile at rest for 234
/// rounds a step, 104 of them dropped, where its steps meet tol in 86 on average.)
pub fn near_tol_batch(run: usize) -> usize {
    (4 * run).isqrt().clamp(16, 128)
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
    per_iteration: PerIteration,
    record: impl Fn(&mut wgpu::ComputePass),
) -> Result<SolveReport, GpuError> {
    let products_per_iteration = per_iteration.products;
    // Iterations a round counts as (a round of counted updates counts by its updates instead).
    let per_round = per_iteration.iterations.max(1);
    // A batch of `sweeps` sweeps' worth, in iterations.
    let iterations_of = |sweeps: usize| (sweeps / per_iteration.sweeps.max(1)).max(1);
    let checker = Checker::new(ctx, p, gp, r_buf, opts.criterion, per_iteration.updates.clone());
    // Counted updates: iterations are sweeps' worth of them, rounds bounded apart.
    let counting = per_iteration.updates.is_some();
    let rounds_cap = match counting {
        true => opts.max_iter.saturating_mul(ROUNDS_PER_COUNTED_ITERATION),
        false => opts.max_iter / per_round,
    };
    let contacts = p.n_contacts().max(1) as u64;
    let (mut updates, mut last_count, mut idle_check) = (0u64, 0u32, false);
    // Iterations as reported after `rounds` rounds with `updates` counted.
    let spent_after = |rounds: usize, updates: u64| match counting {
        true => updates.div_ceil(contacts) as usize,
        false => rounds * per_round,
    };
    // The next batch from round `at`, at most `spent` iterations spent by then: a round may
    // update every contact (a sweep's worth), so a batch stays within max_iter whatever it updates.
    let batch_from = |batch: usize, at: usize, spent: usize| {
        iterations_of(batch).min(rounds_cap - at).min(opts.max_iter.saturating_sub(spent) / per_round)
    };
    let run_batch = |k: usize| {
        submit(ctx, kind.name(), |pass| {
            for _ in 0..k {
                record(pass);
            }
        })
    };
    let mut batch = 8usize;
    // A solve runs its first batch before it may stop, as the CPU's sweeps run before their first
    // check: a warm start that meets tol is not handed back unchanged (the pile at rest under the
    // natural map sank 11× deeper on an H200 than on the CPU when it was). It is queued before the
    // warm start is judged, which the GPU's sweeps then hide.
    let first = batch_from(batch, 0, 0);
    if first > 0 {
        run_batch(first);
    }
    let measure = JudgedMeasure::new(p, opts.criterion);
    let judge = |r: &[f64]| {
        let (natural, u) = error_of(p, r);
        (measure.of(p, r, &u, natural), natural, u)
    };
    // The f64 judgement of `r` whenever `judged_last` holds (the warm start's to begin with): the
    // report takes it rather than judging the same impulses again.
    let mut last_judgement = judge(&r);
    let mut error = last_judgement.0;
    let mut history = vec![HistoryPoint { iteration: 0, seconds: start.elapsed().as_secs_f64(), w_products: 0, error }];
    let (mut best, mut best_r) = (error, r.clone());
    let mut stall = StallWatch::new(error);
    let mut iterations = 0usize;
    let mut checks = GpuChecks::default();
    // `iterations`: rounds run; `spent`: iterations as reported (sweeps' worth of counted
    // updates); `idle`: counted sweeps that updated nothing since the last check.
    let stop_at = |error: f64, iterations: usize, spent: usize, idle: bool, stall: &StallWatch| {
        if error <= opts.tol {
            return Some((StopReason::Converged, format!("converged: error {error:.3e} <= tol {:.1e}", opts.tol)));
        }
        if spent + per_round > opts.max_iter {
            return Some((StopReason::MaxIter, format!("not converged: max_iter = {} reached", opts.max_iter)));
        }
        if iterations >= rounds_cap {
            return Some((
                StopReason::MaxIter,
                format!(
                    "not converged: {rounds_cap} rounds of thresholded sweeps ({ROUNDS_PER_COUNTED_ITERATION} × max_iter) \
                     reached, {spent} sweeps' worth of updates"
                ),
            ));
        }
        if idle {
            return Some((
                StopReason::Stalled,
                "not converged: the thresholded sweeps updated no contact since the last check (every residual within \
                 the f32 threshold)"
                    .to_string(),
            ));
        }
        // A plateau of the f32 iteration: its floor on this problem, or a slow stretch that f64
        // may get past; the mixed-precision finish tells which.
        stall.stalled(iterations).filter(|&mark| opts.gpu_plateau_stops && mark <= F32_PLATEAU_CEILING).map(|mark| {
            (
                StopReason::Stalled,
                format!("not converged: stalled near {mark:.3e} (no 1 % gain in f32 for as many iterations as the last gain took)"),
            )
        })
    };
    // Within 10 tol the impulses come back with a check's sums: a judgement is likely.
    let likely_judged = |error: f64| error <= 10.0 * opts.tol;
    // Whether `r` holds the last check's impulses, judged.
    let mut judged_last = true;
    let (stop, stop_reason) = match (first == 0).then(|| stop_at(error, 0, 0, false, &stall)).flatten() {
        Some(stop) => stop,
        None => {
            let mut in_flight = (checker.submit(ctx, likely_judged(error)), first);
            loop {
                let (check, at) = in_flight;
                // The next batch is queued before the check's numbers are waited for: the GPU
                // sweeps while they travel back and the CPU reads them.
                // `iterations` and `updates` are still the last check's: the rounds since may
                // each have been a sweep's worth.
                let mut ahead = batch_from(batch, at, spent_after(iterations, updates) + (at - iterations) * per_round);
                if ahead > 0 {
                    run_batch(ahead);
                }
                let (estimate, impulses, count) = checker.finish(ctx, check)?;
                iterations = at;
                if let Some(count) = count {
                    // The counter wraps past u32; a batch's updates do not.
                    updates += u64::from(count.wrapping_sub(last_count));
                    idle_check = count == last_count;
                    last_count = count;
                }
                if !estimate.is_finite() {
                    checks.discarded = ahead * per_round;
                    judged_last = false;
                    break (StopReason::Diverged, "diverged: non-finite impulses".to_string());
                }
                // Near the tolerance the f32 estimate is not trusted either way: judge in f64.
                judged_last = estimate <= 2.0 * opts.tol;
                checks.estimates += 1;
                if judged_last {
                    let judging = Instant::now();
                    let impulses = match impulses {
                        Some(r32) => r32,
                        None => checker.snapshot(ctx)?,
                    };
                    r = to_f64(&impulses);
                    // Judge what would be returned: f32 impulses (and APGD's lagging box) landed on the f64 cone.
                    project_each(&mut r, &p.mu, project_cone);
                    last_judgement = judge(&r);
                    error = last_judgement.0;
                    checks.judged += 1;
                    checks.judge_seconds += judging.elapsed().as_secs_f64();
                } else {
                    error = estimate;
                }
                let spent = spent_after(iterations, updates);
                history.push(HistoryPoint {
                    iteration: spent,
                    seconds: start.elapsed().as_secs_f64(),
                    w_products: products_per_iteration * spent + 1,
                    error,
                });
                stall.record(iterations, error);
                if judged_last && error < best {
                    best = error;
                    best_r.clone_from(&r);
                }
                // Far from the tolerance, read back less often; near it, see `near_tol_batch`.
                batch = match error > 100.0 * opts.tol {
                    true => (2 * batch).min(512),
                    false => near_tol_batch(at),
                };
                if let Some(stop) = stop_at(error, iterations, spent, idle_check, &stall) {
                    // Run past this check and not used: its impulses are returned.
                    checks.discarded = ahead * per_round;
                    break stop;
                }
                if ahead == 0 {
                    // Held back by the bound on updates not yet read, which this check read: the
                    // next batch runs before the next check (no stop here: rounds and work left).
                    ahead = batch_from(batch, at, spent);
                    run_batch(ahead);
                }
                in_flight = (checker.submit(ctx, likely_judged(error)), at + ahead);
            }
        }
    };
    // The last check's impulses (the GPU's buffer may hold a discarded batch past them), judged
    // in f64; the best f64-judged ones if those were better.
    let (mut judged, mut error, mut u) = match judged_last {
        true => last_judgement,
        false => {
            r = to_f64(&checker.snapshot(ctx)?);
            project_each(&mut r, &p.mu, project_cone);
            judge(&r)
        }
    };
    // As on the CPU: a solve that did not converge returns its best iterate (the warm start
    // among them) when that is better than its last; one that converged, its last.
    if (judged.is_nan() || (judged > opts.tol && judged > best)) && best.is_finite() {
        r = best_r;
        (judged, error, u) = judge(&r);
    }
    let converged = judged <= opts.tol;
    (checks.rounds, checks.counted) = (iterations, counting);
    let mut notes = vec![format!(
        "{} error estimates on the GPU, {} of them judged in f64 on the CPU ({:.1} ms); {} \
         iterations queued past the last check and not used",
        checks.estimates,
        checks.judged,
        1e3 * checks.judge_seconds,
        checks.discarded
    )];
    if counting {
        notes.push(format!(
            "{updates} contact updates ({:.1} sweeps' worth, the iterations) in {iterations} rounds of thresholded sweeps",
            updates as f64 / contacts as f64
        ));
    }
    let iterations = spent_after(iterations, updates);
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
        notes,
        parts: Vec::new(),
        gpu_dispatches: 0,
        gpu_bytes: 0,
        gpu_checks: checks,
        r,
        u,
        body_velocity: None,
        iterates: Vec::new(),
    })
}

/// The on-GPU error estimate of the impulses the solver's buffer holds: `u = W r + q`, then the
/// criterion's own measure of it ([`Estimate`]). Only a few numbers come back.
struct Checker {
    operator: GpuOperator,
    kernels: std::sync::Arc<super::kernels::Kernels>,
    estimate: Estimate,
    r_buf: GpuBuffer,
    /// The impulses at the last check, kept while the next batch runs.
    snapshot: GpuBuffer,
    contacts: usize,
    /// The thresholded sweeps' update counter, read with each check.
    counter: Option<GpuBuffer>,
    _u: GpuBuffer,
}

/// What a check measures on `u`.
enum Estimate {
    /// The natural map's |F| / max(|q|, |r|, |u|) as the core measures it: per-contact residuals
    /// and |F|², |r|², |u|² reduced into three slots (|q| in f64, gap terms left out as the core
    /// leaves them).
    Natural {
        residual: BindGroup,
        dots: Box<[Dot; 3]>,
        scalars: GpuBuffer,
        q_norm: f64,
        gap_norm: f64,
        groups: u32,
        _buffers: [GpuBuffer; 2],
    },
    /// Under a velocity test, the largest per-contact residual in velocity units over the largest
    /// free velocity, as [`crate::problem::residual::velocity_error`] measures it: one dispatch,
    /// whose partials carry a finiteness witness in place of the natural map's sums.
    Velocity {
        residual: BindGroup,
        partials: GpuBuffer,
        groups: usize,
        /// The largest free velocity (f64, gap terms left out).
        scale: f64,
        _c: GpuBuffer,
    },
}

/// Impulses as the GPU holds them.
type F32Impulses = Vec<[f32; 2]>;

/// A check's estimate (NaN for a diverged iterate), the impulses if they came back, and the
/// update counter if the sweeps count.
type CheckResult = (f64, Option<F32Impulses>, Option<u32>);

/// A check on its way back.
struct PendingCheck {
    read: PendingRead,
    with_impulses: bool,
}

impl Checker {
    fn new(
        ctx: &GpuContext,
        p: &ContactProblem,
        gp: &GpuProblem,
        r_buf: &GpuBuffer,
        criterion: StopCriterion,
        counter: Option<GpuBuffer>,
    ) -> Self {
        let nc = p.n_contacts();
        let kernels = gp.kernels.clone();
        let u = storage(ctx, "u check", &vec![[0.0f32; 2]; nc]);
        let operator = gp.product(ctx, r_buf, &gp.q, &u);
        let estimate = if criterion.is_velocity_test() {
            let c = storage(ctx, "W_aa,nn", &p.w.diag_blocks().iter().map(|d| d[0] as f32).collect::<Vec<_>>());
            let groups = velocity_groups(nc);
            let partials = storage(ctx, "velocity partials", &vec![[0.0f32; 2]; groups]);
            let residual = bind(
                ctx,
                &kernels.velocity_residual,
                &[("r", r_buf), ("u", &u), ("mu", &gp.mu), ("c", &c), ("partials", &partials)],
            );
            Estimate::Velocity { residual, partials, groups, scale: velocity_scale(p, criterion), _c: c }
        } else {
            let f = storage(ctx, "f", &vec![[0.0f32; 2]; nc]);
            let scalars = storage(ctx, "check scalars", &[0.0f32; 4]);
            let partials = storage(ctx, "check partials", &vec![0.0f32; partials_len(2 * nc)]);
            let residual = bind(ctx, &kernels.natural_map, &[("r", r_buf), ("u", &u), ("mu", &gp.mu), ("f", &f)]);
            let n = 2 * nc;
            let dots = Box::new([
                Dot::new(ctx, &kernels, &f, &f, n, &partials, &scalars, 0),
                Dot::new(ctx, &kernels, r_buf, r_buf, n, &partials, &scalars, 1),
                Dot::new(ctx, &kernels, &u, &u, n, &partials, &scalars, 2),
            ]);
            // The core's scale leaves each open contact's gap term s out of q and u; |u − s| is not
            // reduced here, so |u| − |s| (at most |u − s|) stands in: the estimate can only grow.
            let q_norm = (0..p.q.len()).map(|k| (p.q[k] - gap_term(&p.gap_rate, k)).powi(2)).sum::<f64>().sqrt();
            let gap_norm = p.gap_rate.iter().map(|g| g * g).sum::<f64>().sqrt();
            Estimate::Natural { residual, dots, scalars, q_norm, gap_norm, groups: groups(nc), _buffers: [f, partials] }
        };
        let snapshot = storage(ctx, "r at check", &vec![[0.0f32; 2]; nc]);
        Self { operator, kernels, estimate, r_buf: r_buf.clone(), snapshot, contacts: nc, counter, _u: u }
    }

    /// Submits the estimate of the impulses the solver's buffer holds now, keeping a copy of them
    /// on the GPU ([`Checker::snapshot`]); `with_impulses`: they come back with the estimate.
    fn submit(&self, ctx: &GpuContext, with_impulses: bool) -> PendingCheck {
        let k = &self.kernels;
        let mut reads = match &self.estimate {
            Estimate::Natural { scalars, .. } => vec![(&**scalars, 3 * 4)],
            Estimate::Velocity { partials, groups, .. } => vec![(&**partials, 8 * groups)],
        };
        if with_impulses {
            reads.push((&*self.r_buf, 8 * self.contacts));
        }
        if let Some(counter) = &self.counter {
            reads.push((&**counter, 4));
        }
        let mut encoder = encode_pass(ctx, "check", |pass| {
            self.operator.record(k, pass);
            match &self.estimate {
                Estimate::Natural { residual, dots, groups, .. } => {
                    dispatch(pass, &k.natural_map, residual, *groups);
                    for d in dots.iter() {
                        d.record(k, pass);
                    }
                }
                Estimate::Velocity { residual, groups, .. } => {
                    dispatch(pass, &k.velocity_residual, residual, *groups as u32)
                }
            }
        });
        // (wgpu copies no empty range)
        if self.contacts > 0 {
            encoder.copy_buffer_to_buffer(&self.r_buf, 0, &self.snapshot, 0, 8 * self.contacts as u64);
        }
        PendingCheck { read: submit_and_read(ctx, encoder, &reads), with_impulses }
    }

    /// Waits for a submitted check: its estimate (NaN for a diverged iterate), the impulses if
    /// they came back, and the update counter when there is one.
    fn finish(&self, ctx: &GpuContext, check: PendingCheck) -> Result<CheckResult, GpuError> {
        let mut parts = check.read.wait(ctx).map_err(GpuError::Runtime)?.into_iter();
        let floats = |bytes: Vec<u8>| bytemuck::pod_collect_to_vec::<u8, f32>(&bytes);
        let s = floats(parts.next().unwrap_or_default());
        let impulses = check.with_impulses.then(|| bytemuck::pod_collect_to_vec(&parts.next().unwrap_or_default()));
        let count = self.counter.as_ref().map(|_| {
            let bytes = parts.next().unwrap_or_default();
            bytemuck::pod_collect_to_vec::<u8, u32>(&bytes).first().copied().unwrap_or(0)
        });
        // The measure over its scale.
        let (measure, scale) = match &self.estimate {
            Estimate::Natural { q_norm, gap_norm, .. } => {
                let (f, r, u) = ((s[0] as f64).sqrt(), (s[1] as f64).sqrt(), (s[2] as f64).sqrt());
                (f, q_norm.max(r).max(u - gap_norm))
            }
            // (largest residual, finiteness witness) per chunk of contacts.
            Estimate::Velocity { scale, .. } => match s.chunks_exact(2).all(|pair| pair[1].is_finite()) {
                true => (s.chunks_exact(2).fold(0.0f64, |m, pair| m.max(pair[0] as f64)), *scale),
                false => (f64::NAN, *scale),
            },
        };
        let estimate = if scale > f64::EPSILON { measure / scale } else { measure };
        Ok((estimate, impulses, count))
    }

    /// The impulses of the last submitted check, read back (waits for all queued work).
    fn snapshot(&self, ctx: &GpuContext) -> Result<F32Impulses, GpuError> {
        read_back::<[f32; 2]>(ctx, &self.snapshot, self.contacts).map_err(GpuError::Runtime)
    }
}
