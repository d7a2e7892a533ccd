//! The structural study of the founding paper's punch (Fig. 17.1): LATIN's search direction
//! swept, then every solver — and LATIN at the best k found — recorded at every iteration, as
//! work-precision runs and with their energy-norm errors.

use super::Run;
use crate::solvers::{HistoryPoint, LatinK, SolverKind, SolverOptions};
use crate::structure::study::{latin_k_sweep, run, LatinKRow, PunchProblems, StructuralRun, StructuralSolver};

/// What the study found.
pub struct StructuralStudy {
    /// LATIN's iterations for each factor of k (mean or per-contact diagonal).
    pub latin_k: Vec<LatinKRow>,
    /// One work-precision run per solver (labels name LATIN's best k).
    pub runs: Vec<Run>,
    /// Each run's iterates with their energy-norm errors, by label.
    pub energy: Vec<(String, StructuralRun)>,
}

impl StructuralStudy {
    /// LATIN's best converged factor (fewest iterations, then least time), for k = factor × the
    /// mean diagonal of M, or × diag M per contact.
    pub fn best_latin_factor(&self, per_contact_diagonal: bool) -> Option<&LatinKRow> {
        best_factor(&self.latin_k, per_contact_diagonal)
    }
}

fn best_factor(rows: &[LatinKRow], per_contact_diagonal: bool) -> Option<&LatinKRow> {
    rows.iter()
        .filter(|r| r.per_contact_diagonal == per_contact_diagonal && r.converged)
        .min_by(|x, y| x.iterations.cmp(&y.iterations).then(x.seconds.total_cmp(&y.seconds)))
}

/// Runs the study of `problems` (named `name`) to `opts.tol`, LATIN's k swept over `factors`;
/// `say` is told of each solver's result.
pub fn structural_study(
    name: &str,
    problems: &PunchProblems,
    solvers: &[StructuralSolver],
    factors: &[f64],
    opts: &SolverOptions,
    say: &mut dyn FnMut(String),
) -> StructuralStudy {
    // Every iteration is recorded: the paper's Fig. 17.1 is error against iterations.
    let opts = SolverOptions { history_every: 1, ..opts.clone() };
    let latin_k = latin_k_sweep(problems, factors, opts.tol, opts.max_iter);
    let mut labelled: Vec<(String, StructuralSolver, SolverOptions)> =
        solvers.iter().map(|&s| (s.name().to_string(), s, opts.clone())).collect();
    let latin = StructuralSolver::Primal(SolverKind::Latin);
    if let (Some(b), true) = (best_factor(&latin_k, false), solvers.contains(&latin)) {
        let best = SolverOptions { latin_k: LatinK::Factor(b.factor), latin_k_mean: true, ..opts.clone() };
        labelled.push((format!("latin k={}·mean", b.factor), latin, best));
    }
    if solvers.contains(&latin) {
        // The automatic factor and the fixed factor 1 side by side (one of them is `latin`'s).
        let other = if opts.latin_k == LatinK::Auto { LatinK::Factor(1.0) } else { LatinK::Auto };
        let mean = if opts.latin_k_mean { "·mean" } else { "" };
        labelled.push((format!("latin k={other}{mean}"), latin, SolverOptions { latin_k: other, ..opts.clone() }));
    }
    let mut runs = Vec::new();
    let mut energy = Vec::new();
    for (label, solver, opts) in &labelled {
        let r = run(problems, *solver, opts);
        say(format!(
            "{name}: {label}: error {:.2e}, energy-norm error {:.2e} after {} its, {:.4} s ({})",
            r.error(),
            r.energy_error(),
            r.iterations,
            r.seconds,
            r.stop_reason
        ));
        let history = r
            .points
            .iter()
            .map(|p| HistoryPoint {
                iteration: p.iteration,
                seconds: p.seconds,
                w_products: p.w_products,
                error: p.error,
            })
            .collect();
        runs.push(Run {
            problem: name.to_string(),
            contacts: problems.primal.n,
            solver: label.clone(),
            device: "cpu",
            history,
            converged: r.converged,
            iterations: r.iterations,
            error: r.error(),
            seconds: r.seconds,
            stop_reason: r.stop_reason.clone(),
        });
        energy.push((label.clone(), r));
    }
    StructuralStudy { latin_k, runs, energy }
}
