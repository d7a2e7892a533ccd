//! `moreau._moreau`: the compiled part of the Python package. Arrays cross as `bytes` of
//! little-endian f64 (or integers), which `moreau/__init__.py` turns into numpy arrays; every
//! error is a `moreau.MoreauError` with the library's message. Solves and steps release the
//! GIL.

use std::path::PathBuf;

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use moreau::backend::{solve_by_name, DeviceChoice};
use moreau::detection::Antagonist;
use moreau::io::siconos::{read_fc2d, write_fc2d, Storage};
use moreau::problem::{BlockSparse, ContactProblem, Delassus};
use moreau::solvers::{Ordering, StopCriterion};
use moreau::world::Interaction;
use moreau::{BodySpec, DVec2, SolverOptions, StepSettings, Wall};

create_exception!(_moreau, MoreauError, PyException, "An error from moreau; the message names the problem.");

fn error(e: impl ToString) -> PyErr {
    MoreauError::new_err(e.to_string())
}

/// `bytes` as little-endian values of `T` (`kind` names it in the error).
fn values<T: bytemuck::Pod>(bytes: &[u8], name: &str, kind: &str) -> PyResult<Vec<T>> {
    if !bytes.len().is_multiple_of(std::mem::size_of::<T>()) {
        return Err(error(format!("{name}: {} bytes is not a whole number of {kind}", bytes.len())));
    }
    Ok(bytemuck::pod_collect_to_vec(bytes))
}

fn floats(bytes: &[u8], name: &str) -> PyResult<Vec<f64>> {
    values(bytes, name, "float64")
}

fn indices(bytes: &[u8], name: &str) -> PyResult<Vec<i64>> {
    values(bytes, name, "int64")
}

/// Indices as `usize`; a negative one is an error naming the array.
fn unsigned(values: Vec<i64>, name: &str) -> PyResult<Vec<usize>> {
    values.into_iter().map(|v| usize::try_from(v).map_err(|_| error(format!("{name}: {v} is negative")))).collect()
}

fn to_bytes<'py, T: bytemuck::Pod>(py: Python<'py>, values: &[T]) -> Bound<'py, PyBytes> {
    PyBytes::new(py, bytemuck::cast_slice(values))
}

fn vec2(v: (f64, f64)) -> DVec2 {
    DVec2::new(v.0, v.1)
}

/// One step's frictional contact problem `u = W r + q`, `mu` per contact.
#[pyclass(name = "Problem", module = "moreau._moreau", frozen)]
struct Problem(ContactProblem);

#[pymethods]
impl Problem {
    /// `W` as 2n × 2n compressed sparse rows (int64 `indptr`, `indices`; float64 `data`),
    /// `q` (2n) and `mu` (n), as bytes.
    #[staticmethod]
    fn from_csr(n: usize, indptr: &[u8], indices_: &[u8], data: &[u8], q: &[u8], mu: &[u8]) -> PyResult<Self> {
        let indptr = unsigned(indices(indptr, "indptr")?, "indptr")?;
        let columns = unsigned(indices(indices_, "indices")?, "indices")?;
        let w = BlockSparse::from_csr(n, &indptr, &columns, &floats(data, "data")?)
            .map_err(|e| error(format!("W: {e}")))?;
        let w = Delassus::Sparse(w);
        ContactProblem::new(w, floats(q, "q")?, floats(mu, "mu")?).map(Self).map_err(error)
    }

    #[getter]
    fn n_contacts(&self) -> usize {
        self.0.n_contacts()
    }

    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        to_bytes(py, &self.0.q)
    }

    #[getter]
    fn mu<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        to_bytes(py, &self.0.mu)
    }

    /// Whether `W` is matrix-free (`B M⁻¹ Bᵀ` of a simulation step) rather than explicit.
    #[getter]
    fn matrix_free(&self) -> bool {
        matches!(self.0.w, Delassus::MatrixFree(_))
    }

    /// `W r + q` for `r` given as bytes (2n float64).
    fn velocity<'py>(&self, py: Python<'py>, r: &[u8]) -> PyResult<Bound<'py, PyBytes>> {
        let r = floats(r, "r")?;
        if r.len() != self.0.q.len() {
            return Err(error(format!("r has {} entries, expected {} (2 per contact)", r.len(), self.0.q.len())));
        }
        Ok(to_bytes(py, &self.0.velocity(&r)))
    }

    /// Writes the problem as a Siconos fc2d file (17 digits; sparse or dense `W`).
    #[pyo3(signature = (path, sparse = true))]
    fn write_fc2d(&self, path: PathBuf, sparse: bool) -> PyResult<()> {
        let storage = if sparse { Storage::Sparse } else { Storage::Dense };
        write_fc2d(&self.0, storage, &path).map_err(error)
    }
}

