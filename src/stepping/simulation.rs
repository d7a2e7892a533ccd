//! The library API: a [`Simulation`] owns a [`World`] and advances it one Moreau–Jean step at a
//! time; a host code may add bodies and walls between steps and read states and contact impulses.

use glam::DVec2;
use serde::Serialize;
use thiserror::Error;

use super::WarmStart;
use crate::backend::Backend;
use crate::detection::{DetectedContact, Detector};
use crate::problem::cone::ContactStatus;
use crate::problem::ContactProblem;
use crate::solvers::{SolverKind, SolverOptions, StopReason};
use crate::world::{BodySpec, Wall, World};

/// Time step, θ, alert distance and the solver of each step.
#[derive(Clone, Debug)]
pub struct StepSettings {
    /// Time step h.
    pub h: f64,
    /// θ of the θ-method, in [1/2, 1].
    pub theta: f64,
    /// Pairs closer than this become contacts (absolute length).
    pub alert: f64,
    pub solver: SolverKind,
    pub options: SolverOptions,
}

impl StepSettings {
    pub fn validate(&self) -> Result<(), String> {
        if !(self.h.is_finite() && self.h > 0.0) {
            return Err(format!("time step {} must be finite and > 0", self.h));
        }
        if !(0.5..=1.0).contains(&self.theta) {
            return Err(format!("theta {} must lie in [0.5, 1]", self.theta));
        }
        if !(self.alert.is_finite() && self.alert >= 0.0) {
            return Err(format!("alert distance {} must be finite and >= 0", self.alert));
        }
        if !(self.options.tol.is_finite() && self.options.tol > 0.0) {
            return Err(format!("solver tolerance {} must be finite and > 0", self.options.tol));
        }
        if self.options.max_iter == 0 {
            return Err("solver max_iter must be >= 1".into());
        }
        Ok(())
    }
}

/// A contact of the last step with its impulse (normal, tangential) and status.
#[derive(Clone, Copy, Debug)]
pub struct ContactState {
    pub contact: DetectedContact,
    pub impulse: [f64; 2],
    pub status: ContactStatus,
}

/// What one step did.
#[derive(Clone, Debug, Serialize)]
pub struct StepReport {
    pub step: usize,
    pub time: f64,
    pub contacts: usize,
    /// Contacts whose impulse came from last step.
    pub warm_started: usize,
    pub iterations: usize,
    pub error: f64,
    pub converged: bool,
    /// Why the step's solve stopped (`converged` when there was nothing to solve).
    pub stop: StopReason,
    pub stop_reason: String,
    /// GPU dispatches and bytes moved CPU ↔ GPU by the step's solve (0 on the CPU).
    pub gpu_dispatches: u64,
    pub gpu_bytes: u64,
    /// Contacts that detection at the start of the step missed and found overlapping at its
    /// end (a grain kicked farther than its reach); the projection separates them.
    pub missed: usize,
    /// Contacts that the position projection moved back to their surface (a pair meeting early
    /// in the step at θ < 1; 0 in a settled scene).
    pub projected: usize,
    /// Largest overlap at the end of the step (absolute length).
    pub max_penetration: f64,
    pub kinetic_energy: f64,
    pub potential_energy: f64,
    /// Wall time of the whole step, and of its detection and solve parts.
    pub seconds: f64,
    pub detection_seconds: f64,
    pub solve_seconds: f64,
}

#[derive(Debug, Error)]
pub enum StepError {
    #[error("invalid settings: {0}")]
    Settings(String),
    #[error("the scene cannot be integrated: {0}")]
    Unintegrable(String),
    /// The step's new state was not finite or ran away; the step was undone, so the
    /// simulation holds the last good state.
    #[error("step {step}: {message} (the state of step {} is kept)", step - 1)]
    Diverged { step: usize, message: String },
    #[error("step {step}: the contact problem is invalid: {message}")]
    Problem { step: usize, message: String },
    #[error("step {step}: {message}")]
    Device { step: usize, message: String },
}

