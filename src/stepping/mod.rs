//! Moreau–Jean time stepping (notes §1): predict, detect, build the matrix-free contact problem
//! of the step, solve it warm-started, update. [`Simulation`] is the library API a host code drives.

mod moreau_jean;
mod simulation;
mod warm_start;

pub use simulation::{ContactState, Simulation, StepError, StepReport, StepSettings};
pub use warm_start::WarmStart;