/// The stopping criterion and NLGS ordering named `criterion` and `ordering`.
fn criterion_and_ordering(criterion: &str, ordering: &str) -> PyResult<(StopCriterion, Ordering)> {
    Ok((StopCriterion::from_name(criterion).map_err(error)?, Ordering::from_name(ordering).map_err(error)?))
}

/// Reads a Siconos fc2d problem file.
#[pyfunction(name = "read_fc2d")]
fn read_problem(path: PathBuf) -> PyResult<Problem> {
    read_fc2d(&path).map(Problem).map_err(error)
}

/// The first step of `disks` disks deposited in a 20 cm box and loaded by gravity from rest
/// (`moreau generate deposit`).
#[pyfunction(name = "deposit")]
fn deposit_problem(disks: i64, mu: f64, seed: u64) -> PyResult<Problem> {
    let max = moreau::sweep::problems::MAX_DEPOSIT_DISKS;
    let disks = usize::try_from(disks).map_err(|_| error(format!("a deposit of {disks} disks: give 1 to {max}")))?;
    moreau::sweep::problems::deposit_problem(disks, mu, seed).map(Problem).map_err(|e| error(format!("{e:#}")))
}

/// Solves `problem`; returns a dict of the report (arrays as bytes).
#[pyfunction]
#[pyo3(signature = (problem, solver, tol, max_iter, device, threads, r0 = None, history_every = 0, anderson = 0, focus = 0, criterion = "natural", ordering = "forward", omega = 1.0))]
#[allow(clippy::too_many_arguments)]
fn solve<'py>(
    py: Python<'py>,
    problem: &Problem,
    solver: &str,
    tol: f64,
    max_iter: usize,
    device: &str,
    threads: usize,
    r0: Option<&[u8]>,
    history_every: usize,
    anderson: usize,
    focus: usize,
    criterion: &str,
    ordering: &str,
    omega: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let r0 = r0.map(|b| floats(b, "r0")).transpose()?;
    let (criterion, ordering) = criterion_and_ordering(criterion, ordering)?;
    let opts = SolverOptions {
        tol,
        max_iter,
        history_every,
        anderson,
        focus,
        criterion,
        ordering,
        omega,
        ..SolverOptions::default()
    };
    let problem = &problem.0;
    let (report, device) =
        py.detach(|| solve_by_name(problem, solver, device, threads, &opts, r0.as_deref())).map_err(error)?;
    let parts: Vec<(String, usize, f64, f64)> =
        report.parts.iter().map(|p| (p.device.clone(), p.iterations, p.seconds, p.error)).collect();
    let gpu_iterations = report.gpu_iterations();
    let d = PyDict::new(py);
    d.set_item("r", to_bytes(py, &report.r))?;
    d.set_item("u", to_bytes(py, &report.u))?;
    d.set_item("converged", report.converged)?;
    d.set_item("error", report.error)?;
    d.set_item("judged_error", report.judged_error)?;
    d.set_item("velocity_error", moreau::io::report::answer_velocity_error(problem, &report))?;
    d.set_item("iterations", report.iterations)?;
    d.set_item("seconds", report.seconds)?;
    d.set_item("w_products", report.w_products)?;
    d.set_item("stop", report.stop.name())?;
    d.set_item("stop_reason", report.stop_reason)?;
    d.set_item("solver", report.solver.name())?;
    d.set_item("device", device)?;
    let history: Vec<(usize, f64, f64)> = report.history.iter().map(|h| (h.iteration, h.seconds, h.error)).collect();
    d.set_item("history", history)?;
    d.set_item("parts", parts)?;
    d.set_item("gpu_iterations", gpu_iterations)?;
    d.set_item("notes", report.notes.clone())?;
    Ok(d)
}

/// Materials, effects, bodies and walls, gathered before a simulation starts.
#[pyclass(name = "World", module = "moreau._moreau")]
struct World(moreau::World);

fn material_named(world: &moreau::World, name: &str) -> PyResult<usize> {
    world.material_named(name).map_err(error)
}

/// A clump's shape from Python's `(x, y, r)` triples.
fn clump(center: (f64, f64), disks: Vec<(f64, f64, f64)>) -> BodySpec {
    BodySpec::clump(vec2(center), disks.into_iter().map(|(x, y, r)| (DVec2::new(x, y), r)).collect(), 0)
}

