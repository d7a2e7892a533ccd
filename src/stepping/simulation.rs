//! The library API: a [`Simulation`] owns a [`World`] and advances it one Moreau–Jean step at a
//! time; a host code may add bodies and walls between steps and read states and contact impulses.

use glam::DVec2;
use serde::Serialize;
use thiserror::Error;

use super::WarmStart;
use crate::backend::{Backend, DeviceChoice};
use crate::detection::{Antagonist, DetectedContact, Detector};
use crate::problem::cone::ContactStatus;
use crate::problem::ContactProblem;
use crate::solvers::{SolverKind, SolverOptions, StopReason};
use crate::world::{BodySpec, Wall, World, WorldError};

/// Time step, θ, alert distance and the solver of each step.
#[derive(Clone, Debug)]
pub struct StepSettings {
    /// Time step h.
    pub h: f64,
    /// θ of the θ-method, in [1/2, 1].
    pub theta: f64,
    /// Pairs closer than this become contacts (absolute length).
    pub alert: f64,
    /// An overlap that grew within a step by less than this fraction of the smaller grain's
    /// radius is left as it is; deeper ones are projected back to where they started the step.
    /// Growth below it accumulates over steps (BENCHMARKS.md, "The position projection's slack").
    pub projection_slack: f64,
    /// The solver of every step.
    pub solver: SolverKind,
    /// Its options (tolerance, budget, criterion).
    pub options: SolverOptions,
}

/// A scene's default alert distance, as a fraction of its smallest grain radius.
pub const DEFAULT_ALERT_FRACTION: f64 = 0.05;

/// The default [`StepSettings::projection_slack`].
pub const DEFAULT_PROJECTION_SLACK: f64 = 1e-4;

impl StepSettings {
    /// The settings a scene file gets when it names only its time step: θ = 1/2, an alert
    /// distance of 5 % of the smallest grain radius of `world` (add the grains first), NLGS to
    /// 1e-4 (natural-map error) with at most 10,000 sweeps.
    pub fn for_world(world: &World, h: f64) -> Self {
        let b = &world.bodies;
        let smallest =
            (0..b.len()).filter(|&k| b.inv_mass[k] > 0.0).map(|k| b.radius_of(k)).fold(f64::INFINITY, f64::min);
        Self {
            h,
            theta: 0.5,
            alert: if smallest.is_finite() { DEFAULT_ALERT_FRACTION * smallest } else { 0.0 },
            projection_slack: DEFAULT_PROJECTION_SLACK,
            solver: SolverKind::Nlgs,
            options: SolverOptions { tol: 1e-4, max_iter: 10_000, ..SolverOptions::default() },
        }
    }

    /// Checks h, θ, the alert distance and the solver options.
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
        if !(0.0..1.0).contains(&self.projection_slack) {
            return Err(format!(
                "projection_slack {} must lie in [0, 1): a fraction of a radius",
                self.projection_slack
            ));
        }
        self.options.validate().map_err(|e| format!("solver {e}"))
    }
}

/// A contact of the last step with its impulse (normal, tangential) and status.
#[derive(Clone, Copy, Debug)]
pub struct ContactState {
    /// Where and what: bodies, point, normal, gap.
    pub contact: DetectedContact,
    /// Normal and tangential impulse over the step.
    pub impulse: [f64; 2],
    /// Open, stick or slide.
    pub status: ContactStatus,
}

impl ContactState {
    /// The mean force of a step of length `h` on body `i`: the impulse in the (normal, tangent)
    /// frame, the tangent being the normal turned a quarter counter-clockwise.
    pub fn force(&self, h: f64) -> DVec2 {
        let n = self.contact.normal;
        (self.impulse[0] * n + self.impulse[1] * n.perp()) / h
    }

    /// The bodies the contact pushes on: (body, the step's mean force on it, the shift its
    /// position takes in this contact — a periodic image), body `i` first, the other only when
    /// it is a body.
    pub fn loaded_bodies(&self, h: f64) -> impl Iterator<Item = (usize, DVec2, DVec2)> {
        let force = self.force(h);
        let other = match self.contact.other {
            Antagonist::Body(j) => Some((j, -force, self.contact.image)),
            Antagonist::Wall(_) => None,
        };
        std::iter::once((self.contact.i, force, DVec2::ZERO)).chain(other)
    }
}

