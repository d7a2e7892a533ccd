//! Shared bookkeeping of every solve: iteration count, operator products, wall time, error
//! history and the stopping decision.
//!
//! With the natural-map criterion the cheap "light" change `‖r_k − r_{k−1}‖/‖r_k‖` is watched
//! every iteration and the full f64 error is evaluated when it drops below an adaptive threshold
//! (Siconos' LIGHT_WITH_FULL_FINAL rule, notes §3.3), when the work since the last check makes
//! a check cost ≤ 10 % ([`super::stopping::CheckCadence`]: a warm-started solve whose light
//! change never falls stops at the first check that meets tol), or every iteration when the
//! solver already holds `u = W r + q`. A solve is `converged` only if the full error of the returned `r` is ≤ tol
//! (or, when asked, LMGC90's test holds); the final error is always reported.

use super::lmgc_criteria::LmgcMeasures;
use super::stopping::{check_work, stopped_falling, CheckCadence, JudgedMeasure, StopReason};
use super::{HistoryPoint, SolveReport, SolverKind, SolverOptions};
use crate::parallel::{all_finite, chunked_sum, copied, copy, equal};
use crate::problem::cone::project_box;
use crate::problem::residual::problem_error;
use crate::problem::{ContactProblem, Mat2};
use std::borrow::Cow;
use std::time::{Duration, Instant};

/// The bookkeeping of one solve (see the module's description).
pub struct Monitor<'a> {
    problem: &'a ContactProblem,
    opts: &'a SolverOptions,
    kind: SolverKind,
    start: Instant,
    excluded: Duration,
    /// Operator products so far.
    pub w_products: usize,
    iteration: usize,
    r_prev: Vec<f64>,
    /// Whether a small change between iterates calls a check (off: [`Self::without_light_rule`]).
    light_rule: bool,
    tol_light: f64,
    history: Vec<HistoryPoint>,
    /// W's diagonal blocks, for the LMGC90 tests.
    diag: Option<Cow<'a, [Mat2]>>,
    measure: JudgedMeasure,
    converged: bool,
    stop_reason: Option<(StopReason, String)>,
    cadence: CheckCadence,
    /// `w_products` after the previous iteration: the work of one iteration is the difference.
    products_seen: usize,
    scratch_u: Vec<f64>,
    /// `scratch_u = W r + q` of the iterate of this iteration, with its (error, judged): the
    /// final report of a solve stopped right after a check needs no product of its own.
    scratch_check: Option<(usize, f64, f64)>,
    /// `M⁻¹ Bᵀ r` of that product, on a matrix-free problem: handed to the caller with the
    /// iterate returned ([`SolveReport::body_velocity`]).
    scratch_body_velocity: Option<Vec<f64>>,
    iterates: Vec<Vec<f64>>,
    /// The checked iterate with the smallest judged error, returned if the solve does not converge.
    best: Option<(f64, Vec<f64>)>,
    notes: Vec<String>,
}

impl<'a> Monitor<'a> {
    /// Starts watching a solve of `problem` from `r0`.
    pub fn new(problem: &'a ContactProblem, opts: &'a SolverOptions, kind: SolverKind, r0: &[f64]) -> Self {
        let lmgc = !opts.criterion.judges_one_iterate();
        let diag = lmgc.then(|| problem.w.diag_blocks());
        Self {
            problem,
            opts,
            kind,
            start: Instant::now(),
            excluded: Duration::ZERO,
            w_products: 0,
            iteration: 0,
            r_prev: copied(r0),
            light_rule: true,
            tol_light: opts.tol,
            history: Vec::new(),
            diag,
            measure: JudgedMeasure::new(problem, opts.criterion),
            converged: false,
            stop_reason: None,
            cadence: CheckCadence::every(check_work(problem, opts.criterion)),
            products_seen: 0,
            scratch_u: crate::parallel::filled(r0.len(), 0.0),
            scratch_check: None,
            scratch_body_velocity: None,
            iterates: Vec::new(),
            best: None,
            notes: Vec::new(),
        }
    }

    /// Counts `k` products spent before the first iteration (set-up, not an iteration's work).
    pub fn add_setup_products(&mut self, k: usize) {
        self.w_products += k;
        self.products_seen += k;
    }

    /// Records something the solver chose on its own, for the report.
    pub fn note(&mut self, line: String) {
        self.notes.push(line);
    }

    /// Counts `k` iterations done outside [`Self::observe`] (a batch of sweeps observed once).
    pub fn add_iterations(&mut self, k: usize) {
        self.iteration += k;
    }

    /// Iterations so far.
    pub fn iteration(&self) -> usize {
        self.iteration
    }

    /// Solve time so far (s), excluded work (kept iterates, uncounted checks) left out.
    pub fn elapsed(&self) -> f64 {
        (self.start.elapsed() - self.excluded).as_secs_f64()
    }

    fn record(&mut self, error: f64, r: &[f64]) {
        let point =
            HistoryPoint { iteration: self.iteration, seconds: self.elapsed(), w_products: self.w_products, error };
        self.history.push(point);
        if self.opts.keep_iterates {
            let t = Instant::now();
            self.iterates.push(r.to_vec());
            self.excluded += t.elapsed();
        }
    }