#[allow(clippy::too_many_arguments)]
fn body_spec(
    world: &moreau::World,
    mut spec: BodySpec,
    material_name: &str,
    angle: f64,
    velocity: (f64, f64),
    spin: f64,
    fixed: bool,
    tag: u32,
    drive: Drive,
) -> PyResult<BodySpec> {
    spec.material = material_named(world, material_name)?;
    spec.angle = angle;
    spec.velocity = vec2(velocity);
    spec.spin = spin;
    spec.fixed = fixed;
    spec.tag = tag;
    spec.force = vec2(drive.force);
    spec.lock_rotation = drive.lock_rotation;
    spec.mass = drive.mass;
    for axis in &drive.hold_velocity {
        spec.hold_axis(axis).map_err(|e| error(format!("hold_velocity: {e}")))?;
    }
    Ok(spec)
}

/// The keywords that make a body a piston or a driven plate, as a scene's `[[body]]` has them:
/// a constant force (N), its angle kept, its mass (kg) instead of density × area, the axes
/// ("x", "y") along which it keeps its velocity.
struct Drive {
    force: (f64, f64),
    lock_rotation: bool,
    mass: Option<f64>,
    hold_velocity: Vec<String>,
}

#[pymethods]
impl World {
    /// `materials`: (name, density) pairs; one contact law for every pair of materials, which
    /// `set_interaction` changes per pair. An effect is on when its parameter is given.
    #[new]
    #[pyo3(signature = (materials, friction = 0.0, restitution = 0.0, cohesion = 0.0, gravity = None, rotation = false, moving_walls = false, rolling_resistance = 0.0))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        materials: Vec<(String, f64)>,
        friction: f64,
        restitution: f64,
        cohesion: f64,
        gravity: Option<(f64, f64)>,
        rotation: bool,
        moving_walls: bool,
        rolling_resistance: f64,
    ) -> PyResult<Self> {
        let law = Interaction { friction, restitution, cohesion, rolling_resistance };
        moreau::World::in_code(materials, law, gravity.map(vec2), rotation, moving_walls).map(Self).map_err(error)
    }

    /// Makes the bodies and walls of materials `a` and `b` pass through each other
    /// (`through`), or touch again: a scene's `[[interaction]] pass_through`.
    #[pyo3(signature = (a, b, through = true))]
    fn set_pass_through(&mut self, a: &str, b: &str, through: bool) -> PyResult<()> {
        self.0.set_pass_through(a, b, through).map_err(error)
    }

    /// The contact law between materials `a` and `b`.
    #[pyo3(signature = (a, b, friction = 0.0, restitution = 0.0, cohesion = 0.0, rolling_resistance = 0.0))]
    fn set_interaction(
        &mut self,
        a: &str,
        b: &str,
        friction: f64,
        restitution: f64,
        cohesion: f64,
        rolling_resistance: f64,
    ) -> PyResult<()> {
        let law = Interaction { friction, restitution, cohesion, rolling_resistance };
        self.0.set_interaction(a, b, law).map_err(error)
    }

    /// Adds a disk; returns its index. The keyword-only `force`, `lock_rotation`, `mass` and
    /// `hold_velocity` (axes "x", "y") make a piston or a driven plate, as in a scene's `[[body]]`;
    /// `add_polygon` and `add_clump` take them too.
    #[pyo3(signature = (center, radius, material, velocity = (0.0, 0.0), spin = 0.0, fixed = false, tag = 0, *, force = (0.0, 0.0), lock_rotation = false, mass = None, hold_velocity = Vec::new()))]
    #[allow(clippy::too_many_arguments)]
    fn add_disk(
        &mut self,
        center: (f64, f64),
        radius: f64,
        material: &str,
        velocity: (f64, f64),
        spin: f64,
        fixed: bool,
        tag: u32,
        force: (f64, f64),
        lock_rotation: bool,
        mass: Option<f64>,
        hold_velocity: Vec<String>,
    ) -> PyResult<usize> {
        let drive = Drive { force, lock_rotation, mass, hold_velocity };
        let spec = body_spec(
            &self.0,
            BodySpec::disk(vec2(center), radius, 0),
            material,
            0.0,
            velocity,
            spin,
            fixed,
            tag,
            drive,
        )?;
        self.add(&spec)
    }

    /// Adds a polygon (vertices relative to `center`: convex in any order, or a concave outline in
    /// either direction); returns its index.
    #[pyo3(signature = (center, vertices, material, angle = 0.0, velocity = (0.0, 0.0), spin = 0.0, fixed = false, tag = 0, *, force = (0.0, 0.0), lock_rotation = false, mass = None, hold_velocity = Vec::new()))]
    #[allow(clippy::too_many_arguments)]
    fn add_polygon(
        &mut self,
        center: (f64, f64),
        vertices: Vec<(f64, f64)>,
        material: &str,
        angle: f64,
        velocity: (f64, f64),
        spin: f64,
        fixed: bool,
        tag: u32,
        force: (f64, f64),
        lock_rotation: bool,
        mass: Option<f64>,
        hold_velocity: Vec<String>,
    ) -> PyResult<usize> {
        let drive = Drive { force, lock_rotation, mass, hold_velocity };
        let shape = BodySpec::polygon(vec2(center), vertices.into_iter().map(vec2).collect(), 0);
        let spec = body_spec(&self.0, shape, material, angle, velocity, spin, fixed, tag, drive)?;
        self.add(&spec)
    }

    /// Adds a clump: disks `(x, y, r)` (centres relative to `center`) that overlap into one
    /// rigid grain, turning about their union's centroid; returns its index.
    #[pyo3(signature = (center, disks, material, angle = 0.0, velocity = (0.0, 0.0), spin = 0.0, fixed = false, tag = 0, *, force = (0.0, 0.0), lock_rotation = false, mass = None, hold_velocity = Vec::new()))]
    #[allow(clippy::too_many_arguments)]
    fn add_clump(
        &mut self,
        center: (f64, f64),
        disks: Vec<(f64, f64, f64)>,
        material: &str,
        angle: f64,
        velocity: (f64, f64),
        spin: f64,
        fixed: bool,
        tag: u32,
        force: (f64, f64),
        lock_rotation: bool,
        mass: Option<f64>,
        hold_velocity: Vec<String>,
    ) -> PyResult<usize> {
        let drive = Drive { force, lock_rotation, mass, hold_velocity };
        let spec = body_spec(&self.0, clump(center, disks), material, angle, velocity, spin, fixed, tag, drive)?;
        self.add(&spec)
    }

    /// Adds the disks of a grains CSV file (the columns of `[[grains]]`: x, y, r and optionally vx,
    /// vy, spin, tag, material, fixed), each of `material` unless its row names one; `order` as a scene's
    /// `[[grains]] order` (auto, space, file). Returns each row's body index, in the file's order.
    #[pyo3(signature = (path, material, order = "auto"))]
    fn add_grains(&mut self, path: PathBuf, material: &str, order: &str) -> PyResult<Vec<usize>> {
        use moreau::scene::grains_csv::{add_grains, GrainOrder};
        let order = GrainOrder::from_name(order).map_err(error)?;
        add_grains(&mut self.0, &path, material, order).map_err(error)
    }

    /// Adds a wall segment from `a` to `b` (moving at `velocity` with the effect moving_walls).
    #[pyo3(signature = (a, b, material, velocity = (0.0, 0.0)))]
    fn add_wall(&mut self, a: (f64, f64), b: (f64, f64), material: &str, velocity: (f64, f64)) -> PyResult<usize> {
        let mut wall = Wall::segment(vec2(a), vec2(b), material_named(&self.0, material)?);
        wall.velocity = vec2(velocity);
        self.0.add_wall(wall).map_err(error)
    }

    /// Adds a solid wall polygon of world `vertices` (convex, or a concave outline), moving at
    /// `velocity` and turning at `spin` about its centroid (with the effect moving_walls).
    #[pyo3(signature = (vertices, material, velocity = (0.0, 0.0), spin = 0.0))]
    fn add_polygon_wall(
        &mut self,
        vertices: Vec<(f64, f64)>,
        material: &str,
        velocity: (f64, f64),
        spin: f64,
    ) -> PyResult<usize> {
        let vertices: Vec<DVec2> = vertices.into_iter().map(vec2).collect();
        let mut wall = Wall::polygon(&vertices, None, material_named(&self.0, material)?).map_err(error)?;
        (wall.velocity, wall.spin) = (vec2(velocity), spin);
        self.0.add_wall(wall).map_err(error)
    }

    /// Adds a drum: `sides` wall segments on the circle of `radius` about `center`, turning at
    /// `spin` about it (with the effect moving_walls); returns their indices.
    #[pyo3(signature = (center, radius, sides, material, spin = 0.0))]
    fn add_drum(
        &mut self,
        center: (f64, f64),
        radius: f64,
        sides: usize,
        material: &str,
        spin: f64,
    ) -> PyResult<Vec<usize>> {
        let ring = Wall::drum(vec2(center), radius, sides, None, material_named(&self.0, material)?).map_err(error)?;
        let added = self.0.add_walls(ring.into_iter().map(|w| Wall { spin, ..w }).collect()).map_err(error)?;
        Ok(added.collect())
    }

    /// Makes the world periodic along x over [x0, x1) (a shear cell, a slope without side walls):
    /// every body, and each one added later, is brought into the cell; the cell must be at least
    /// four of the widest bodies long.
    fn set_periodic(&mut self, x0: f64, x1: f64) -> PyResult<()> {
        self.0.set_periodic(x0, x1).map_err(error)
    }

    /// The periodic cell (x0, x1), or None.
    #[getter]
    fn periodic(&self) -> Option<(f64, f64)> {
        self.0.periodic.map(|p| (p.x0, p.x1))
    }

    #[getter]
    fn body_count(&self) -> usize {
        self.0.bodies.len()
    }
}

