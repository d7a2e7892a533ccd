//! The one stopping policy of every solve, CPU ([`super::monitor`]) and GPU (`gpu/driver.rs`):
//! the measure a tolerance is read in, why a solve stopped, how often the full error is checked,
//! and when a solve has stalled.

use serde::Serialize;
use std::fmt;

use super::{HistoryPoint, SolveReport, StopCriterion};
use crate::problem::residual::{free_velocity_bound, loaded_approach, velocity_error_scaled};
use crate::problem::{ContactProblem, Delassus, Mat2};

/// The f64 measure a criterion compares with `tol`: the natural-map error, or under a velocity
/// test (`velocity`, `step-velocity`) the worst contact's residual in velocity units over the
/// test's scale (which needs the diagonal blocks of W, taken once). The LMGC90 tests judge changes
/// between iterates, not a measure of one, and read the natural map here.
#[derive(Clone, Debug)]
pub struct JudgedMeasure {
    /// The blocks (kept for an explicit `W` only: a matrix-free operator keeps its own) and the
    /// scale.
    velocity_test: Option<(Vec<Mat2>, f64)>,
}

impl JudgedMeasure {
    /// The measure `criterion` judges `problem` by.
    pub fn new(problem: &ContactProblem, criterion: StopCriterion) -> Self {
        let velocity_test = criterion.is_velocity_test().then(|| {
            let kept = match &problem.w {
                Delassus::MatrixFree(_) => Vec::new(),
                Delassus::Sparse(_) => problem.w.diag_blocks().into_owned(),
            };
            (kept, velocity_scale(problem, criterion))
        });
        Self { velocity_test }
    }

    /// Of `r` with `u = W r + q`, whose natural-map error is `natural` (`p` the problem the
    /// measure was made for).
    pub fn of(&self, p: &ContactProblem, r: &[f64], u: &[f64], natural: f64) -> f64 {
        match &self.velocity_test {
            Some((kept, scale)) => {
                let d = match &p.w {
                    Delassus::MatrixFree(op) => op.diag_blocks(),
                    Delassus::Sparse(_) => kept,
                };
                velocity_error_scaled(d, &p.mu, &p.rolling, *scale, r, u)
            }
            None => natural,
        }
    }
}

/// What a velocity test divides the worst contact residual by: one step of the applied
/// acceleration under `step-velocity` when the problem has one, else the largest free velocity
/// (gap terms out), which one fast grain sets for the whole pile.
pub fn velocity_scale(p: &ContactProblem, criterion: StopCriterion) -> f64 {
    match criterion == StopCriterion::StepVelocity && p.velocity_floor > 0.0 {
        true => p.velocity_floor,
        false => free_velocity_bound(&p.q, &p.gap_rate),
    }
}

/// Why a solve stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The judged error of the returned impulses is at most the tolerance.
    Converged,
    /// The iteration budget ran out first.
    MaxIter,
    /// The error stopped improving (on the GPU: the f32 floor of the problem).
    Stalled,
    /// The iterate became non-finite.
    Diverged,
    /// The method broke down (a zero curvature in a conjugate gradient).
    Breakdown,
    /// The impulses grew without stopping the contacts they load ([`refuse_unbounded`]): the
    /// relative error shrank only because `‖r‖` grew.
    Unbounded,
}

impl StopReason {
    /// The name reports use.
    pub fn name(self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::MaxIter => "max_iter",
            StopReason::Stalled => "stalled",
            StopReason::Diverged => "diverged",
            StopReason::Breakdown => "breakdown",
            StopReason::Unbounded => "unbounded",
        }
    }
}

impl fmt::Display for StopReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The share of the largest free velocity at which the contacts an answer loads may still close
/// ([`loaded_approach`], weighted by their impulses) before the answer counts as none. The
/// shipped scenes' answers stay below 0.18 even at a natural tol of 0.3 (2 t grains), below 0.015
/// at 1e-2, and the Siconos files' below 0.012; a problem with no answer gives 1.
pub const MAX_LOADED_APPROACH: f64 = 0.5;

/// Marks a converged `report` of `problem` as not converged ([`StopReason::Unbounded`]) when
/// its impulses stop nothing: its loaded contacts still close at [`MAX_LOADED_APPROACH`] of the
/// largest free velocity or more. Under the Siconos scale `max(‖q‖, ‖r‖, ‖u‖)` the residual of
/// impulses that grow and cancel stays O(‖q‖) while their norm grows, so the relative error of a
/// problem with no answer (contacts pressed from opposite sides at once) falls below any tol:
/// NLGS, LATIN, Newton, APGD and the interior point all called one converged.
pub fn refuse_unbounded(problem: &ContactProblem, report: &mut SolveReport) {
    if !report.converged || report.r.len() < 2 * problem.mu.len() {
        return;
    }
    let approach = loaded_approach(&problem.q, &problem.gap_rate, problem.mu.len(), &report.r, &report.u);
    if approach >= MAX_LOADED_APPROACH {
        let largest = report.r.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
        report.converged = false;
        report.stop = StopReason::Unbounded;
        report.stop_reason = format!(
            "unbounded: the contacts the impulses load still close at {:.0} % of the largest free velocity \
             (impulses up to {largest:.3e}); the relative error {:.3e} fell only because the impulses grew. \
             The problem may have no answer (contacts pressed from opposite sides at once), or its masses \
             make the natural criterion too loose (try --criterion velocity)",
            100.0 * approach,
            report.error
        );
    }
}

