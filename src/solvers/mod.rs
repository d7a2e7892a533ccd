//! CPU reference solvers (f64) of the one-step frictional contact problem.
//!
//! | solver | file | idea |
//! |---|---|---|
//! | NLGS | [`nlgs`] | Gauss–Seidel sweeps of the exact single-contact solve |
//! | CPG / PCPG | [`cpg`] | Renouf–Alart conjugate projected gradient, plain / diagonal preconditioner |
//! | LATIN | [`latin`] | local/linear stages with search direction k (augmented Lagrangian) |
//! | projected Jacobi | [`jacobi`] | all contacts from the same iterate, relaxation and per-contact scaling |
//! | APGD | [`apgd`] | Nesterov projected gradient with restart, Tresca box with threshold updates |
//! | Newton | [`newton`] | semismooth Newton on the Alart–Curnier function, GMRES on `W` products (prototype) |
//! | NLGS–Newton | [`truncated_newton`] | NLGS sweeps, each followed by a truncated Newton correction of the Tresca problem (sparse Cholesky) |
//! | interior point | [`interior_point`] | primal–dual interior point on De Saxcé's form of the wedge cones (LU on the Cholesky's structure, `pattern_lu.rs` / Cholesky), NLGS sweeps from its iterate when it stops short |
//!
//! Every solver is judged by the same f64 error ([`crate::problem::residual`]) through a
//! [`monitor::Monitor`], and returns a [`SolveReport`].

pub mod anderson;
pub mod apgd;
mod conjugate_gradient;
pub mod cpg;
pub mod focus;
pub mod interior_point;
pub mod jacobi;
pub mod latin;
pub mod lmgc_criteria;
pub mod monitor;
pub mod newton;
pub mod nlgs;
mod pattern_lu;
mod recycled;
mod sparse_cholesky;
pub mod stopping;
pub mod truncated_newton;
pub mod worklist;

pub use latin::LatinK;
pub use newton::NewtonLinear;
pub use stopping::StopReason;

use crate::problem::ContactProblem;
use serde::Serialize;
use std::fmt;

/// The solvers of the one solver interface ([`solve`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// Nonlinear Gauss–Seidel with the exact single-contact solve.
    Nlgs,
    /// Conjugate projected gradient (Renouf & Alart).
    Cpg,
    /// CPG preconditioned by the diagonal blocks.
    Pcpg,
    /// LATIN: local and global stages with a search direction k.
    Latin,
    /// Projected Jacobi with a per-contact step.
    Jacobi,
    /// Accelerated projected gradient with restarts.
    Apgd,
    /// Semismooth Newton (Alart–Curnier), NLGS sweeps when its line search fails.
    Newton,
    /// NLGS sweeps, each followed by a truncated Newton correction of the Tresca problem they define.
    NlgsNewton,
    /// Primal–dual interior point on De Saxcé's form of Coulomb's law (each 2D cone a wedge), NLGS sweeps from its iterate when it stops short.
    InteriorPoint,
}

impl SolverKind {
    /// Every solver, in the order reports list them.
    pub const ALL: [SolverKind; 9] = [
        SolverKind::Nlgs,
        SolverKind::Cpg,
        SolverKind::Pcpg,
        SolverKind::Latin,
        SolverKind::Jacobi,
        SolverKind::Apgd,
        SolverKind::Newton,
        SolverKind::NlgsNewton,
        SolverKind::InteriorPoint,
    ];

    /// The name the command line and scene files use.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Nlgs => "nlgs",
            SolverKind::Cpg => "cpg",
            SolverKind::Pcpg => "pcpg",
            SolverKind::Latin => "latin",
            SolverKind::Jacobi => "jacobi",
            SolverKind::Apgd => "apgd",
            SolverKind::Newton => "newton",
            SolverKind::NlgsNewton => "nlgs-newton",
            SolverKind::InteriorPoint => "interior-point",
        }
    }
}

impl SolverKind {
    /// The solver called `name` (as the command line spells it); the error lists the names.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|k| k.name() == name).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|k| k.name()).collect();
            format!("unknown solver {name:?} (one of: {})", names.join(", "))
        })
    }
}

