//! The JSON written by `moreau solve --out`.

use crate::solvers::{HistoryPoint, SolveReport, SolverKind, SolverOptions, StopCriterion};
use serde::Serialize;

#[derive(Serialize)]
pub struct SolveOutput<'a> {
    pub problem: &'a str,
    pub solver: SolverKind,
    pub device: &'a str,
    /// The GPU adapter's name when `device` is `gpu`.
    pub adapter: Option<&'a str>,
    pub contacts: usize,
    pub tol: f64,
    pub criterion: StopCriterion,
    pub converged: bool,
    pub iterations: usize,
    pub error: f64,
    pub seconds: f64,
    pub w_products: usize,
    pub stop_reason: &'a str,
    pub history: &'a [HistoryPoint],
    pub r: &'a [f64],
    pub u: &'a [f64],
}

impl<'a> SolveOutput<'a> {
    pub fn new(problem: &'a str, device: &'a str, opts: &SolverOptions, rep: &'a SolveReport) -> Self {
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
            seconds: rep.seconds,
            w_products: rep.w_products,
            stop_reason: &rep.stop_reason,
            history: &rep.history,
            r: &rep.r,
            u: &rep.u,
        }
    }
}

/// The one-line summary printed after a solve.
pub fn summary_line(rep: &SolveReport, device: &str, tol: f64) -> String {
    format!(
        "{} on {}: {} contacts, {} after {} iterations, error {:.3e} (tol {:.1e}), {:.4} s, {} W-products",
        rep.solver,
        device,
        rep.r.len() / 2,
        if rep.converged { "converged" } else { "NOT CONVERGED" },
        rep.iterations,
        rep.error,
        tol,
        rep.seconds,
        rep.w_products
    )
}