    /// The f64 error of the iterate last observed, when that observation checked it.
    pub fn checked_error(&self) -> Option<f64> {
        self.history.last().filter(|h| h.iteration == self.iteration).map(|h| h.error)
    }

    /// Stops the solve early for a reason the solver knows (breakdown, stagnation).
    pub fn stop_with(&mut self, reason: StopReason, detail: impl Into<String>) {
        self.stop_reason.get_or_insert_with(|| (reason, detail.into()));
    }

    /// Checks by cost only, and when the solver asks ([`Self::observe_with_product`]): for a
    /// solver that knows when its iterate may meet the test (the work list, once its list is
    /// empty). There the change between iterates, which touch a few contacts each, is always
    /// small, and the light rule would check every iteration.
    pub fn without_light_rule(mut self) -> Self {
        self.light_rule = false;
        self
    }

    /// [`Self::observe`], with the full check made now on a product of its own, which
    /// [`Self::finish`] reuses when this iterate is the one returned.
    pub fn observe_with_product(&mut self, r: &[f64]) -> bool {
        self.observe_checking(r, None, true)
    }

    /// Called once per iteration with the new iterate (and `u = W r + q` if the solver has it).
    /// Returns true when the solve must stop.
    pub fn observe(&mut self, r: &[f64], u: Option<&[f64]>) -> bool {
        self.observe_checking(r, u, false)
    }

    /// [`Self::observe`]; with `check`, the full check is made whatever the cadence says.
    fn observe_checking(&mut self, r: &[f64], u: Option<&[f64]>, check: bool) -> bool {
        self.iteration += 1;
        if !all_finite(r) {
            self.stop_with(StopReason::Diverged, "diverged: the iterate holds NaN or Inf");
            return true;
        }
        // With the rule off, a change that never calls a check.
        let light = if !self.light_rule {
            f64::INFINITY
        } else {
            let nc = r.len() / 2;
            let prev = &self.r_prev;
            let d = chunked_sum(nc, |a| {
                let (x, y) = (r[2 * a] - prev[2 * a], r[2 * a + 1] - prev[2 * a + 1]);
                x * x + y * y
            })
            .sqrt();
            let n = chunked_sum(nc, |a| r[2 * a] * r[2 * a] + r[2 * a + 1] * r[2 * a + 1]).sqrt();
            // Same rule as the error's normalisation: below machine epsilon, judge absolutely.
            if n > f64::EPSILON {
                d / n
            } else {
                d
            }
        };
        let last = self.iteration >= self.opts.max_iter;
        let work = self.w_products - self.products_seen;
        let cost_due = self.cadence.after_iteration(work);
        let history_due = self.opts.history_every > 0 && self.iteration.is_multiple_of(self.opts.history_every);
        match self.opts.criterion {
            criterion if criterion.judges_one_iterate() => {
                let needed = u.is_some() || check || light <= self.tol_light || last || cost_due;
                if needed || history_due {
                    let (err, judged) = self.full_error(r, u, !needed);
                    if needed {
                        self.cadence.checked();
                    }
                    self.record(err, r);
                    if needed && self.best.as_ref().is_none_or(|(b, _)| judged < *b) {
                        match &mut self.best {
                            Some((b, kept)) => {
                                *b = judged;
                                copy(r, kept);
                            }
                            None => self.best = Some((judged, copied(r))),
                        }
                    }
                    if judged <= self.opts.tol {
                        self.converged = true;
                    } else if light <= self.tol_light && judged > 0.0 {
                        self.tol_light = (light * self.opts.tol / judged).min(self.tol_light);
                    }
                }
            }
            criterion => {
                let m = LmgcMeasures::compute(self.diag.as_ref().unwrap(), &self.r_prev, r, self.opts.tol);
                self.converged = m.satisfied(criterion);
                if history_due || self.converged {
                    let (err, _) = self.full_error(r, u, true);
                    self.record(err, r);
                }
            }
        }
        copy(r, &mut self.r_prev);
        self.products_seen = self.w_products;
        if self.converged {
            self.stop_with(StopReason::Converged, "converged");
        } else if last {
            self.stop_with(StopReason::MaxIter, format!("not converged: max_iter = {} reached", self.opts.max_iter));
        }
        self.stop_reason.is_some()
    }

    /// Full error of `r` and the measure the criterion judges (the same unless it is `Velocity`);
    /// one product unless `u` is given. `excluded` time is left out of the solve time.
    fn full_error(&mut self, r: &[f64], u: Option<&[f64]>, excluded: bool) -> (f64, f64) {
        let t = Instant::now();
        let mut uu = std::mem::take(&mut self.scratch_u);
        let own_product = u.is_none();
        let (u, err) = match u {
            Some(u) => (u, problem_error(self.problem, r, u)),
            None => {
                let (v, err) = self.problem.velocity_and_error(r, &mut uu);
                self.scratch_body_velocity = v;
                if !excluded {
                    self.w_products += 1;
                }
                (&uu[..], err)
            }
        };
        let judged = self.judged(r, u, err);
        self.scratch_u = uu;
        self.scratch_check = own_product.then_some((self.iteration, err, judged));
        if excluded {
            self.excluded += t.elapsed();
        }
        (err, judged)
    }

