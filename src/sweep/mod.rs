//! What accuracy costs in time (notes §7.4): every solver × device on a set of problems, each
//! solved once to the tightest tolerance while its error history (f64, the core's measure) is
//! recorded against wall time and W-products; the time to each tolerance is read off that
//! history. Also the Dolan–Moré performance profiles (`profile.rs`), the problems a sweep runs
//! on (`problems.rs`) and the structural study of the founding paper's punch (`structural.rs`).

pub mod problems;
pub mod profile;
pub mod structural;

use crate::backend::{Backend, BackendError};
use crate::problem::ContactProblem;
use crate::solvers::{HistoryPoint, SolverKind, SolverOptions};

/// One solver on one device on one problem: its history and its final state.
#[derive(Clone, Debug)]
pub struct Run {
    /// The problem's name.
    pub problem: String,
    /// Its contacts.
    pub contacts: usize,
    /// The solver's name (a core solver, or `dual_cg` on a structural problem).
    pub solver: String,
    /// Where it ran: `cpu` or `gpu` ([`Backend::name`]).
    pub device: &'static str,
    /// The error against time and work.
    pub history: Vec<HistoryPoint>,
    /// Whether it met the tightest tolerance.
    pub converged: bool,
    /// Iterations done.
    pub iterations: usize,
    /// Final error.
    pub error: f64,
    /// Seconds.
    pub seconds: f64,
    /// Why it stopped.
    pub stop_reason: String,
}

/// One row of `work_precision.csv`: a run judged at one tolerance.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// The problem's name.
    pub problem: String,
    /// Its contacts.
    pub contacts: usize,
    /// The solver's name.
    pub solver: String,
    /// `cpu` or `gpu`.
    pub device: String,
    /// The tolerance this row judges at.
    pub tol: f64,
    /// Whether the history reached it.
    pub converged: bool,
    /// Iterations to reach it (or done).
    pub iterations: usize,
    /// The error then.
    pub error: f64,
    /// Seconds to reach it (or spent).
    pub seconds: f64,
    /// Operator products to reach it (or done).
    pub w_products: usize,
}

impl Run {
    /// The first point of the history at or below `tol` (a solve judged at that tolerance), or
    /// the final state, not converged.
    pub fn at(&self, tol: f64) -> Row {
        let hit = self.history.iter().find(|h| h.error <= tol);
        let last = self.history.last();
        let (converged, point) = match hit {
            Some(h) => (true, *h),
            None => (
                false,
                HistoryPoint {
                    iteration: self.iterations,
                    seconds: self.seconds,
                    w_products: last.map(|h| h.w_products).unwrap_or(0),
                    error: self.error,
                },
            ),
        };
        Row {
            problem: self.problem.clone(),
            contacts: self.contacts,
            solver: self.solver.clone(),
            device: self.device.into(),
            tol,
            converged,
            iterations: point.iteration,
            error: point.error,
            seconds: point.seconds,
            w_products: point.w_products,
        }
    }
}

/// Solves `problem` with `solver` on `backend` to `tol` (the tightest of the sweep), recording
/// the error history: every iteration up to 2,000 iterations, then about 1,000 points in all.
pub fn run_one(
    name: &str,
    problem: &ContactProblem,
    solver: SolverKind,
    backend: &Backend,
    tol: f64,
    max_iter: usize,
) -> Result<Run, BackendError> {
    let opts = SolverOptions { tol, max_iter, history_every: (max_iter / 1000).max(1), ..SolverOptions::default() };
    let device = backend.name();
    let report = backend.solve(problem, solver, &opts, None)?;
    let mut history = report.history.clone();
    // The history is monotone in time; make it end on the returned state.
    if history.last().is_none_or(|h| h.iteration != report.iterations) {
        history.push(HistoryPoint {
            iteration: report.iterations,
            seconds: report.seconds,
            w_products: report.w_products,
            error: report.error,
        });
    }
    Ok(Run {
        problem: name.to_string(),
        contacts: problem.n_contacts(),
        solver: solver.name().to_string(),
        device,
        history,
        converged: report.converged,
        iterations: report.iterations,
        error: report.error,
        seconds: report.seconds,
        stop_reason: report.stop_reason,
    })
}

/// Every solver of `kinds` on every problem on every backend, each to `tol` with its history;
/// a solve a backend cannot do is skipped and `say` is told why (and of each run).
pub fn work_precision(
    problems: &[(String, ContactProblem)],
    kinds: &[SolverKind],
    backends: &[&Backend],
    tol: f64,
    max_iter: usize,
    say: &mut dyn FnMut(String),
) -> Result<Vec<Run>, BackendError> {
    let mut runs = Vec::new();
    for (name, p) in problems {
        for &solver in kinds {
            for backend in backends {
                if let Err(e) = backend.check(solver, &SolverOptions::default()) {
                    let why = match e {
                        BackendError::Refused(why) => why,
                        other => other.to_string(),
                    };
                    say(format!("{name}: {} skipped on the {} ({why})", solver.name(), backend.name()));
                    continue;
                }
                let run = run_one(name, p, solver, backend, tol, max_iter)?;
                say(format!(
                    "{name} ({} contacts): {} on {}: error {:.2e} after {} its, {:.3} s ({})",
                    p.n_contacts(),
                    solver.name(),
                    backend.name(),
                    run.error,
                    run.iterations,
                    run.seconds,
                    run.stop_reason
                ));
                runs.push(run);
            }
        }
    }
    Ok(runs)
}

/// Markdown table of the time to each tolerance (– where it was not reached).
pub fn markdown_table(runs: &[Run], tols: &[f64]) -> String {
    let mut s = String::from("| problem | solver | device |");
    for t in tols {
        s.push_str(&format!(" {t:.0e} |"));
    }
    s.push_str("\n|---|---|---|");
    s.push_str(&"---|".repeat(tols.len()));
    s.push('\n');
    for r in runs {
        s.push_str(&format!("| {} | {} | {} |", r.problem, r.solver, r.device));
        for &t in tols {
            let row = r.at(t);
            if row.converged {
                s.push_str(&format!(" {:.3} s ({} its) |", row.seconds, row.iterations));
            } else {
                s.push_str(" – |");
            }
        }
        s.push('\n');
    }
    s
}