/// What one step did.
#[derive(Clone, Debug, Serialize)]
pub struct StepReport {
    /// Index of the step (from 1).
    pub step: usize,
    /// Time at its end (s).
    pub time: f64,
    /// Contacts detected.
    pub contacts: usize,
    /// Contacts whose impulse came from last step.
    pub warm_started: usize,
    /// Solver iterations.
    pub iterations: usize,
    /// Of them, those run on a GPU (the rest, on a GPU step, are the f64 finish on the CPU).
    pub gpu_iterations: usize,
    /// The solve's f64 error in the measure its stopping test judged (the velocity measure
    /// under `criterion = velocity`, else the natural map's), to be read against `tol`.
    pub error: f64,
    /// Whether the solve met its tolerance.
    pub converged: bool,
    /// Why the step's solve stopped (`converged` when there was nothing to solve).
    pub stop: StopReason,
    /// Why the solve stopped, in words.
    pub stop_reason: String,
    /// GPU dispatches and bytes moved CPU ↔ GPU by the step's solve and projection (0 on the CPU).
    pub gpu_dispatches: u64,
    /// Bytes moved between CPU and GPU.
    pub gpu_bytes: u64,
    /// Contacts that detection at the start of the step missed and found overlapping at its
    /// end (a grain kicked farther than its reach); the projection separates them.
    pub missed: usize,
    /// Contacts that the position projection moved back to their surface (a pair meeting early
    /// in the step at θ < 1; 0 in a settled scene).
    pub projected: usize,
    /// Largest overlap at the end of the step (absolute length).
    pub max_penetration: f64,
    /// Kinetic energy at the end of the step (J).
    pub kinetic_energy: f64,
    /// Potential energy in gravity at the end of the step (J).
    pub potential_energy: f64,
    /// Energy the contacts dissipated in the step (J): `−Σ r·ū` over them, `ū` a contact's
    /// relative velocity (normal, tangential, rolling) at the bodies' mean velocity over the step
    /// `½(v⁻ + v⁺)`, a moving wall's or a driven body's motion included. Friction and plastic
    /// impacts make it positive. With θ = ½, `ΔK + ΔP = boundary_work − dissipated_energy` in a
    /// step where no force but gravity acts and the position projection moves nothing.
    pub dissipated_energy: f64,
    /// Work done on the grains in the step through their contacts by moving walls and driven
    /// bodies (fixed bodies given a velocity, held axes) (J).
    pub boundary_work: f64,
    /// Wall time of the whole step, and of its detection and solve parts.
    pub seconds: f64,
    /// Detection time (s).
    pub detection_seconds: f64,
    /// Solve time (s).
    pub solve_seconds: f64,
    /// Time in the position projection (s), on the step's device.
    pub projection_seconds: f64,
    /// How a GPU solve checked its error (estimates, f64 judgements and their time): what its
    /// iterations cost beyond their kernels; zero on the CPU.
    pub gpu_checks: crate::solvers::GpuChecks,
    /// The scale the velocity tests divide a contact's residual by (m/s), so that every contact
    /// was asked to be within `tol` times it. Under `step-velocity` it is one step of the applied
    /// acceleration (g h); otherwise the largest free velocity of the step's contacts, gap terms
    /// left out, which a grain falling through a settled pile raises 100-fold (BENCHMARKS.md,
    /// "The velocity test's scale follows the fastest grain").
    pub velocity_scale: f64,
}

impl StepReport {
    /// Adds GPU traffic (dispatches, bytes) done by the step outside its solve.
    pub(crate) fn add_gpu_traffic(&mut self, (dispatches, bytes): (u64, u64)) {
        self.gpu_dispatches += dispatches;
        self.gpu_bytes += bytes;
    }
}