    /// The measure the criterion judges, of `r` with `u = W r + q`.
    fn judged(&self, r: &[f64], u: &[f64], error: f64) -> f64 {
        self.measure.of(self.problem, r, u, error)
    }

    /// Final report: `u` and the error of the returned `r` are recomputed in f64 here. A solve
    /// that did not converge returns its best checked iterate when that is better than its last.
    pub fn finish(mut self, mut r: Vec<f64>) -> SolveReport {
        let seconds = self.elapsed();
        let lmgc = !self.opts.criterion.judges_one_iterate();
        // The last check's product, when it was of the iterate returned (the same bits).
        let mut body_velocity = None;
        let (mut u, mut error, mut judged) = match self.scratch_check.take() {
            Some((iteration, error, judged)) if iteration == self.iteration && equal(&r, &self.r_prev) => {
                body_velocity = self.scratch_body_velocity.take();
                (std::mem::take(&mut self.scratch_u), error, judged)
            }
            _ => {
                let u = self.problem.velocity(&r);
                let error = problem_error(self.problem, &r, &u);
                let judged = self.judged(&r, &u, error);
                (u, error, judged)
            }
        };
        if let (Some((best, mut kept)), false) = (self.best.take(), lmgc) {
            if judged.is_nan() || (judged > self.opts.tol && best < judged) {
                // Some solvers (APGD) iterate in a box that lags the cone: land on the cone first.
                for (a, &m) in self.problem.mu.iter().enumerate() {
                    let ra = project_box([kept[2 * a], kept[2 * a + 1]], m);
                    kept[2 * a..2 * a + 2].copy_from_slice(&ra);
                }
                let kept_u = self.problem.velocity(&kept);
                let kept_error = problem_error(self.problem, &kept, &kept_u);
                let kept_judged = self.judged(&kept, &kept_u, kept_error);
                if judged.is_nan() || kept_judged < judged {
                    (r, u, error, judged) = (kept, kept_u, kept_error, kept_judged);
                    body_velocity = None;
                }
            }
        }
        let converged = if lmgc { self.converged && error.is_finite() } else { judged <= self.opts.tol };
        let (mut stop, mut detail) = self.stop_reason.take().unwrap_or((StopReason::MaxIter, "not converged".into()));
        if converged {
            stop = StopReason::Converged;
        } else if stop == StopReason::Converged {
            // A test held at a check, but the error of what is returned is not finite or above tol.
            (stop, detail) = (StopReason::Stalled, "not converged: the returned impulses miss the tolerance".into());
        }
        if self.history.last().map(|h| h.iteration) != Some(self.iteration) {
            self.history.push(HistoryPoint { iteration: self.iteration, seconds, w_products: self.w_products, error });
            if self.opts.keep_iterates {
                self.iterates.push(r.clone());
            }
        }
        if stop == StopReason::MaxIter && !lmgc {
            self.notes.extend(stopped_falling(&self.history, self.iteration));
        }
        SolveReport {
            solver: self.kind,
            converged,
            iterations: self.iteration,
            error,
            judged_error: if lmgc { error } else { judged },
            seconds,
            w_products: self.w_products,
            history: self.history,
            stop,
            stop_reason: detail,
            notes: self.notes,
            parts: Vec::new(),
            gpu_dispatches: 0,
            gpu_bytes: 0,
            gpu_checks: Default::default(),
            r,
            u,
            body_velocity,
            iterates: self.iterates,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{solve, Ordering, SolverKind, SolverOptions};
    use crate::problem::generate::lattice_packing;
    use crate::problem::Delassus;

    /// The bodies' velocities a solve hands on with its answer (a step then makes no product of
    /// its own) are those of the impulses returned, bit for bit. A converged NLGS solve, in
    /// order or on a work list, hands them on; the colour ordering, which sums over the contacts
    /// renumbered, hands none.
    #[test]
    fn handed_body_velocities_are_those_of_the_returned_impulses() {
        let p = lattice_packing(12, 8, 0.3, 4);
        let Delassus::MatrixFree(op) = &p.w else { panic!("a matrix-free problem") };
        for ordering in [Ordering::Forward, Ordering::Worklist, Ordering::Colours] {
            for (tol, max_iter) in [(1e-6, 5000), (1e-14, 30)] {
                let opts = SolverOptions { tol, max_iter, ordering, ..Default::default() };
                let report = solve(&p, SolverKind::Nlgs, &opts, None);
                let case = format!("{ordering:?}, tol {tol:e}, converged {}", report.converged);
                match &report.body_velocity {
                    Some(v) => assert!(*v == op.body_velocities(&report.r), "{case}"),
                    None => assert!(ordering == Ordering::Colours || !report.converged, "{case}: none handed on"),
                }
                if ordering == Ordering::Colours {
                    assert!(report.body_velocity.is_none(), "{case}");
                }
            }
        }
    }
}
