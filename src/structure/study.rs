//! What the structural problem shows about the solvers (founding paper, Fig. 17.1): each solver's
//! convergence in the energy norm, `‖z − z*‖_M / ‖z*‖_M` against an exact reference `z*`, next to
//! the core's natural-map error against time; and where LATIN's search direction `k` is best.

use std::fmt;

use super::{dual_cg, Lcp, PunchModel, StructureError};
use crate::solvers::{solve, LatinK, SolverKind, SolverOptions};

/// A solver of the structural problem: a granular solver on the primal LCP, or the dual CG.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StructuralSolver {
    /// A granular solver on the primal LCP (gaps from forces).
    Primal(SolverKind),
    /// Projected CG on the dual problem (forces from gaps).
    DualCg,
}

impl StructuralSolver {
    /// A solver by name (`dual_cg` or a granular solver's name).
    pub fn parse(name: &str) -> Result<Self, String> {
        if name == "dual_cg" || name == "dual-cg" {
            return Ok(Self::DualCg);
        }
        SolverKind::ALL.into_iter().find(|k| k.name() == name).map(Self::Primal).ok_or_else(|| {
            let all: Vec<&str> = SolverKind::ALL.iter().map(|k| k.name()).collect();
            format!("unknown solver {name:?} (one of {}, dual_cg)", all.join(", "))
        })
    }

    /// Its name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Primal(k) => k.name(),
            Self::DualCg => "dual_cg",
        }
    }
}

impl fmt::Display for StructuralSolver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The primal and dual LCPs of a model, in length units, and the exact solution.
///
/// The gap `z` is a length and the force `w` is not, so the natural-map error of the raw pair
/// would weigh them by their units (a 1 % error in the gaps can read as 1e-8). Both problems are
/// therefore posed for `w̃ = w / s` with `s` the mean of `diag M`: `w̃ = (M/s) z + q/s` and
/// `z = (s F) w̃ + q_F`. No solver's iterates change (NLGS, CG and LATIN's scaled k are invariant
/// to it); only the measure becomes meaningful.
pub struct PunchProblems {
    /// `w̃ = (M/s) z + q/s` (forces from gaps).
    pub primal: Lcp,
    /// `z = (s F) w̃ + q_F` (gaps from forces).
    pub dual: Lcp,
    /// `s`: contact force = `s · w̃`.
    pub force_scale: f64,
    /// Exact `z*` (active-set solve polished from a tight PCPG solution).
    pub reference: Vec<f64>,
}

impl PunchProblems {
    /// Condenses the model onto its contact nodes and solves for the reference.
    pub fn new(model: &PunchModel) -> Result<Self, StructureError> {
        let stiffness = model.condense()?;
        let flexibility = model.flexibility()?;
        let s = (0..stiffness.n).map(|i| stiffness.entry(i, i)).sum::<f64>() / stiffness.n as f64;
        let primal = Lcp::new(stiffness.m.iter().map(|x| x / s).collect(), stiffness.q.iter().map(|x| x / s).collect());
        let dual = Lcp::new(flexibility.m.iter().map(|x| x * s).collect(), flexibility.q);
        let tight = SolverOptions { tol: 1e-12, max_iter: 200_000, ..SolverOptions::default() };
        let start = solve(&primal.to_contact_problem(), SolverKind::Pcpg, &tight, None);
        let z0: Vec<f64> = start.r.iter().step_by(2).copied().collect();
        let reference = primal.solve_by_active_set(&z0).ok_or_else(|| {
            StructureError::Invalid("the active-set reference solve did not settle on a solution".into())
        })?;
        Ok(Self { primal, dual, force_scale: s, reference })
    }

    /// Smallest and largest eigenvalue of the scaled `M` (dense, faer): where LATIN's `k` should lie.
    pub fn extreme_eigenvalues(&self) -> Option<(f64, f64)> {
        let n = self.primal.n;
        let m = faer::Mat::from_fn(n, n, |i, j| self.primal.entry(i, j));
        let ev = m.self_adjoint_eigenvalues(faer::Side::Lower).ok()?;
        Some((*ev.first()?, *ev.last()?))
    }

    /// `‖z − z*‖_M / ‖z*‖_M` (absolute when `z* = 0`).
    pub fn energy_error(&self, z: &[f64]) -> f64 {
        let d: Vec<f64> = z.iter().zip(&self.reference).map(|(a, b)| a - b).collect();
        let scale = self.primal.energy_norm(&self.reference);
        let e = self.primal.energy_norm(&d);
        if scale > 0.0 {
            e / scale
        } else {
            e
        }
    }
}

/// One recorded iterate.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Point {
    /// Iterations done.
    pub iteration: usize,
    /// Seconds.
    pub seconds: f64,
    /// Operator products.
    pub w_products: usize,
    /// Natural-map error of the primal pair (z, w).
    pub error: f64,
    /// Energy-norm error ‖z − z*‖_M / ‖z*‖_M.
    pub energy_error: f64,
}

