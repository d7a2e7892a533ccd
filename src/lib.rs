//! moreau — 2D granular contact dynamics (nonsmooth contact dynamics, Moreau–Jean).
//!
//! * [`problem`]: the one-step frictional contact problem `u = W r + q` and its operator `W`
//!   (matrix-free `B M⁻¹ Bᵀ` or explicit block-sparse), the Coulomb cone, the error measure.
//! * [`solvers`]: the CPU reference solvers in f64 (NLGS, CPG, PCPG, LATIN, projected Jacobi, APGD).
//! * [`backend`]: where a solve runs (CPU threads or a GPU), chosen in one place, with the GPU's
//!   f32 solves finished in f64 on the CPU when the tolerance asks for it.
//! * [`structure`]: the founding paper's Signorini punch (finite elements condensed to an LCP) and
//!   the dual projected CG.
//! * [`parallel`]: how the CPU path uses threads (fixed chunks: the same bits on any thread count).
//! * [`io`]: Siconos fc2d problem files, JSON reports.
//! * [`cli`]: the `moreau` command line.

pub mod backend;
pub mod cli;
pub mod detection;
pub mod gpu;
pub mod io;
pub mod parallel;
pub mod problem;
pub mod scene;
pub mod solvers;
pub mod stepping;
pub mod structure;
pub mod sweep;
pub mod world;

pub use problem::ContactProblem;
pub use solvers::{solve, SolveReport, SolverKind, SolverOptions};
