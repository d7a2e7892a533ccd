//! The GPU path: WGSL compute kernels (shaders/) on a headless wgpu device, f32, each with a CPU
//! mirror of the same name in [`cpu`]. Iterations stay on the GPU; the error of a result is
//! always evaluated in f64 on the CPU with the core's measure.

pub mod anderson;
pub mod apgd;
pub mod colouring;
pub mod context;
pub mod cpg;
pub mod cpu;
pub mod driver;
pub mod jacobi;
pub mod kernels;
pub mod layout;
pub mod nlgs;
pub mod operator;
pub mod pool;
pub mod reduce;
pub mod stages;
pub mod timing;
pub mod traffic;

pub use context::{GpuContext, GpuError};

use crate::problem::ContactProblem;
use crate::solvers::{SolveReport, SolverKind, SolverOptions};

/// Solves `problem` on the GPU with `kind`, or says that the GPU path lacks that solver.
pub fn solve(
    ctx: &GpuContext,
    problem: &ContactProblem,
    kind: SolverKind,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
) -> Result<SolveReport, GpuError> {
    if !opts.criterion.judges_one_iterate() {
        return Err(GpuError::Criterion(opts.criterion.name().into()));
    }
    match kind {
        SolverKind::Jacobi => jacobi::solve(ctx, problem, opts, r0),
        SolverKind::Nlgs => nlgs::solve(ctx, problem, opts, r0),
        SolverKind::Cpg => cpg::solve(ctx, problem, opts, r0, false),
        SolverKind::Pcpg => cpg::solve(ctx, problem, opts, r0, true),
        SolverKind::Apgd => apgd::solve(ctx, problem, opts, r0),
        other => Err(GpuError::Unsupported(other.name().to_string())),
    }
}

/// Which pipelines a problem needs: (rotation, friction). Explicit `W` uses the general ones.
pub fn specialisation(p: &ContactProblem) -> (bool, bool) {
    match &p.w {
        crate::problem::Delassus::MatrixFree(op) => (op.dofs().rotation, op.dofs().friction),
        crate::problem::Delassus::Sparse(_) => (true, true),
    }
}

/// Whether the GPU path has this solver.
pub fn supports(kind: SolverKind) -> bool {
    !matches!(kind, SolverKind::Latin | SolverKind::Newton | SolverKind::NlgsNewton | SolverKind::InteriorPoint)
}