/// Checking once this many product-equivalents of work keeps checks at ≤ 10 % of a solve; a
/// Gauss–Seidel sweep counts as one, so NLGS is checked at least every 10 sweeps. A full check is
/// a product and the error's pass, and costs at most a sweep: `moreau bench --scene` measured
/// 0.96–1.11 sweeps on the 10,000-disk pile and 1.12–1.21 on the 40,000 (one and two threads,
/// two runs). A check under a velocity test adds that test's pass (0.52–0.55 ms against a sweep's
/// 0.76–0.99 on the 10,000-disk pile's first problem, one thread).
pub const CHECK_WORK: usize = 10;

/// [`CHECK_WORK`] for a check made in one pass ([`ContactProblem::error_in_product`] under the
/// natural map): 0.44–0.51 of a sweep on the 10,000-disk pile's first problem (one thread) once
/// the product's gather called no `memmove` per contact and took the error's terms as it went,
/// so a check every 5 sweeps' worth stays near 10 %. The 10,000-disk pile at rest under the
/// natural map at 1e-4 met tol by its fifth sweep: checked at the tenth, each step made twice the
/// sweeps it needed (BENCHMARKS.md, "The cadence of a one-pass check").
pub const ONE_PASS_CHECK_WORK: usize = 5;

/// Product-equivalents of work between two checks of `problem` under `criterion` (≤ 10 % of a
/// solve): [`ONE_PASS_CHECK_WORK`] where a check is one pass, [`CHECK_WORK`] otherwise.
pub fn check_work(problem: &ContactProblem, criterion: StopCriterion) -> usize {
    match criterion == StopCriterion::Natural && problem.error_in_product() {
        true => ONE_PASS_CHECK_WORK,
        false => CHECK_WORK,
    }
}

/// Decides when the full error is due, by work done since the last check.
#[derive(Clone, Debug)]
pub struct CheckCadence {
    every: usize,
    work_since_check: usize,
}

impl Default for CheckCadence {
    fn default() -> Self {
        Self::every(CHECK_WORK)
    }
}

impl CheckCadence {
    /// A check due once `work` product-equivalents were done since the last ([`check_work`]).
    pub fn every(work: usize) -> Self {
        Self { every: work.max(1), work_since_check: 0 }
    }

    /// Records one iteration that cost `work` product-equivalents (at least 1) and says whether a
    /// check is due by cost.
    pub fn after_iteration(&mut self, work: usize) -> bool {
        self.work_since_check += work.max(1);
        self.work_since_check >= self.every
    }

    /// A check happened (for whatever reason): the work count starts again.
    pub fn checked(&mut self) {
        self.work_since_check = 0;
    }
}

/// Iterations without a 1 % improvement of the error before a solve is declared stalled: at
/// least this many, and at least as many as it took to get there.
pub const STALLED_ITERATIONS: usize = 500;

/// Watches the checked errors for progress.
#[derive(Clone, Debug)]
pub struct StallWatch {
    mark: f64,
    improved_at: usize,
}

impl StallWatch {
    /// Watches errors from `initial_error`.
    pub fn new(initial_error: f64) -> Self {
        Self { mark: initial_error, improved_at: 0 }
    }

    /// Records the error checked after `iteration` iterations.
    pub fn record(&mut self, iteration: usize, error: f64) {
        if error < 0.99 * self.mark {
            (self.mark, self.improved_at) = (error, iteration);
        }
    }

    /// The error it stalled near, once no 1 % gain came for long enough.
    pub fn stalled(&self, iteration: usize) -> Option<f64> {
        (iteration - self.improved_at >= STALLED_ITERATIONS.max(self.improved_at)).then_some(self.mark)
    }
}

/// Checks of each of the last two quarters of a solve below which [`stopped_falling`] says
/// nothing: too few to tell a wandering error from a falling one.
const QUARTER_CHECKS: usize = 8;
/// Median ratio of the last quarter's checks to the quarter before's above which the error has
/// stopped falling: an error falling as k^−0.3 or faster (NLGS's crawl on deposits falls as
/// 1/k – k^−0.75 while it converges) gives 0.9 or less.
const NOT_FALLING: f64 = 0.9;