/// A step or a setting refused; the simulation keeps its last good state.
#[derive(Debug, Error)]
pub enum StepError {
    /// Settings that cannot run (time step, θ, solver options, effects).
    #[error("invalid settings: {0}")]
    Settings(String),
    /// A world this time step cannot integrate.
    #[error("the scene cannot be integrated: {0}")]
    Unintegrable(String),
    /// The step's new state was not finite or ran away; the step was undone, so the
    /// simulation holds the last good state.
    #[error("step {step}: {message} (the state of step {} is kept)", step - 1)]
    Diverged {
        /// The step undone.
        step: usize,
        /// What ran away.
        message: String,
    },
    /// A world whose materials, laws or walls are out of range.
    #[error("invalid world: {0}")]
    World(#[from] crate::world::WorldError),
    /// The step's contact problem could not be built.
    #[error("step {step}: the contact problem is invalid: {message}")]
    Problem {
        /// The step.
        step: usize,
        /// What is wrong with it.
        message: String,
    },
    /// The device failed or refused the solve.
    #[error("step {step}: {message}")]
    Device {
        /// The step.
        step: usize,
        /// The device's words.
        message: String,
    },
}

/// A host's request about a body or a wall that cannot be met.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum BodyError {
    /// No such body.
    #[error("body {body} does not exist (the simulation has {count} bodies)")]
    NoBody {
        /// The index asked for.
        body: usize,
        /// Bodies there are.
        count: usize,
    },
    /// No material of this index.
    #[error("material {0} does not exist")]
    NoMaterial(usize),
    /// No material of this name.
    #[error("material {0:?} does not exist")]
    NoMaterialNamed(String),
    /// A value that is NaN or infinite.
    #[error("{what} of body {body} must be finite, got {value}")]
    NotFinite {
        /// The body.
        body: usize,
        /// Which quantity.
        what: &'static str,
        /// The value given.
        value: String,
    },
    /// The body is fixed.
    #[error("body {0} is fixed: it takes no force or impulse (set its velocity and spin to move it)")]
    Fixed(usize),
    /// The world has no rotation.
    #[error("the world was built without the effect rotation: body {0} has no spin")]
    NoRotation(usize),
    /// No such wall.
    #[error("wall {wall} does not exist (the simulation has {count} walls)")]
    NoWall {
        /// The index asked for.
        wall: usize,
        /// Walls there are.
        count: usize,
    },
    /// A wall refused (its material, geometry or motion), or a body the periodic cell refuses.
    #[error(transparent)]
    World(#[from] crate::world::WorldError),
    /// Anything else, in words.
    #[error("{0}")]
    Invalid(String),
}

/// A world stepped by Moreau–Jean: the state, what one step hands to the next, and where solves run.
pub struct Simulation {
    /// Bodies, walls, materials, effects.
    pub world: World,
    /// Time step, θ, alert distance, solver.
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
    /// A scene file's warnings and notes, when the simulation came from one ([`Self::from_scene`]).
    scene_said: (Vec<String>, Vec<String>),
    /// External forces and torques on each body for the next step (empty when none is applied).
    pub(super) forces: Vec<(DVec2, f64)>,
    /// The threads this simulation's steps run on, when the host chose a count.
    pool: Option<std::sync::Arc<rayon::ThreadPool>>,
}

impl Simulation {
    /// A simulation of `world` at time 0; refuses settings that cannot run.
    pub fn new(world: World, settings: StepSettings) -> Result<Self, StepError> {
        settings.validate().map_err(StepError::Settings)?;
        world.validate()?;
        let rolling = world.effects.rolling_resistance;
        if let Some(why) = crate::solvers::rolling_refusal(rolling, settings.solver, settings.options.criterion) {
            return Err(StepError::Settings(why));
        }
        if rolling && !world.effects.rotation {
            return Err(StepError::Settings("rolling resistance needs the effect `rotation`".into()));
        }
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
            scene_said: (Vec::new(), Vec::new()),
            forces: Vec::new(),
            pool: None,
        })
    }

    /// Checks the world before the first step: refuses one that cannot be integrated with this
    /// time step (coordinates f64 cannot resolve at the grain size, a kinetic energy that
    /// overflows, a grain crossing the container in one step), and returns warnings about its
    /// start (grains outside the walls, in a wall, on top of each other), after its scene file's
    /// own ([`Self::from_scene`]). The first step runs it when the host has not.
    pub fn check(&mut self) -> Result<&[String], StepError> {
        if !self.checked {
            let start = super::checks::check_start(&self.world, self.settings.h).map_err(StepError::Unintegrable)?;
            self.warnings = self.scene_said.0.iter().cloned().chain(start).collect();
            self.checked = true;
        }
        Ok(&self.warnings)
    }

    /// What loading its scene file did that the file does not spell out (a grains file numbered
    /// in rows); empty for a simulation built otherwise. Notes, not warnings.
    pub fn notes(&self) -> &[String] {
        &self.scene_said.1
    }

    /// The scene's extent for the runaway test of each step.
    pub(super) fn extent(&mut self) -> f64 {
        *self.extent.get_or_insert_with(|| super::checks::extent(&self.world))
    }

    /// Solves every step on `backend`, refused up front when that device cannot do the
    /// settings' solve (the same check the command line makes).
    pub fn set_backend(&mut self, backend: Backend) -> Result<(), StepError> {
        backend.check(self.settings.solver, &self.settings.options).map_err(|e| StepError::Settings(e.to_string()))?;
        if let Some(why) = crate::backend::cpu_only(&self.world).filter(|_| backend.is_gpu()) {
            return Err(StepError::Settings(why.into()));
        }
        // The pause of a stalled GPU mixing follows the simulation's solves, not the device.
        // The state of another backend: one a pause reaches.
        let _ = backend.set_mixing_pause(self.backend.mixing_pause());
        self.backend = backend;
        Ok(())
    }

    /// Solves every step on the device `choice` picks for the settings' solve (`auto`: a
    /// hardware GPU that can do it, for a scene of at least [`crate::backend::GPU_MIN_BODIES`]
    /// bodies, else the CPU); returns the device and why, in one line.
    pub fn choose_device(&mut self, choice: DeviceChoice) -> Result<String, StepError> {
        let cpu_only = crate::backend::cpu_only(&self.world);
        let bodies = self.world.bodies.len();
        let backend = Backend::choose_for_scene(choice, self.settings.solver, &self.settings.options, cpu_only, bodies)
            .map_err(|e| StepError::Settings(e.to_string()))?;
        let line = backend.describe();
        // The state of another backend: one a pause reaches.
        let _ = backend.set_mixing_pause(self.backend.mixing_pause());
        self.backend = backend;
        Ok(line)
    }

    /// Runs this simulation's steps on `threads` threads of its own (0: rayon's global pool,
    /// all cores unless the process chose otherwise). Results depend on the count, not the run.
    pub fn set_threads(&mut self, threads: usize) -> Result<(), StepError> {
        self.pool = match threads {
            0 => None,
            n => Some(std::sync::Arc::new(crate::parallel::thread_pool(n).map_err(StepError::Settings)?)),
        };
        Ok(())
    }

    /// The solver of the following steps and its options (tolerance, budget, criterion,
    /// ordering, acceleration), as a host sets them after loading a scene: `settings` checked
    /// first, as [`Self::new`] and [`Self::set_backend`] check them (options out of range, a
    /// solver the world's rolling rows or the current device cannot run are refused).
    pub fn set_solver(&mut self, solver: SolverKind, options: SolverOptions) -> Result<(), StepError> {
        let settings = StepSettings { solver, options, ..self.settings.clone() };
        settings.validate().map_err(StepError::Settings)?;
        let rolling = self.world.effects.rolling_resistance;
        if let Some(why) = crate::solvers::rolling_refusal(rolling, solver, settings.options.criterion) {
            return Err(StepError::Settings(why));
        }
        self.backend.check(solver, &settings.options).map_err(|e| StepError::Settings(e.to_string()))?;
        self.settings = settings;
        Ok(())
    }

    /// The time step of the following steps; refused, with the settings unchanged, when it is
    /// not finite and positive. The next step starts from the last step's impulses scaled to
    /// it (an impulse is a force times the step).
    pub fn set_time_step(&mut self, h: f64) -> Result<(), StepError> {
        let settings = StepSettings { h, ..self.settings.clone() };
        settings.validate().map_err(StepError::Settings)?;
        self.settings = settings;
        Ok(())
    }

    /// Where the steps are solved.
    pub fn backend(&self) -> &Backend {
        &self.backend
    }

    /// The simulation a scene file describes (its bodies, walls, materials, effects and step
    /// settings), on the CPU; `scene.steps` and the outputs are the command line's business. The
    /// file's warnings come first in [`Self::check`]'s, its notes from [`Self::notes`].
    pub fn from_scene(path: &std::path::Path) -> Result<Self, crate::Error> {
        Ok(Self::from_loaded(crate::scene::load(path)?)?)
    }

    /// The simulation of a scene already loaded, as [`Self::from_scene`] makes it (the file's
    /// warnings and notes kept).
    pub fn from_loaded(scene: crate::scene::Scene) -> Result<Self, StepError> {
        let mut sim = Self::new(scene.world, scene.settings)?;
        sim.scene_said = (scene.warnings, scene.notes);
        Ok(sim)
    }

    /// Adds a body; its density comes from its material. In a periodic world it is brought into
    /// the cell, and refused when wider than a quarter of it.
    pub fn add_body(&mut self, spec: &BodySpec) -> Result<usize, BodyError> {
        if spec.material >= self.world.materials.len() {
            return Err(BodyError::NoMaterial(spec.material));
        }
        self.extent = None;
        self.world.add_body(spec).map_err(|e| match e {
            WorldError::Body(why) => BodyError::Invalid(why),
            other => BodyError::World(other),
        })
    }

    /// Adds a disk of the named material, moving at `velocity`; returns its index.
    pub fn add_disk(
        &mut self,
        center: DVec2,
        radius: f64,
        material: &str,
        velocity: DVec2,
    ) -> Result<usize, BodyError> {
        let mut spec = BodySpec::disk(center, radius, self.material(material)?);
        spec.velocity = velocity;
        self.add_body(&spec)
    }

    /// Adds a wall; returns its index.
    pub fn add_wall(&mut self, wall: Wall) -> Result<usize, BodyError> {
        let index = self.world.add_wall(wall)?;
        self.extent = None;
        Ok(index)
    }

    /// Sets a wall's velocity (m/s) and spin about its centre (rad/s) from the next step on: a
    /// host driving a piston or a shear box (the world needs the effect moving_walls).
    pub fn set_wall_motion(&mut self, wall: usize, velocity: DVec2, spin: f64) -> Result<(), BodyError> {
        let count = self.world.walls.len();
        let w = self.world.walls.get(wall).ok_or(BodyError::NoWall { wall, count })?;
        let moved = Wall { velocity, spin, ..w.clone() };
        self.world.check_wall(wall, &moved)?;
        self.world.walls[wall] = moved;
        Ok(())
    }

    /// Removes a body: the bodies after it move down one index (as in a `Vec`), its contacts
    /// are dropped and the others keep their warm start.
    pub fn remove_body(&mut self, body: usize) -> Result<(), BodyError> {
        let k = self.body_index(body)?;
        self.world.bodies.remove(k);
        if k < self.forces.len() {
            self.forces.remove(k);
        }
        self.contacts = std::mem::take(&mut self.contacts)
            .into_iter()
            .filter_map(|mut c| {
                let (i, other, _) = super::warm_start::key_without_body(c.contact.key(), k)?;
                (c.contact.i, c.contact.other) = (i, other);
                Some(c)
            })
            .collect();
        self.warm_start.forget_body(k);
        self.last_problem = None;
        self.extent = None;
        Ok(())
    }

    /// The index of the material called `name`.
    pub fn material(&self, name: &str) -> Result<usize, BodyError> {
        self.world.materials.index_of(name).ok_or_else(|| BodyError::NoMaterialNamed(name.to_string()))
    }

    /// How many bodies there are (indices `0..body_count()`).
    pub fn body_count(&self) -> usize {
        self.world.bodies.len()
    }

    fn body_index(&self, body: usize) -> Result<usize, BodyError> {
        let count = self.world.bodies.len();
        if body < count {
            Ok(body)
        } else {
            Err(BodyError::NoBody { body, count })
        }
    }

    fn moving_body(&self, body: usize) -> Result<usize, BodyError> {
        let k = self.body_index(body)?;
        if self.world.bodies.inv_mass[k] == 0.0 {
            return Err(BodyError::Fixed(k));
        }
        Ok(k)
    }

    /// Sets a body's velocity (from the next step on); a fixed body keeps it (a kinematic body),
    /// as a body keeps it along an axis where it holds its velocity (`hold_velocity`).
    pub fn set_velocity(&mut self, body: usize, velocity: DVec2) -> Result<(), BodyError> {
        let k = self.body_index(body)?;
        finite(k, "velocity", velocity.is_finite(), velocity)?;
        self.world.bodies.velocity[k] = velocity;
        Ok(())
    }

    /// Sets a body's spin (rad/s); needs the effect rotation. A fixed body keeps it; a body that
    /// keeps its angle (`lock_rotation`) has none to set.
    pub fn set_spin(&mut self, body: usize, spin: f64) -> Result<(), BodyError> {
        let k = self.body_index(body)?;
        finite(k, "spin", spin.is_finite(), spin)?;
        if !self.world.bodies.has_rotation() {
            return Err(BodyError::NoRotation(k));
        }
        let b = &self.world.bodies;
        if b.inv_mass[k] > 0.0 && b.inv_inertia[k] == 0.0 {
            return Err(BodyError::Invalid(format!("body {k} keeps its angle (lock_rotation): it has no spin to set")));
        }
        self.world.bodies.spin[k] = spin;
        Ok(())
    }

    /// Applies an impulse `impulse` (N·s) at the world point `at`: the body's velocity and spin
    /// change at once (the spin only with the effect rotation).
    pub fn apply_impulse(&mut self, body: usize, impulse: DVec2, at: DVec2) -> Result<(), BodyError> {
        let k = self.moving_body(body)?;
        finite(k, "impulse", impulse.is_finite() && at.is_finite(), (impulse, at))?;
        let b = &mut self.world.bodies;
        let [mx, my] = b.axis_inv_mass(k);
        b.velocity[k] += DVec2::new(mx * impulse.x, my * impulse.y);
        if b.has_rotation() {
            b.spin[k] += b.inv_inertia[k] * (at - b.position[k]).perp_dot(impulse);
        }
        Ok(())
    }

    /// Adds a force (N) and a torque (N·m, counted only with the effect rotation) on a body
    /// during the next step only, as gravity acts: in its free velocity, so the contacts
    /// answer it within the step. Forces on one body add up until that step.
    pub fn apply_force(&mut self, body: usize, force: DVec2, torque: f64) -> Result<(), BodyError> {
        let k = self.moving_body(body)?;
        finite(k, "force", force.is_finite() && torque.is_finite(), (force, torque))?;
        if self.forces.len() != self.world.bodies.len() {
            self.forces.resize(self.world.bodies.len(), (DVec2::ZERO, 0.0));
        }
        self.forces[k].0 += force;
        self.forces[k].1 += torque;
        Ok(())
    }

    /// Advances one time step.
    pub fn step(&mut self) -> Result<StepReport, StepError> {
        self.check()?;
        match self.pool.clone() {
            Some(pool) => pool.install(|| super::moreau_jean::step(self)),
            None => crate::parallel::on_pool(|| super::moreau_jean::step(self)),
        }
    }

    /// Simulated time (s).
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

    /// A body's centre. Panics when `body` is not below [`Self::body_count`], as indexing does.
    pub fn position(&self, body: usize) -> DVec2 {
        self.world.bodies.position[body]
    }

    /// A body's velocity. Panics when `body` is not below [`Self::body_count`].
    pub fn velocity(&self, body: usize) -> DVec2 {
        self.world.bodies.velocity[body]
    }

    /// A body's angle (0 without the effect rotation). Panics when `body` does not exist.
    pub fn angle(&self, body: usize) -> f64 {
        self.world.bodies.angle_of(body)
    }

    /// A body's spin (0 without the effect rotation). Panics when `body` does not exist.
    pub fn spin(&self, body: usize) -> f64 {
        self.world.bodies.spin_of(body)
    }

    /// Every body's centre, in body order.
    pub fn positions(&self) -> &[DVec2] {
        &self.world.bodies.position
    }

    /// Every body's velocity, in body order.
    pub fn velocities(&self) -> &[DVec2] {
        &self.world.bodies.velocity
    }

    /// Keep each step's contact problem (for `--dump-problem` and inspection).
    pub fn keep_problems(&mut self, keep: bool) {
        self.keep_problem = keep;
    }

    /// The contact problem the next step will solve and its warm start, without stepping
    /// (detection, free velocities, the local problem: the step's first stages; nothing moves):
    /// for a host that studies or solves it itself. `None` when no pair is in reach. With
    /// cohesion the problem is in shifted impulses `r + c e_n`, as the step solves it.
    pub fn next_problem(&mut self) -> Result<Option<(ContactProblem, Vec<f64>)>, StepError> {
        self.check()?;
        let assembled = super::moreau_jean::assemble(self, self.step_index + 1)?;
        Ok(assembled.problem.map(|p| (p, assembled.r0)))
    }

    /// The contact problem of the last step, when [`Self::keep_problems`] is on.
    pub fn last_problem(&self) -> Option<&ContactProblem> {
        self.last_problem.as_ref()
    }
}

fn finite(body: usize, what: &'static str, ok: bool, value: impl std::fmt::Debug) -> Result<(), BodyError> {
    if ok {
        Ok(())
    } else {
        Err(BodyError::NotFinite { body, what, value: format!("{value:?}") })
    }
}