/// One solver's solve of the punch.
pub struct StructuralRun {
    /// The solver.
    pub solver: StructuralSolver,
    /// Every iterate recorded.
    pub points: Vec<Point>,
    /// Whether it met its tolerance.
    pub converged: bool,
    /// Iterations done.
    pub iterations: usize,
    /// Seconds.
    pub seconds: f64,
    /// Why it stopped.
    pub stop_reason: String,
    /// Gaps after deformation.
    pub z: Vec<f64>,
    /// Contact forces (physical units).
    pub w: Vec<f64>,
}

impl StructuralRun {
    /// Natural-map error of the last iterate.
    pub fn error(&self) -> f64 {
        self.points.last().map_or(f64::NAN, |p| p.error)
    }

    /// Energy-norm error of the last iterate.
    pub fn energy_error(&self) -> f64 {
        self.points.last().map_or(f64::NAN, |p| p.energy_error)
    }
}

/// Solves with `solver` to `opts.tol` (natural-map error of the primal pair), recording both errors
/// at the history points (their evaluation is not counted in the solve time).
pub fn run(problems: &PunchProblems, solver: StructuralSolver, opts: &SolverOptions) -> StructuralRun {
    let opts = SolverOptions { keep_iterates: true, ..opts.clone() };
    // (gaps, forces) of every kept iterate.
    type Pairs = Vec<(Vec<f64>, Vec<f64>)>;
    let (report, z, w, pairs): (_, Vec<f64>, Vec<f64>, Pairs) = match solver {
        StructuralSolver::Primal(kind) => {
            let r = solve(&problems.primal.to_contact_problem(), kind, &opts, None);
            let pair = |it: &[f64]| {
                let z: Vec<f64> = it.iter().step_by(2).copied().collect();
                let w = problems.primal.complement(&z);
                (z, w)
            };
            let pairs = r.iterates.iter().map(|it| pair(it)).collect();
            let (z, w) = pair(&r.r);
            (r, z, w, pairs)
        }
        StructuralSolver::DualCg => {
            let d = dual_cg::solve(&problems.dual, &opts);
            let pairs = d
                .report
                .iterates
                .iter()
                .map(|it| (dual_cg::gaps_of(&problems.dual, it), it.iter().step_by(2).copied().collect()))
                .collect();
            (d.report, d.z, d.w, pairs)
        }
    };
    let points: Vec<Point> = report
        .history
        .iter()
        .zip(&pairs)
        .map(|(h, (z, w))| Point {
            iteration: h.iteration,
            seconds: h.seconds,
            w_products: h.w_products,
            error: problems.primal.natural_error(z, w),
            energy_error: problems.energy_error(z),
        })
        .collect();
    let error = problems.primal.natural_error(&z, &w);
    StructuralRun {
        solver,
        converged: error <= opts.tol,
        iterations: report.iterations,
        seconds: report.seconds,
        stop_reason: report.stop_reason,
        points,
        z,
        w: w.iter().map(|x| x * problems.force_scale).collect(),
    }
}

/// One LATIN solve of the k sweep.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LatinKRow {
    /// `k = factor · mean(diag M)` (or `· diag M` per contact).
    pub factor: f64,
    /// The resulting k.
    pub k: f64,
    /// Whether k is scaled per contact (diag M) rather than by its mean.
    pub per_contact_diagonal: bool,
    /// Whether it met the tolerance.
    pub converged: bool,
    /// Iterations.
    pub iterations: usize,
    /// Seconds.
    pub seconds: f64,
    /// Natural-map error.
    pub error: f64,
    /// Energy-norm error.
    pub energy_error: f64,
}

/// LATIN to `tol` for each factor, with `k` from the mean of `diag M` and from `diag M` itself.
pub fn latin_k_sweep(problems: &PunchProblems, factors: &[f64], tol: f64, max_iter: usize) -> Vec<LatinKRow> {
    // In physical units (stiffness): the problems are scaled by the mean of diag M.
    let mean_diag = problems.force_scale;
    let mut rows = Vec::new();
    for per_contact_diagonal in [false, true] {
        for &factor in factors {
            let opts = SolverOptions {
                tol,
                max_iter,
                latin_k: LatinK::Factor(factor),
                latin_k_mean: !per_contact_diagonal,
                ..SolverOptions::default()
            };
            let r = run(problems, StructuralSolver::Primal(SolverKind::Latin), &opts);
            rows.push(LatinKRow {
                factor,
                k: factor * mean_diag,
                per_contact_diagonal,
                converged: r.converged,
                iterations: r.iterations,
                seconds: r.seconds,
                error: r.error(),
                energy_error: r.energy_error(),
            });
        }
    }
    rows
}