impl World {
    fn add(&mut self, spec: &BodySpec) -> PyResult<usize> {
        self.0.add_body(spec).map_err(error)
    }
}

fn loads_dict<'py>(py: Python<'py>, loads: &[moreau::stepping::WallLoad]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("force", to_bytes(py, &loads.iter().flat_map(|l| l.force).collect::<Vec<f64>>()))?;
    d.set_item("moment", to_bytes(py, &loads.iter().map(|l| l.moment).collect::<Vec<f64>>()))?;
    Ok(d)
}

/// A serialisable report as a Python dict (through JSON, so the keys are the Rust field names).
fn json_dict<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyDict>> {
    let json = serde_json::to_string(value).map_err(error)?;
    py.import("json")?.call_method1("loads", (json,))?.cast_into::<PyDict>().map_err(|e| error(e.to_string()))
}

/// A world advanced one Moreau–Jean step at a time.
#[pyclass(name = "Simulation", module = "moreau._moreau")]
struct Simulation(moreau::Simulation);

#[pymethods]
impl Simulation {
    /// A simulation of `world` with time step `h`; the alert distance defaults to 5 % of the
    /// smallest grain radius, the solver to NLGS at `tol` and the position projection's slack to
    /// 1e-4 of a radius.
    #[new]
    #[pyo3(signature = (world, h, theta = 0.5, alert = None, solver = "nlgs", tol = 1e-4, max_iter = 10_000, anderson = 0, focus = 0, criterion = "natural", ordering = "forward", projection_slack = None, omega = 1.0))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        world: &World,
        h: f64,
        theta: f64,
        alert: Option<f64>,
        solver: &str,
        tol: f64,
        max_iter: usize,
        anderson: usize,
        focus: usize,
        criterion: &str,
        ordering: &str,
        projection_slack: Option<f64>,
        omega: f64,
    ) -> PyResult<Self> {
        let mut settings = StepSettings::for_world(&world.0, h);
        settings.theta = theta;
        settings.projection_slack = projection_slack.unwrap_or(settings.projection_slack);
        settings.alert = alert.unwrap_or(settings.alert);
        settings.solver = moreau::SolverKind::from_name(solver).map_err(error)?;
        let (criterion, ordering) = criterion_and_ordering(criterion, ordering)?;
        settings.options =
            SolverOptions { tol, max_iter, anderson, focus, criterion, ordering, omega, ..settings.options };
        moreau::Simulation::new(world.0.clone(), settings).map(Self).map_err(error)
    }

    /// The solver of the following steps: each argument given replaces the current setting (a
    /// scene's, or the constructor's), the others stay; refused, with the settings unchanged,
    /// when the result cannot run.
    #[pyo3(signature = (solver = None, tol = None, max_iter = None, criterion = None, ordering = None, anderson = None, focus = None, omega = None, block_sweeps = None))]
    #[allow(clippy::too_many_arguments)]
    fn set_solver(
        &mut self,
        solver: Option<&str>,
        tol: Option<f64>,
        max_iter: Option<usize>,
        criterion: Option<&str>,
        ordering: Option<&str>,
        anderson: Option<usize>,
        focus: Option<usize>,
        omega: Option<f64>,
        block_sweeps: Option<usize>,
    ) -> PyResult<()> {
        let now = &self.0.settings;
        let solver = solver.map(moreau::SolverKind::from_name).transpose().map_err(error)?.unwrap_or(now.solver);
        let mut options = now.options.clone();
        options.tol = tol.unwrap_or(options.tol);
        options.max_iter = max_iter.unwrap_or(options.max_iter);
        options.criterion =
            criterion.map(StopCriterion::from_name).transpose().map_err(error)?.unwrap_or(options.criterion);
        options.ordering = ordering.map(Ordering::from_name).transpose().map_err(error)?.unwrap_or(options.ordering);
        options.anderson = anderson.unwrap_or(options.anderson);
        options.focus = focus.unwrap_or(options.focus);
        options.omega = omega.unwrap_or(options.omega);
        options.block_sweeps = block_sweeps.unwrap_or(options.block_sweeps);
        self.0.set_solver(solver, options).map_err(error)
    }

    /// The time step of the following steps (s); refused, with the settings unchanged, when it
    /// is not finite and positive. The next step starts from the last step's impulses scaled
    /// to it.
    fn set_time_step(&mut self, h: f64) -> PyResult<()> {
        self.0.set_time_step(h).map_err(error)
    }

    /// The time step of the steps (s).
    #[getter]
    fn time_step(&self) -> f64 {
        self.0.settings.h
    }

    /// The solver of the steps and its options, as a dict (`solver`, `tol`, `max_iter`,
    /// `criterion`, `ordering`, `anderson`, `focus`, …).
    fn solver_settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = json_dict(py, &self.0.settings.options)?;
        d.set_item("solver", self.0.settings.solver.name())?;
        Ok(d)
    }

    /// The simulation a scene file describes.
    #[staticmethod]
    fn from_scene(path: PathBuf) -> PyResult<Self> {
        moreau::Simulation::from_scene(&path).map(Self).map_err(error)
    }

    /// Checks the world before the first step (the first step does when the host has not):
    /// the scene file's warnings and the start's; an unintegrable start raises.
    fn check(&mut self) -> PyResult<Vec<String>> {
        self.0.check().map(<[String]>::to_vec).map_err(error)
    }

    /// What loading the scene file did that it does not spell out (notes, not warnings).
    fn notes(&self) -> Vec<String> {
        self.0.notes().to_vec()
    }

    /// Solves the steps on `device` (auto, cpu, gpu) with `threads` CPU threads (0: all
    /// cores); returns the device and why it was chosen.
    #[pyo3(signature = (device = "cpu", threads = 0))]
    fn set_device(&mut self, device: &str, threads: usize) -> PyResult<String> {
        let line = self.0.choose_device(DeviceChoice::from_name(device).map_err(error)?).map_err(error)?;
        self.0.set_threads(threads).map_err(error)?;
        Ok(line)
    }

    /// Advances one step; returns its report as a dict.
    fn step<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let sim = &mut self.0;
        let report = py.detach(|| sim.step()).map_err(error)?;
        json_dict(py, &report)
    }

    /// Packing fraction, coordination, neighbours, rattlers, the mean stress and fabric tensors (a dict).
    fn measures<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        json_dict(py, &self.0.measures())
    }

    /// The moving grains by height, layers `thickness` high (default: one mean diameter): a list
    /// of dicts, one a layer, bottom first.
    #[pyo3(signature = (thickness = None))]
    fn height_profile<'py>(&self, py: Python<'py>, thickness: Option<f64>) -> PyResult<Bound<'py, PyAny>> {
        let thickness = thickness.unwrap_or_else(|| self.0.world.mean_diameter());
        if !(thickness.is_finite() && thickness > 0.0) {
            return Err(error(format!("thickness {thickness} must be finite and > 0")));
        }
        let json = serde_json::to_string(&self.0.height_profile(thickness)).map_err(error)?;
        py.import("json")?.call_method1("loads", (json,))
    }

    #[getter]
    fn time(&self) -> f64 {
        self.0.time()
    }

    #[getter]
    fn steps_done(&self) -> usize {
        self.0.steps_done()
    }

    #[getter]
    fn body_count(&self) -> usize {
        self.0.body_count()
    }

    /// The index of the material called `name`.
    fn material(&self, name: &str) -> PyResult<usize> {
        self.0.material(name).map_err(error)
    }

    /// Centres (2N float64, x then y per body).
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let v: Vec<f64> = self.0.positions().iter().flat_map(|p| p.to_array()).collect();
        to_bytes(py, &v)
    }

    fn velocities<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let v: Vec<f64> = self.0.velocities().iter().flat_map(|p| p.to_array()).collect();
        to_bytes(py, &v)
    }

    fn angles<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let v: Vec<f64> = (0..self.0.body_count()).map(|k| self.0.angle(k)).collect();
        to_bytes(py, &v)
    }

    fn spins<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let v: Vec<f64> = (0..self.0.body_count()).map(|k| self.0.spin(k)).collect();
        to_bytes(py, &v)
    }

    /// The last step's contacts: a dict of bytes (body, other: int64; other_is_wall: uint8;
    /// point, normal, impulse: 2 float64 each; gap: float64; status: uint32).
    fn contacts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.0.contacts();
        let body: Vec<i64> = c.iter().map(|c| c.contact.i as i64).collect();
        let (other, wall): (Vec<i64>, Vec<u8>) = c
            .iter()
            .map(|c| match c.contact.other {
                Antagonist::Body(j) => (j as i64, 0),
                Antagonist::Wall(w) => (w as i64, 1),
            })
            .unzip();
        let pairs = |f: &dyn Fn(&moreau::ContactState) -> [f64; 2]| -> Vec<f64> { c.iter().flat_map(f).collect() };
        let d = PyDict::new(py);
        d.set_item("body", to_bytes(py, &body))?;
        d.set_item("other", to_bytes(py, &other))?;
        d.set_item("other_is_wall", to_bytes(py, &wall))?;
        d.set_item("point", to_bytes(py, &pairs(&|c| c.contact.point.to_array())))?;
        d.set_item("normal", to_bytes(py, &pairs(&|c| c.contact.normal.to_array())))?;
        d.set_item("impulse", to_bytes(py, &pairs(&|c| c.impulse)))?;
        d.set_item("gap", to_bytes(py, &c.iter().map(|c| c.contact.gap).collect::<Vec<f64>>()))?;
        d.set_item("status", to_bytes(py, &c.iter().map(|c| c.status.code()).collect::<Vec<u32>>()))?;
        Ok(d)
    }

    /// The last step's mean load on each wall (`wall_loads`) or body (`body_loads`): a dict of
    /// bytes (force: 2 float64, moment about the centre: float64).
    fn wall_loads<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        loads_dict(py, &self.0.wall_loads())
    }

    fn body_loads<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        loads_dict(py, &self.0.body_loads())
    }

    /// Every wall's frame and motion: a dict of bytes (center, velocity: 2 float64; angle, spin:
    /// float64).
    fn walls<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let w = &self.0.world.walls;
        let d = PyDict::new(py);
        d.set_item("center", to_bytes(py, &w.iter().flat_map(|w| w.center.to_array()).collect::<Vec<f64>>()))?;
        d.set_item("angle", to_bytes(py, &w.iter().map(|w| w.angle).collect::<Vec<f64>>()))?;
        d.set_item("velocity", to_bytes(py, &w.iter().flat_map(|w| w.velocity.to_array()).collect::<Vec<f64>>()))?;
        d.set_item("spin", to_bytes(py, &w.iter().map(|w| w.spin).collect::<Vec<f64>>()))?;
        Ok(d)
    }

    /// A wall's velocity and spin from the next step on (the effect moving_walls).
    #[pyo3(signature = (wall, velocity, spin = 0.0))]
    fn set_wall_motion(&mut self, wall: usize, velocity: (f64, f64), spin: f64) -> PyResult<()> {
        self.0.set_wall_motion(wall, vec2(velocity), spin).map_err(error)
    }

    fn set_velocity(&mut self, body: usize, velocity: (f64, f64)) -> PyResult<()> {
        self.0.set_velocity(body, vec2(velocity)).map_err(error)
    }

    fn set_spin(&mut self, body: usize, spin: f64) -> PyResult<()> {
        self.0.set_spin(body, spin).map_err(error)
    }

    /// An impulse (N·s) at the world point `at`, applied at once.
    fn apply_impulse(&mut self, body: usize, impulse: (f64, f64), at: (f64, f64)) -> PyResult<()> {
        self.0.apply_impulse(body, vec2(impulse), vec2(at)).map_err(error)
    }

    /// A force (N) and torque (N·m) during the next step only.
    #[pyo3(signature = (body, force, torque = 0.0))]
    fn apply_force(&mut self, body: usize, force: (f64, f64), torque: f64) -> PyResult<()> {
        self.0.apply_force(body, vec2(force), torque).map_err(error)
    }

    /// Adds a disk between steps, checked as `World.add_disk`'s; returns its index.
    #[pyo3(signature = (center, radius, material, velocity = (0.0, 0.0), spin = 0.0, fixed = false, tag = 0, *, force = (0.0, 0.0), lock_rotation = false, mass = None, hold_velocity = Vec::new()))]
    #[allow(clippy::too_many_arguments)]
    fn add_disk(
        &mut self,
        center: (f64, f64),
        radius: f64,
        material: &str,
        velocity: (f64, f64),
        spin: f64,
        fixed: bool,
        tag: u32,
        force: (f64, f64),
        lock_rotation: bool,
        mass: Option<f64>,
        hold_velocity: Vec<String>,
    ) -> PyResult<usize> {
        let drive = Drive { force, lock_rotation, mass, hold_velocity };
        let shape = BodySpec::disk(vec2(center), radius, 0);
        let spec = body_spec(&self.0.world, shape, material, 0.0, velocity, spin, fixed, tag, drive)?;
        self.0.add_body(&spec).map_err(error)
    }

    /// Adds a polygon between steps (vertices relative to `center`; convex or concave), checked as
    /// `World.add_polygon`'s; returns its index.
    #[pyo3(signature = (center, vertices, material, angle = 0.0, velocity = (0.0, 0.0), spin = 0.0, fixed = false, tag = 0, *, force = (0.0, 0.0), lock_rotation = false, mass = None, hold_velocity = Vec::new()))]
    #[allow(clippy::too_many_arguments)]
    fn add_polygon(
        &mut self,
        center: (f64, f64),
        vertices: Vec<(f64, f64)>,
        material: &str,
        angle: f64,
        velocity: (f64, f64),
        spin: f64,
        fixed: bool,
        tag: u32,
        force: (f64, f64),
        lock_rotation: bool,
        mass: Option<f64>,
        hold_velocity: Vec<String>,
    ) -> PyResult<usize> {
        let drive = Drive { force, lock_rotation, mass, hold_velocity };
        let shape = BodySpec::polygon(vec2(center), vertices.into_iter().map(vec2).collect(), 0);
        let spec = body_spec(&self.0.world, shape, material, angle, velocity, spin, fixed, tag, drive)?;
        self.0.add_body(&spec).map_err(error)
    }

    /// Adds a clump between steps (disks `(x, y, r)` relative to `center`); the keywords are
    /// `World.add_clump`'s; returns its index.
    #[pyo3(signature = (center, disks, material, angle = 0.0, velocity = (0.0, 0.0), spin = 0.0, fixed = false, tag = 0, *, force = (0.0, 0.0), lock_rotation = false, mass = None, hold_velocity = Vec::new()))]
    #[allow(clippy::too_many_arguments)]
    fn add_clump(
        &mut self,
        center: (f64, f64),
        disks: Vec<(f64, f64, f64)>,
        material: &str,
        angle: f64,
        velocity: (f64, f64),
        spin: f64,
        fixed: bool,
        tag: u32,
        force: (f64, f64),
        lock_rotation: bool,
        mass: Option<f64>,
        hold_velocity: Vec<String>,
    ) -> PyResult<usize> {
        let drive = Drive { force, lock_rotation, mass, hold_velocity };
        let spec = body_spec(&self.0.world, clump(center, disks), material, angle, velocity, spin, fixed, tag, drive)?;
        self.0.add_body(&spec).map_err(error)
    }

    /// Removes a body; the bodies after it move down one index.
    fn remove_body(&mut self, body: usize) -> PyResult<()> {
        self.0.remove_body(body).map_err(error)
    }

    /// Writes the state between steps (bodies, walls, time, last step's impulses and colours) as
    /// a checkpoint file (JSON); with `scene`, stamped with that scene file's fingerprint, as
    /// `moreau run` does, so that the command line can go on from it.
    #[pyo3(signature = (path, scene = None))]
    fn write_checkpoint(&self, path: PathBuf, scene: Option<PathBuf>) -> PyResult<()> {
        moreau::io::checkpoint::save(&self.0, &path, scene.as_deref()).map_err(error)
    }

    /// Goes back to a checkpoint: the steps after it are those the first run took (same solver,
    /// threads and device). With `scene`, the checkpoint must come from that scene file.
    #[pyo3(signature = (path, scene = None))]
    fn restore(&mut self, path: PathBuf, scene: Option<PathBuf>) -> PyResult<()> {
        let c = moreau::io::checkpoint::load(&path, scene.as_deref()).map_err(error)?;
        self.0.restore(&c).map_err(error)
    }

    /// Keep each step's contact problem, for `last_problem`.
    fn keep_problems(&mut self, keep: bool) {
        self.0.keep_problems(keep)
    }

    /// The last step's contact problem (matrix-free), when `keep_problems(True)` was called.
    fn last_problem(&self) -> Option<Problem> {
        self.0.last_problem().cloned().map(Problem)
    }
}

#[pymodule]
fn _moreau(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("MoreauError", m.py().get_type::<MoreauError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Problem>()?;
    m.add_class::<World>()?;
    m.add_class::<Simulation>()?;
    m.add_function(wrap_pyfunction!(read_problem, m)?)?;
    m.add_function(wrap_pyfunction!(deposit_problem, m)?)?;
    m.add_function(wrap_pyfunction!(solve, m)?)?;
    Ok(())
}
