#![warn(missing_docs)]
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
//! * `cli`: the `moreau` command line (feature `cli`, on by default; a host embedding the library
//!   turns default features off and builds neither clap, indicatif nor plotters).
//!
//! A host steps a scene file, or a world it builds, one Moreau–Jean step at a time:
//!
//! ```
//! use moreau::{BodySpec, DVec2, Simulation, StepSettings, Wall, World};
//! use moreau::world::Interaction;
//!
//! // Each input checked as a scene file's is; friction is on because the law has it.
//! let glass = Interaction { friction: 0.3, ..Interaction::default() };
//! let gravity = Some(DVec2::new(0.0, -9.81));
//! let mut world = World::in_code(vec![("glass".into(), 2500.0)], glass, gravity, false, false)?;
//! world.add_wall(Wall::segment(DVec2::new(-1.0, 0.0), DVec2::new(1.0, 0.0), 0))?;
//! world.add_body(&BodySpec::disk(DVec2::new(0.0, 0.05), 0.05, world.material_named("glass")?))?;
//! let settings = StepSettings::for_world(&world, 1e-3);
//! let mut sim = Simulation::new(world, settings)?;
//! let grain = sim.add_body(&BodySpec::disk(DVec2::new(0.0, 0.2), 0.05, sim.material("glass")?))?;
//! for _ in 0..200 {
//!     let report = sim.step()?;
//!     assert!(report.converged, "{}", report.stop_reason);
//! }
//! // The second grain has landed on the first and rests there.
//! assert!((sim.position(grain).y - 0.15).abs() < 1e-3 && sim.velocity(grain).length() < 1e-2);
//! assert!(sim.contacts().iter().all(|c| c.impulse[0] >= 0.0));
//! # Ok::<(), moreau::Error>(())
//! ```
//!
//! [`Simulation::from_scene`] loads a scene file instead.

pub mod backend;
#[cfg(feature = "cli")]
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

pub use glam;
pub use glam::DVec2;
pub use problem::ContactProblem;
pub use scene::SceneError;
pub use solvers::{solve, SolveReport, SolverKind, SolverOptions};
pub use stepping::{BodyError, ContactState, Simulation, StepError, StepReport, StepSettings};
pub use world::{BodySpec, Effects, Materials, Wall, World};

/// Every error the library returns to a host, by where it arose (each names the problem).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file refused.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A step or setting refused.
    #[error(transparent)]
    Step(#[from] StepError),
    /// A request about a body refused.
    #[error(transparent)]
    Body(#[from] BodyError),
    /// A world built in code refused (a material, a law, a wall, a body).
    #[error(transparent)]
    World(#[from] world::WorldError),
    /// A contact problem refused.
    #[error(transparent)]
    Problem(#[from] problem::ProblemError),
}
