//! The JSON written by `moreau solve --out`.

use crate::problem::residual::velocity_error_rolling;
use crate::problem::ContactProblem;
use crate::solvers::{HistoryPoint, SolvePart, SolveReport, SolverKind, SolverOptions, StopCriterion};
use serde::Serialize;

/// The JSON of one solve: its setting, its result and its history.
#[derive(Serialize)]
pub struct SolveOutput<'a> {
    /// The problem's name.
    pub problem: &'a str,
    /// The solver.
    pub solver: SolverKind,
    /// `cpu` or `gpu`.
    pub device: &'a str,
    /// The GPU adapter's name when `device` is `gpu`.
    pub adapter: Option<&'a str>,
    /// Contacts.
    pub contacts: usize,
    /// Tolerance asked for.
    pub tol: f64,
    /// The stopping criterion.
    pub criterion: StopCriterion,
    /// Whether the answer meets the tolerance.
    pub converged: bool,
    /// Iterations done.
    pub iterations: usize,
    /// The f64 natural-map error of the answer.
    pub error: f64,
    /// The f64 error the stopping test judged (the velocity measure under `criterion =
    /// velocity`, else `error`).
    pub judged_error: f64,
    /// Solve time (s).
    pub seconds: f64,
    /// Operator products.
    pub w_products: usize,
    /// Why the solve stopped.
    pub stop_reason: &'a str,
    /// The answer's worst contact residual in velocity units over the largest free velocity
    /// (the velocity test's measure, whatever the criterion): where heavy grains' impulses
    /// dominate the natural map's scale, what the natural-map error does not show.
    pub velocity_error: f64,
    /// What the solver chose on its own (LATIN's search direction, Newton's refused directions).
    pub notes: &'a [String],
    /// The error at the checks.
    pub history: &'a [HistoryPoint],
    /// A solve split across devices, part by part (device, iterations, seconds, error, stop):
    /// f32 sweeps on a GPU, then an f64 finish on the CPU; empty when one device did it all.
    pub parts: &'a [SolvePart],
    /// Iterations run on a GPU.
    pub gpu_iterations: usize,
    /// The impulses.
    pub r: &'a [f64],
    /// Their velocities `W r + q`.
    pub u: &'a [f64],
}

impl<'a> SolveOutput<'a> {
    /// The output of `rep`, a solve of the problem named `problem` on `device` with `opts`;
    /// `velocity_error` is the answer's ([`answer_velocity_error`]).
    pub fn new(
        problem: &'a str,
        device: &'a str,
        opts: &SolverOptions,
        rep: &'a SolveReport,
        velocity_error: f64,
    ) -> Self {
        Self {
            problem,
            solver: rep.solver,
            device,
            adapter: None,
            contacts: rep.r.len() / 2,
            tol: opts.tol,
            criterion: opts.criterion,
            converged: rep.converged,
            iterations: rep.iterations,
            error: rep.error,
            judged_error: rep.judged_error,
            seconds: rep.seconds,
            w_products: rep.w_products,
            stop_reason: &rep.stop_reason,
            velocity_error,
            notes: &rep.notes,
            history: &rep.history,
            parts: &rep.parts,
            gpu_iterations: rep.gpu_iterations(),
            r: &rep.r,
            u: &rep.u,
        }
    }
}

/// The velocity test's measure of `rep`'s answer to `problem`: its worst contact's residual in
/// velocity units over the largest free velocity, rolling rows included.
pub fn answer_velocity_error(problem: &ContactProblem, rep: &SolveReport) -> f64 {
    let p = problem;
    velocity_error_rolling(&p.w.diag_blocks(), &p.q, &p.mu, &p.rolling, &p.gap_rate, &rep.r, &rep.u)
}

/// The one-line summary printed after a solve: the error the stopping test judged, and the
/// natural-map error beside it when that is another measure.
pub fn summary_line(rep: &SolveReport, device: &str, tol: f64) -> String {
    let natural = match rep.judged_error == rep.error {
        true => String::new(),
        false => format!(" (natural-map error {:.3e})", rep.error),
    };
    format!(
        "{} on {}: {} contacts, {} after {} iterations, error {:.3e} (tol {:.1e}){natural}, {:.4} s, {} W-products",
        rep.solver,
        device,
        rep.r.len() / 2,
        if rep.converged { "converged" } else { "NOT CONVERGED" },
        rep.iterations,
        rep.judged_error,
        tol,
        rep.seconds,
        rep.w_products
    )
}