impl fmt::Display for SolverKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Contact ordering of an NLGS sweep.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Ordering {
    /// Contacts in index order.
    Forward,
    /// Contacts in reverse index order.
    Backward,
    /// Forward then backward (symmetric Gauss–Seidel).
    Symmetric,
    /// A new random permutation every sweep.
    Shuffled,
    /// Colour by colour, as the GPU sweeps: the contacts of one colour share no moving body
    /// (matrix-free problems; the same bits on any thread count). In f64 on the CPU it
    /// separates what the GPU's order costs in sweeps from what its f32 costs.
    Colours,
    /// A work list: only contacts whose residual exceeds the tolerance are updated, and a contact
    /// updated puts its neighbours back on the list (matrix-free problems; on threads by the
    /// threaded sweep's blocks, the same bits on any thread count). For warm-started simulation
    /// steps, where the error sits on a few contacts.
    Worklist,
}

impl Ordering {
    /// Every ordering.
    pub const ALL: [Ordering; 6] = [
        Ordering::Forward,
        Ordering::Backward,
        Ordering::Symmetric,
        Ordering::Shuffled,
        Ordering::Colours,
        Ordering::Worklist,
    ];

    /// The name the command line and scene files use.
    pub fn name(self) -> &'static str {
        match self {
            Ordering::Forward => "forward",
            Ordering::Backward => "backward",
            Ordering::Symmetric => "symmetric",
            Ordering::Shuffled => "shuffled",
            Ordering::Colours => "colours",
            Ordering::Worklist => "worklist",
        }
    }

    /// The ordering called `name` (any case).
    pub fn from_name(name: &str) -> Result<Self, String> {
        by_name(&Self::ALL, Self::name, name, "ordering")
    }
}

/// When a solve stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum StopCriterion {
    /// The relative natural-map residual |r − proj_cone(r − u)| is at most `tol`.
    Natural,
    /// LMGC90's `Quad` test (RMS of local velocity changes).
    Quad,
    /// LMGC90's `Maxm` test (every contact).
    Maxm,
    /// LMGC90's `QM/16` compromise.
    Qm16,
    /// Every contact's residual in velocity units is at most `tol` times the largest free
    /// velocity: for simulations, where the 2-norm error lets one contact violate Signorini
    /// (and overlap) while the rest converge.
    // (computed by `problem::residual::velocity_error`)
    Velocity,
    /// Every contact's residual in velocity units is at most `tol` times one step of the largest
    /// applied acceleration (`g h` under gravity, the problem's `velocity_floor`): a bound that no
    /// fast grain loosens. Without one (a problem read from a file, no applied force) it is the
    /// velocity test.
    #[serde(rename = "step-velocity")]
    StepVelocity,
}

impl StopCriterion {
    /// Every criterion.
    pub const ALL: [StopCriterion; 6] = [
        StopCriterion::Natural,
        StopCriterion::Quad,
        StopCriterion::Maxm,
        StopCriterion::Qm16,
        StopCriterion::Velocity,
        StopCriterion::StepVelocity,
    ];

    /// Whether it judges the largest contact residual in velocity units (`velocity`,
    /// `step-velocity`), which needs `W`'s diagonal blocks and which a work list can empty.
    pub fn is_velocity_test(self) -> bool {
        matches!(self, StopCriterion::Velocity | StopCriterion::StepVelocity)
    }

    /// Whether it judges a measure of one iterate (the natural map or a velocity test), not the
    /// change between two as LMGC90's tests do.
    pub fn judges_one_iterate(self) -> bool {
        self == StopCriterion::Natural || self.is_velocity_test()
    }

    /// The name the command line and scene files use.
    pub fn name(self) -> &'static str {
        match self {
            StopCriterion::Natural => "natural",
            StopCriterion::Quad => "quad",
            StopCriterion::Maxm => "maxm",
            StopCriterion::Qm16 => "qm16",
            StopCriterion::Velocity => "velocity",
            StopCriterion::StepVelocity => "step-velocity",
        }
    }

    /// The criterion called `name` (any case).
    pub fn from_name(name: &str) -> Result<Self, String> {
        by_name(&Self::ALL, Self::name, name, "criterion")
    }
}

/// The one of `all` whose name is `wanted` (any case); the error lists the names.
fn by_name<T: Copy>(all: &[T], name: fn(T) -> &'static str, wanted: &str, what: &str) -> Result<T, String> {
    all.iter().copied().find(|&x| name(x).eq_ignore_ascii_case(wanted)).ok_or_else(|| {
        let names: Vec<&str> = all.iter().map(|&x| name(x)).collect();
        format!("unknown {what} {wanted:?} (one of: {})", names.join(", "))
    })
}