pub struct Simulation {
    pub world: World,
    pub settings: StepSettings,
    pub(super) time: f64,
    pub(super) step_index: usize,
    pub(super) contacts: Vec<ContactState>,
    pub(super) detector: Detector,
    pub(super) warm_start: WarmStart,
    pub(super) keep_problem: bool,
    pub(super) last_problem: Option<ContactProblem>,
    /// Where each step's contact problem is solved.
    pub(super) backend: Backend,
    /// The scene's extent (runaway test), measured when the first step checks the world and
    /// again after bodies or walls are added.
    pub(super) extent: Option<f64>,
    /// Warnings about the start, from [`Self::check`].
    pub(super) warnings: Vec<String>,
    checked: bool,
}

impl Simulation {
    pub fn new(world: World, settings: StepSettings) -> Result<Self, StepError> {
        settings.validate().map_err(StepError::Settings)?;
        Ok(Self {
            world,
            settings,
            time: 0.0,
            step_index: 0,
            contacts: Vec::new(),
            detector: Detector::default(),
            warm_start: WarmStart::default(),
            keep_problem: false,
            last_problem: None,
            backend: Backend::cpu(),
            extent: None,
            warnings: Vec::new(),
            checked: false,
        })
    }

    /// Checks the world before the first step: refuses one that cannot be integrated with this
    /// time step (coordinates f64 cannot resolve at the grain size, a kinetic energy that
    /// overflows, a grain crossing the container in one step), and returns warnings about its
    /// start (grains outside the walls, in a wall, on top of each other). The first step runs it
    /// when the host has not.
    pub fn check(&mut self) -> Result<&[String], StepError> {
        if !self.checked {
            self.warnings =
                super::checks::check_start(&self.world, self.settings.h).map_err(StepError::Unintegrable)?;
            self.checked = true;
        }
        Ok(&self.warnings)
    }

    /// The scene's extent for the runaway test of each step.
    pub(super) fn extent(&mut self) -> f64 {
        *self.extent.get_or_insert_with(|| super::checks::extent(&self.world))
    }

    /// Solves every step on `backend`, refused up front when that device cannot do the
    /// settings' solve (the same check the command line makes).
    pub fn set_backend(&mut self, backend: Backend) -> Result<(), StepError> {
        backend.check(self.settings.solver, &self.settings.options).map_err(|e| StepError::Settings(e.to_string()))?;
        self.backend = backend;
        Ok(())
    }

    /// Where the steps are solved.
    pub fn backend(&self) -> &Backend {
        &self.backend
    }

    /// Adds a body; its density comes from its material.
    pub fn add_body(&mut self, spec: &BodySpec) -> Result<usize, String> {
        let density = *self
            .world
            .materials
            .density
            .get(spec.material)
            .ok_or_else(|| format!("material {} does not exist", spec.material))?;
        self.extent = None;
        self.world.bodies.add(spec, density)
    }

    pub fn add_wall(&mut self, wall: Wall) -> Result<usize, String> {
        if wall.material >= self.world.materials.len() {
            return Err(format!("material {} does not exist", wall.material));
        }
        if wall.is_moving() && !self.world.effects.moving_walls {
            return Err("a wall with a velocity needs the effect moving_walls".into());
        }
        self.extent = None;
        self.world.walls.push(wall);
        Ok(self.world.walls.len() - 1)
    }

    /// Advances one time step.
    pub fn step(&mut self) -> Result<StepReport, StepError> {
        self.check()?;
        super::moreau_jean::step(self)
    }

    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken so far.
    pub fn steps_done(&self) -> usize {
        self.step_index
    }

    /// Contacts of the last step with their impulses.
    pub fn contacts(&self) -> &[ContactState] {
        &self.contacts
    }

    pub fn position(&self, body: usize) -> DVec2 {
        self.world.bodies.position[body]
    }

    pub fn velocity(&self, body: usize) -> DVec2 {
        self.world.bodies.velocity[body]
    }

    /// Keep each step's contact problem (for `--dump-problem` and inspection).
    pub fn keep_problems(&mut self, keep: bool) {
        self.keep_problem = keep;
    }

    /// The contact problem of the last step, when [`Self::keep_problems`] is on.
    pub fn last_problem(&self) -> Option<&ContactProblem> {
        self.last_problem.as_ref()
    }
}