/// A note for a solve that ran out of iterations with its error no longer falling: on
/// frictional deposits NLGS's error wanders in a band for millions of sweeps (BENCHMARKS.md,
/// "NLGS on the frictional deposits does not converge"), where more iterations would not help.
/// Compares the median error of the checks of the last quarter of the `iterations` with that of
/// the quarter before.
pub(crate) fn stopped_falling(history: &[HistoryPoint], iterations: usize) -> Option<String> {
    let quarter = |from: usize, to: usize| {
        let mut e: Vec<f64> = history
            .iter()
            .filter(|h| h.iteration > from && h.iteration <= to && h.error.is_finite())
            .map(|h| h.error)
            .collect();
        e.sort_by(f64::total_cmp);
        e
    };
    let (earlier, last) = (quarter(iterations / 2, 3 * iterations / 4), quarter(3 * iterations / 4, iterations));
    if earlier.len() < QUARTER_CHECKS || last.len() < QUARTER_CHECKS {
        return None;
    }
    let median = |e: &[f64]| e[e.len() / 2];
    (median(&last) > NOT_FALLING * median(&earlier)).then(|| {
        format!(
            "the error stopped falling: the median of its checks over the last quarter of the iterations \
             ({:.2e}) is no lower than over the quarter before ({:.2e}), the checks ranging {:.2e} – {:.2e}; \
             more iterations of this solver are unlikely to reach tol",
            median(&last),
            median(&earlier),
            earlier[0].min(last[0]),
            earlier[earlier.len() - 1].max(last[last.len() - 1])
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cadence_is_due_after_ten_units_of_work() {
        let mut c = CheckCadence::default();
        let due: Vec<bool> = (0..12).map(|_| c.after_iteration(0)).collect();
        assert_eq!(due.iter().position(|&d| d), Some(CHECK_WORK - 1));
        c.checked();
        assert!(!c.after_iteration(1));
        assert!(c.after_iteration(20), "an iteration worth 20 products is checked at once");
        let mut c = CheckCadence::every(ONE_PASS_CHECK_WORK);
        let due: Vec<bool> = (0..12).map(|_| c.after_iteration(1)).collect();
        assert_eq!(due.iter().position(|&d| d), Some(ONE_PASS_CHECK_WORK - 1));
    }

    #[test]
    fn stall_needs_no_gain_for_as_long_as_it_took() {
        let mut s = StallWatch::new(1.0);
        s.record(1000, 1e-3);
        assert!(s.stalled(1999).is_none());
        assert_eq!(s.stalled(2000), Some(1e-3));
        s.record(2000, 0.995e-3);
        assert!(s.stalled(2000).is_some(), "a gain below 1 % is no progress");
    }

    /// A closed contact whose free velocity is 2 m/s and a resting one off by 1e-3 m/s: the
    /// velocity test reads 1e-3 / 2, the step-velocity test 1e-3 / g h once the step names its
    /// floor, and the velocity test's reading without one (a problem from a file).
    #[test]
    fn the_step_velocity_test_divides_by_the_floor_when_the_problem_has_one() {
        use crate::problem::{BlockSparse, Delassus};
        let block = [1.0, 0.0, 0.0, 1.0];
        let w = Delassus::Sparse(BlockSparse::from_block_triplets(2, vec![(0, 0, block), (1, 1, block)]));
        let p = ContactProblem::new(w, vec![-1e-3, 0.0, -2.0, 0.0], vec![0.5, 0.5]).unwrap();
        // Contact 1 is solved (r_n = 2, u = 0); contact 0 closes at 1e-3 with no impulse.
        let r = [0.0, 0.0, 2.0, 0.0];
        let u = p.velocity(&r);
        let judged = |p: &ContactProblem, c| JudgedMeasure::new(p, c).of(p, &r, &u, f64::NAN);
        assert!((judged(&p, StopCriterion::Velocity) - 1e-3 / 2.0).abs() < 1e-15);
        assert_eq!(judged(&p, StopCriterion::StepVelocity), judged(&p, StopCriterion::Velocity));
        let stepped = p.clone().with_velocity_floor(9.81e-3).unwrap();
        assert!((judged(&stepped, StopCriterion::StepVelocity) - 1e-3 / 9.81e-3).abs() < 1e-15);
        assert_eq!(judged(&stepped, StopCriterion::Velocity), judged(&p, StopCriterion::Velocity));
        assert!(judged(&stepped, StopCriterion::Natural).is_nan(), "the natural map is the caller's");
        assert!(p.with_velocity_floor(-1.0).is_err());
    }

    fn history(errors: impl Iterator<Item = (usize, f64)>) -> Vec<HistoryPoint> {
        errors
            .map(|(iteration, error)| HistoryPoint { iteration, seconds: 0.0, w_products: iteration, error })
            .collect()
    }

    /// An error wandering in a band is said to have stopped falling; one falling as 1/k, or
    /// checked too seldom to tell, is not.
    #[test]
    fn a_wandering_error_is_told_from_a_falling_one() {
        let wandering = history((1..=1000).map(|c| (10 * c, 6e-5 * (1.0 + 0.9 * ((c * 7919) % 13) as f64 / 13.0))));
        let note = stopped_falling(&wandering, 10_000).expect("a note for a wandering error");
        assert!(note.starts_with("the error stopped falling"), "{note}");
        let falling = history((1..=1000).map(|c| (10 * c, 1.0 / (10 * c) as f64)));
        assert_eq!(stopped_falling(&falling, 10_000), None);
        let seldom = history((1..=10).map(|c| (1000 * c, 6e-5)));
        assert_eq!(stopped_falling(&seldom, 10_000), None, "two or three checks a quarter are too few");
    }
}