/// What every solver is asked: tolerance, budget, stopping test and the options some solvers read.
#[derive(Clone, Debug, Serialize)]
pub struct SolverOptions {
    /// Stop when the judged error is at most this.
    pub tol: f64,
    /// Iterations (sweeps) allowed.
    pub max_iter: usize,
    /// Which measure judges convergence.
    pub criterion: StopCriterion,
    /// NLGS relaxation ω (1 = plain Gauss–Seidel; above 1 each update is projected back onto the
    /// cone, projected SOR).
    pub omega: f64,
    /// NLGS: the order contacts are visited in.
    pub ordering: Ordering,
    /// NLGS: the seed of the shuffled ordering.
    pub seed: u64,
    /// NLGS: Anderson acceleration over this many past sweeps (0: plain sweeps).
    pub anderson: usize,
    /// NLGS: focused sweeps after each full sweep, over the contacts around its largest changes
    /// (0: full sweeps only; matrix-free problems in forward order).
    pub focus: usize,
    /// Projected Jacobi relaxation (step = ω / mean diagonal of the contact block).
    pub jacobi_omega: f64,
    /// GPU NLGS on a matrix-free problem: sweeps blocks of contacts this many times per dispatch
    /// (`nlgs_blocks.wgsl`) instead of a dispatch per colour and sweep; 0: colour sweeps. An
    /// iteration is then one round of the block colours, and `max_iter` bounds rounds, each of
    /// `block_sweeps` sweeps. The CPU sweeps as `ordering` says.
    pub block_sweeps: usize,
    /// LATIN search direction: `k = factor · diag(W_αα)` per component (compliance units), the
    /// factor given or chosen by the solver.
    pub latin_k: LatinK,
    /// LATIN: one `k = factor · mean(diag W)` for every component instead of the diagonal.
    pub latin_k_mean: bool,
    /// Newton: how its linear systems are solved (GMRES on `W` products, or sparse LU).
    pub newton_linear: NewtonLinear,
    /// APGD: iterations between two updates of the Tresca thresholds `s = μ r_n`.
    pub apgd_threshold_every: usize,
    /// Record the error every this many iterations for work-precision curves (0: only when checked);
    /// time spent on these extra evaluations is not counted in the solve time.
    pub history_every: usize,
    /// Keep a copy of the iterate at every history point (`SolveReport::iterates`), for measures
    /// the solver does not know (the energy norm of a structural problem).
    pub keep_iterates: bool,
    /// A GPU solve stops at a plateau of its f32 error below 1e-3, where the f64 finish on the
    /// CPU takes over (the default); false runs it to tol or max_iter.
    #[serde(skip)]
    pub gpu_plateau_stops: bool,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            tol: 1e-8,
            max_iter: 10_000,
            criterion: StopCriterion::Natural,
            omega: 1.0,
            ordering: Ordering::Forward,
            seed: 0,
            anderson: 0,
            focus: 0,
            jacobi_omega: 0.5,
            block_sweeps: 0,
            latin_k: LatinK::Auto,
            latin_k_mean: false,
            newton_linear: NewtonLinear::Gmres,
            apgd_threshold_every: 10,
            history_every: 0,
            keep_iterates: false,
            gpu_plateau_stops: true,
        }
    }
}

/// A solver option outside its range: its name (as in scene files), its value and the rule.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{name} {value}: {rule}")]
pub struct OptionError {
    /// The option, as the command line names it.
    pub name: &'static str,
    /// The value given.
    pub value: String,
    /// What it must satisfy.
    pub rule: &'static str,
}

