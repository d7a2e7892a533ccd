//! Moreau–Jean time stepping (notes §1): detect, build the matrix-free contact problem of the
//! step, solve it warm-started, update, project what the update pushed in; checks of the start
//! and of every step's state. [`Simulation`] is the library API a host code drives.

mod checkpoint;
mod checks;
mod measures;
mod moreau_jean;
mod projection;
mod simulation;
mod warm_start;

pub use checkpoint::{CarriedContact, Checkpoint, WallState, CHECKPOINT_FORMAT};
pub use measures::{normal_force_pdf, Measures, ProfileLayer, WallLoad};
pub use simulation::{
    BodyError, ContactState, Simulation, StepError, StepReport, StepSettings, DEFAULT_ALERT_FRACTION,
    DEFAULT_PROJECTION_SLACK,
};
pub use warm_start::WarmStart;