impl SolverOptions {
    /// Checks every option a solver reads, before any work.
    pub fn validate(&self) -> Result<(), OptionError> {
        let positive = "must be finite and > 0";
        let factor = match self.latin_k {
            LatinK::Factor(f) => f,
            LatinK::Auto => 1.0,
        };
        let checks: [(&'static str, f64, bool, &'static str); 4] = [
            ("tol", self.tol, self.tol.is_finite() && self.tol > 0.0, positive),
            ("omega", self.omega, self.omega > 0.0 && self.omega < 2.0, "the NLGS relaxation must lie in (0, 2)"),
            ("jacobi_omega", self.jacobi_omega, self.jacobi_omega.is_finite() && self.jacobi_omega > 0.0, positive),
            ("latin_k", factor, factor.is_finite() && factor > 0.0, positive),
        ];
        if let Some(&(name, value, _, rule)) = checks.iter().find(|c| !c.2) {
            return Err(OptionError { name, value: value.to_string(), rule });
        }
        if self.max_iter == 0 {
            return Err(OptionError { name: "max_iter", value: "0".into(), rule: "must be at least 1" });
        }
        if self.focus > MAX_FOCUS {
            let rule = "at most 100 focused sweeps after each full sweep";
            return Err(OptionError { name: "focus", value: self.focus.to_string(), rule });
        }
        if self.block_sweeps > MAX_BLOCK_SWEEPS {
            let rule = "a block is swept at most 64 times a dispatch";
            return Err(OptionError { name: "block_sweeps", value: self.block_sweeps.to_string(), rule });
        }
        if self.anderson > MAX_ANDERSON {
            let rule = "Anderson acceleration keeps at most 50 past sweeps";
            return Err(OptionError { name: "anderson", value: self.anderson.to_string(), rule });
        }
        Ok(())
    }
}

/// Most past sweeps Anderson acceleration may mix.
pub const MAX_ANDERSON: usize = 50;

/// Most sweeps of a block per dispatch ([`SolverOptions::block_sweeps`]).
pub const MAX_BLOCK_SWEEPS: usize = 64;

/// Most focused sweeps after a full sweep ([`SolverOptions::focus`]).
pub const MAX_FOCUS: usize = 100;

/// One point of the error history.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct HistoryPoint {
    /// Iterations done.
    pub iteration: usize,
    /// Seconds of solve time.
    pub seconds: f64,
    /// Operator products done.
    pub w_products: usize,
    /// The f64 error of the iterate then.
    pub error: f64,
}

/// What every solve returns. `error` is always the f64 natural-map error of the returned `r`;
/// `judged_error` is the measure the stopping test compared with `tol`.
#[derive(Clone, Debug, Serialize)]
pub struct SolveReport {
    /// The solver that ran.
    pub solver: SolverKind,
    /// Whether the returned `r` meets the tolerance (by the criterion asked for).
    pub converged: bool,
    /// Iterations done.
    pub iterations: usize,
    /// The f64 natural-map error of the returned `r`.
    pub error: f64,
    /// The f64 measure of the returned `r` that the stopping test judged against `tol`: the
    /// velocity measure under `criterion = velocity`, else `error`. Heavy grains put the two
    /// far apart (the natural map's scale holds impulses of ~1e3 N s): 1e-8 against 1e-3.
    pub judged_error: f64,
    /// Solve time (s).
    pub seconds: f64,
    /// Operator products done.
    pub w_products: usize,
    /// The error at the checks (every `history_every` iterations when asked).
    pub history: Vec<HistoryPoint>,
    /// Why the solve stopped.
    pub stop: StopReason,
    /// Why the solve stopped, in words.
    pub stop_reason: String,
    /// What the solver chose on its own (LATIN's automatic search direction), in words.
    pub notes: Vec<String>,
    /// A solve split across devices (mixed precision: f32 on the GPU, then f64 on the CPU) lists
    /// each part here; empty for a solve on one device.
    pub parts: Vec<SolvePart>,
    /// GPU dispatches recorded and bytes moved between CPU and GPU by this solve (0 on the CPU).
    pub gpu_dispatches: u64,
    /// Bytes moved between CPU and GPU.
    pub gpu_bytes: u64,
    /// How a GPU solve checked its error (all zero on the CPU).
    pub gpu_checks: GpuChecks,
    /// The impulses.
    pub r: Vec<f64>,
    /// The velocities `u = W r + q` of the returned impulses.
    pub u: Vec<f64>,
    /// The bodies' velocities `M⁻¹ Bᵀ r` of the returned impulses, when the solve's last product
    /// (matrix-free) was of them: the step's update then needs no product of its own.
    #[serde(skip)]
    pub body_velocity: Option<Vec<f64>>,
    /// The iterates at the history points, when `keep_iterates` was asked for.
    #[serde(skip)]
    pub iterates: Vec<Vec<f64>>,
}

impl SolveReport {
    /// Iterations run on a GPU: its part of a mixed-precision solve, all of a GPU solve (which
    /// estimated its error there), none of a CPU solve.
    pub fn gpu_iterations(&self) -> usize {
        match self.parts.is_empty() {
            false => self.parts.iter().filter(|p| p.device == "gpu").map(|p| p.iterations).sum(),
            true if self.gpu_checks.estimates > 0 => self.iterations,
            true => 0,
        }
    }
}

/// One device's share of a solve split across devices.
#[derive(Clone, Debug, Serialize)]
pub struct SolvePart {
    /// `gpu` (f32) or `cpu` (f64).
    pub device: String,
    /// Iterations of this part.
    pub iterations: usize,
    /// Its time (s).
    pub seconds: f64,
    /// The f64 error when this part handed over (or finished).
    pub error: f64,
    /// Why this part stopped.
    pub stop: StopReason,
}

/// How a GPU solve checked its error between its batches of iterations: each estimate is a round
/// trip to the GPU, overlapped by the next batch; an estimate near the tolerance reads `r` back and
/// judges it in f64 on the CPU. What a GPU iteration costs beyond its kernels is in these
/// (`moreau bench --scene`).
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct GpuChecks {
    /// Error estimates on the GPU.
    pub estimates: usize,
    /// Of them, the ones judged in f64 on the CPU.
    pub judged: usize,
    /// CPU time of those judgements, read-back included (s).
    pub judge_seconds: f64,
    /// Iterations queued past the check that stopped the solve, run and not used.
    pub discarded: usize,
    /// Iterations run up to that check: for the work list's thresholded sweeps, whose
    /// iterations count sweeps' worth of updates, their rounds of colour dispatches.
    pub rounds: usize,
    /// Whether the iterations counted sweeps' worth of updates (the work list's thresholded
    /// colour sweeps), so that `rounds` are not iterations.
    pub counted: bool,
}

impl GpuChecks {
    /// Adds another solve's checks to these.
    pub fn add(&mut self, other: &GpuChecks) {
        self.estimates += other.estimates;
        self.judged += other.judged;
        self.judge_seconds += other.judge_seconds;
        self.discarded += other.discarded;
        self.rounds += other.rounds;
        self.counted |= other.counted;
    }
}

/// Why `kind` cannot solve `problem` with `opts`, if it cannot: rolling resistance is solved by
/// NLGS, judged by the natural-map or velocity criterion (the other solvers and LMGC90's
/// criteria know 2 unknowns per contact).
pub fn refusal(problem: &ContactProblem, kind: SolverKind, opts: &SolverOptions) -> Option<String> {
    rolling_refusal(problem.has_rolling(), kind, opts.criterion)
}

/// [`refusal`] before any problem exists (a scene that names `rolling_resistance`).
pub fn rolling_refusal(rolling: bool, kind: SolverKind, criterion: StopCriterion) -> Option<String> {
    if rolling && kind != SolverKind::Nlgs {
        Some(format!("rolling resistance is solved by nlgs only, not {}", kind.name()))
    } else if rolling && !criterion.judges_one_iterate() {
        Some(format!("rolling resistance is judged by the natural or velocity criterion, not {}", criterion.name()))
    } else {
        None
    }
}

/// Solves `problem` from `r0` (warm start; zero if `None`); see [`refusal`] for what a
/// solver cannot do (the backend refuses it up front).
pub fn solve(problem: &ContactProblem, kind: SolverKind, opts: &SolverOptions, r0: Option<&[f64]>) -> SolveReport {
    let n = problem.unknowns();
    let r0: Vec<f64> = match r0 {
        Some(r) if r.len() == n && crate::parallel::all_finite(r) => crate::parallel::copied(r),
        _ => crate::parallel::filled(n, 0.0),
    };
    let mut report = match kind {
        SolverKind::Nlgs => nlgs::solve(problem, opts, r0),
        SolverKind::Cpg => cpg::solve(problem, opts, r0, false),
        SolverKind::Pcpg => cpg::solve(problem, opts, r0, true),
        SolverKind::Latin => latin::solve(problem, opts, r0),
        SolverKind::Jacobi => jacobi::solve(problem, opts, r0),
        SolverKind::Apgd => apgd::solve(problem, opts, r0),
        SolverKind::Newton => newton::solve(problem, opts, r0),
        SolverKind::NlgsNewton => truncated_newton::solve(problem, opts, r0),
        SolverKind::InteriorPoint => interior_point::solve(problem, opts, r0),
    };
    stopping::refuse_unbounded(problem, &mut report);
    report
}
