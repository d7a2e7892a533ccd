//! What `moreau run` writes into its output directory: `steps.csv` (one row per step),
//! `summary.json`, VTK files with their `.pvd` series, PNG pictures, dumped problems.

use std::fs::File;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Serialize;

use crate::solvers::{StopCriterion, StopReason};
use crate::stepping::{Measures, Simulation, StepReport};

/// One row of `steps.csv`.
#[derive(Serialize)]
struct Row {
    step: usize,
    time: f64,
    contacts: usize,
    warm_started: usize,
    iterations: usize,
    gpu_iterations: usize,
    error: f64,
    converged: bool,
    stop: &'static str,
    gpu_dispatches: u64,
    gpu_bytes: u64,
    missed: usize,
    projected: usize,
    max_penetration: f64,
    kinetic_energy: f64,
    potential_energy: f64,
    dissipated_energy: f64,
    boundary_work: f64,
    packing_fraction: f64,
    coordination: f64,
    rattlers: usize,
    neighbours: f64,
    stress_xx: f64,
    stress_yy: f64,
    stress_xy: f64,
    fabric_xx: f64,
    fabric_yy: f64,
    fabric_xy: f64,
    anisotropy: f64,
    seconds: f64,
    detection_seconds: f64,
    solve_seconds: f64,
    projection_seconds: f64,
    gpu_estimates: usize,
    gpu_judged: usize,
    gpu_judge_seconds: f64,
    gpu_discarded: usize,
    gpu_rounds: usize,
    velocity_scale: f64,
}

/// One row of `walls.csv`: a wall's position and the grains' mean force and moment on it.
#[derive(Serialize)]
struct WallRow {
    step: usize,
    time: f64,
    wall: usize,
    x: f64,
    y: f64,
    angle: f64,
    fx: f64,
    fy: f64,
    moment: f64,
}

/// One row of `profile.csv`: a layer of the height profile at a step.
#[derive(Serialize)]
struct ProfileRow {
    step: usize,
    time: f64,
    y_low: f64,
    y_high: f64,
    grains: usize,
    solid_fraction: f64,
    vx: f64,
    vy: f64,
    spin: f64,
    velocity_fluctuation: f64,
}

/// One row of `driven.csv`: a body driven by a constant force (a piston), its motion, the force
/// imposed on it and the contacts' mean force on it.
#[derive(Serialize)]
struct DrivenRow {
    step: usize,
    time: f64,
    body: usize,
    x: f64,
    y: f64,
    vx: f64,
    vy: f64,
    imposed_fx: f64,
    imposed_fy: f64,
    contact_fx: f64,
    contact_fy: f64,
}

/// Totals over a run, written as `summary.json`.
#[derive(Serialize, Debug, Clone, Default)]
pub struct RunSummary {
    /// The scene's name.
    pub scene: String,
    /// `cpu`, or `gpu (adapter)`.
    pub device: String,
    /// CPU threads of the run (detection, and solves on the CPU).
    pub threads: usize,
    /// The solver of every step.
    pub solver: String,
    /// Its tolerance.
    pub tol: f64,
    /// What judged convergence (`natural`, `velocity`, LMGC90's tests).
    pub criterion: String,
    /// The effects on.
    pub effects: Vec<String>,
    /// Bodies at the start.
    pub bodies: usize,
    /// Steps run.
    pub steps: usize,
    /// Time in the steps (s).
    pub seconds: f64,
    /// Steps per second in the steps.
    pub steps_per_second: f64,
    /// Time writing after each step (s): steps.csv with its measures, VTK, checkpoints, the
    /// picture. With the steps, the run's wall time but for loading the scene.
    pub output_seconds: f64,
    /// Time in the solves (s).
    pub solve_seconds: f64,
    /// Time in detection (s).
    pub detection_seconds: f64,
    /// Time in the position projection (s).
    pub projection_seconds: f64,
    /// Steps whose solve met the tolerance.
    pub converged_steps: usize,
    /// Steps whose solve did not.
    pub unconverged_steps: usize,
    /// The largest error of any step.
    pub max_error: f64,
    /// The largest of the steps' `velocity_scale` (m/s): under either velocity test, the loosest
    /// bound a contact was held to is `tol` times it.
    pub max_velocity_scale: f64,
    /// Iterations (NLGS: sweeps) per step: mean, median, 95th percentile, largest.
    pub mean_iterations: f64,
    /// See `mean_iterations`.
    pub median_iterations: usize,
    /// See `mean_iterations`.
    pub p95_iterations: usize,
    /// See `mean_iterations`.
    pub max_iterations: usize,
    /// Steps whose solve ran to max_iter.
    pub max_iter_steps: usize,
    /// Iterations run on a GPU over all steps (the rest of a GPU run's: f64 finishes on the CPU).
    pub gpu_iterations: usize,
    /// Every step's iterations, for the percentiles.
    #[serde(skip)]
    pub iterations: Vec<usize>,
    /// Mean contacts per step.
    pub mean_contacts: f64,
    /// Contacts of the last step.
    pub last_contacts: usize,
    /// Largest overlap over the run, absolute and relative to the mean grain diameter.
    pub max_penetration: f64,
    /// See `max_penetration`.
    pub max_penetration_per_diameter: f64,
    /// Kinetic energy at the end (J).
    pub final_kinetic_energy: f64,
    /// Energy the contacts dissipated over the run, and the work moving walls and driven bodies
    /// did on the grains through them (J; each step's in steps.csv).
    pub dissipated_energy: f64,
    /// See `dissipated_energy`.
    pub boundary_work: f64,
    /// Simulated time at the end (s).
    pub final_time: f64,
    /// Contacts found overlapping at the end of a step that its start missed (grains kicked
    /// beyond their reach), and steps whose positions the projection corrected.
    pub missed_contacts: usize,
    /// See `missed_contacts`.
    pub projected_steps: usize,
    /// Why the run stopped before its last step (the outputs hold the steps before).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
}

impl RunSummary {
    /// Counts one step.
    pub fn add(&mut self, r: &StepReport) {
        self.steps += 1;
        self.seconds += r.seconds;
        self.solve_seconds += r.solve_seconds;
        self.detection_seconds += r.detection_seconds;
        self.projection_seconds += r.projection_seconds;
        if r.converged {
            self.converged_steps += 1;
        } else {
            self.unconverged_steps += 1;
        }
        self.max_error = self.max_error.max(r.error);
        self.max_velocity_scale = self.max_velocity_scale.max(r.velocity_scale);
        self.mean_iterations += (r.iterations as f64 - self.mean_iterations) / self.steps as f64;
        self.max_iterations = self.max_iterations.max(r.iterations);
        self.iterations.push(r.iterations);
        self.gpu_iterations += r.gpu_iterations;
        if r.stop == StopReason::MaxIter {
            self.max_iter_steps += 1;
        }
        self.mean_contacts += (r.contacts as f64 - self.mean_contacts) / self.steps as f64;
        self.last_contacts = r.contacts;
        self.max_penetration = self.max_penetration.max(r.max_penetration);
        self.final_kinetic_energy = r.kinetic_energy;
        self.dissipated_energy += r.dissipated_energy;
        self.boundary_work += r.boundary_work;
        self.missed_contacts += r.missed;
        self.projected_steps += usize::from(r.projected > 0);
        self.final_time = r.time;
        self.steps_per_second = self.steps as f64 / self.seconds.max(1e-12);
    }

    /// Sets the percentiles of the iterations per step (once the run is over).
    pub fn close(&mut self) {
        let mut sorted = self.iterations.clone();
        sorted.sort_unstable();
        let rank = |f: f64| match sorted.len() {
            0 => 0,
            n => sorted[((f * n as f64).ceil() as usize).clamp(1, n) - 1],
        };
        (self.median_iterations, self.p95_iterations) = (rank(0.5), rank(0.95));
    }

    /// Whether the velocity test judged the steps (their bound is `tol × max_velocity_scale`).
    pub fn under_velocity_test(&self) -> bool {
        self.criterion == StopCriterion::Velocity.name()
    }

    /// One line for the end of a run.
    pub fn line(&self) -> String {
        let total: usize = self.iterations.iter().sum();
        format!(
            "{}: {} steps in {:.3} s ({:.1} steps/s; solve {:.0} %, projection {:.0} %) and {:.3} s of outputs, device {} ({} threads), {} tol {:.0e}: {}/{} steps converged (max error {:.2e}{}), iterations mean {:.1} median {} p95 {} max {} ({} at max_iter{}), contacts mean {:.0}, max penetration {:.2e} of the mean diameter, final kinetic energy {:.3e}",
            self.scene,
            self.steps,
            self.seconds,
            self.steps_per_second,
            100.0 * self.solve_seconds / self.seconds.max(1e-12),
            100.0 * self.projection_seconds / self.seconds.max(1e-12),
            self.output_seconds,
            self.device,
            self.threads,
            self.solver,
            self.tol,
            self.converged_steps,
            self.steps,
            self.max_error,
            match self.criterion.as_str() {
                _ if self.under_velocity_test() => format!("; each contact held to tol × up to {:.3} m/s", self.max_velocity_scale),
                c if c == StopCriterion::StepVelocity.name() => format!(
                    "; each contact held to tol × {:.3e} m/s, one step of the applied acceleration (g h)",
                    self.max_velocity_scale
                ),
                _ => String::new(),
            },
            self.mean_iterations,
            self.median_iterations,
            self.p95_iterations,
            self.max_iterations,
            self.max_iter_steps,
            match self.gpu_iterations {
                0 => String::new(),
                gpu if gpu == total => "; all on the GPU".to_string(),
                gpu => format!("; {:.0} % on the GPU, the rest f64 finishes on the CPU", 100.0 * gpu as f64 / total as f64),
            },
            self.mean_contacts,
            self.max_penetration_per_diameter,
            self.final_kinetic_energy
        )
    }
}

/// The files of a run: steps.csv, walls.csv, driven.csv, VTK series, summary.json.
pub struct RunOutput {
    /// The output folder.
    pub dir: PathBuf,
    csv: csv::Writer<File>,
    walls_csv: Option<csv::Writer<File>>,
    driven_csv: Option<csv::Writer<File>>,
    profile_csv: Option<csv::Writer<File>>,
    grains: Vec<(f64, PathBuf)>,
    contacts: Vec<(f64, PathBuf)>,
    walls: Vec<(f64, PathBuf)>,
}

impl RunOutput {
    /// Creates `dir` and removes what an earlier run wrote there (only files named as `moreau
    /// run` names them), so that no stale VTK file or picture sits beside the new ones; returns
    /// how many were removed with the writer.
    pub fn create(dir: &Path) -> Result<(Self, usize)> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let removed = clear_earlier_run(dir)?;
        let path = dir.join("steps.csv");
        let csv = csv::Writer::from_path(&path).with_context(|| format!("creating {}", path.display()))?;
        let out = Self {
            dir: dir.to_path_buf(),
            csv,
            walls_csv: None,
            driven_csv: None,
            profile_csv: None,
            grains: Vec::new(),
            contacts: Vec::new(),
            walls: Vec::new(),
        };
        Ok((out, removed))
    }

    /// Rows of walls.csv for the step just taken: each wall's position and load.
    pub fn record_walls(&mut self, sim: &Simulation) -> Result<()> {
        let csv = writer(&mut self.walls_csv, &self.dir.join("walls.csv"))?;
        for (w, (wall, load)) in sim.world.walls.iter().zip(sim.wall_loads()).enumerate() {
            csv.serialize(WallRow {
                step: sim.steps_done(),
                time: sim.time(),
                wall: w,
                x: wall.center.x,
                y: wall.center.y,
                angle: wall.angle,
                fx: load.force[0],
                fy: load.force[1],
                moment: load.moment,
            })?;
        }
        Ok(())
    }

    /// Rows of driven.csv for the step just taken: each body driven by a force (none: no file).
    pub fn record_driven(&mut self, sim: &Simulation) -> Result<()> {
        let b = &sim.world.bodies;
        if b.driven().next().is_none() {
            return Ok(());
        }
        let csv = writer(&mut self.driven_csv, &self.dir.join("driven.csv"))?;
        for k in b.driven() {
            let load = sim.body_load(k);
            csv.serialize(DrivenRow {
                step: sim.steps_done(),
                time: sim.time(),
                body: k,
                x: b.position[k].x,
                y: b.position[k].y,
                vx: b.velocity[k].x,
                vy: b.velocity[k].y,
                imposed_fx: b.force[k].x,
                imposed_fy: b.force[k].y,
                contact_fx: load.force[0],
                contact_fy: load.force[1],
            })?;
        }
        Ok(())
    }

    /// Rows of profile.csv for the step just taken: the moving grains by height, in layers one
    /// mean diameter thick.
    pub fn record_profile(&mut self, sim: &Simulation) -> Result<()> {
        let csv = writer(&mut self.profile_csv, &self.dir.join("profile.csv"))?;
        for l in sim.height_profile(sim.world.mean_diameter()) {
            csv.serialize(ProfileRow {
                step: sim.steps_done(),
                time: sim.time(),
                y_low: l.y_low,
                y_high: l.y_high,
                grains: l.grains,
                solid_fraction: l.solid_fraction,
                vx: l.vx,
                vy: l.vy,
                spin: l.spin,
                velocity_fluctuation: l.velocity_fluctuation,
            })?;
        }
        Ok(())
    }

    /// One row of steps.csv: the step's report and the measures of the state it left.
    pub fn record(&mut self, r: &StepReport, m: &Measures) -> Result<()> {
        self.csv.serialize(Row {
            step: r.step,
            time: r.time,
            contacts: r.contacts,
            warm_started: r.warm_started,
            iterations: r.iterations,
            gpu_iterations: r.gpu_iterations,
            error: r.error,
            converged: r.converged,
            stop: r.stop.name(),
            gpu_dispatches: r.gpu_dispatches,
            gpu_bytes: r.gpu_bytes,
            missed: r.missed,
            projected: r.projected,
            max_penetration: r.max_penetration,
            kinetic_energy: r.kinetic_energy,
            potential_energy: r.potential_energy,
            dissipated_energy: r.dissipated_energy,
            boundary_work: r.boundary_work,
            packing_fraction: m.packing_fraction,
            coordination: m.coordination,
            neighbours: m.neighbours,
            rattlers: m.rattlers,
            stress_xx: m.stress_xx,
            stress_yy: m.stress_yy,
            stress_xy: m.stress_xy,
            fabric_xx: m.fabric_xx,
            fabric_yy: m.fabric_yy,
            fabric_xy: m.fabric_xy,
            anisotropy: m.anisotropy,
            seconds: r.seconds,
            detection_seconds: r.detection_seconds,
            solve_seconds: r.solve_seconds,
            projection_seconds: r.projection_seconds,
            gpu_estimates: r.gpu_checks.estimates,
            gpu_judged: r.gpu_checks.judged,
            gpu_judge_seconds: r.gpu_checks.judge_seconds,
            gpu_discarded: r.gpu_checks.discarded,
            gpu_rounds: r.gpu_checks.rounds,
            velocity_scale: r.velocity_scale,
        })?;
        Ok(())
    }

    /// VTK files of the current state, added to the `.pvd` series.
    pub fn vtk(&mut self, sim: &Simulation) -> Result<()> {
        let [g, c, w] = super::vtk::write_step(sim, &self.dir, sim.steps_done())?;
        let t = sim.time();
        self.grains.push((t, g));
        self.contacts.push((t, c));
        self.walls.push((t, w));
        super::vtk::write_pvd(&self.dir.join("grains.pvd"), &self.grains)?;
        super::vtk::write_pvd(&self.dir.join("contacts.pvd"), &self.contacts)?;
        super::vtk::write_pvd(&self.dir.join("walls.pvd"), &self.walls)
    }

    /// Flushes the CSV files, closes the VTK series and writes `summary`.
    pub fn finish(mut self, summary: &RunSummary) -> Result<()> {
        self.csv.flush()?;
        for w in [&mut self.walls_csv, &mut self.driven_csv, &mut self.profile_csv].into_iter().flatten() {
            w.flush()?;
        }
        let path = self.dir.join("summary.json");
        std::fs::write(&path, serde_json::to_string_pretty(summary)?)
            .with_context(|| format!("writing {}", path.display()))
    }
}

/// The CSV writer `slot` holds, created at `path` on first use.
fn writer<'a>(slot: &'a mut Option<csv::Writer<File>>, path: &Path) -> Result<&'a mut csv::Writer<File>> {
    if slot.is_none() {
        *slot = Some(csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?);
    }
    Ok(slot.as_mut().expect("created above"))
}

/// Is `name` a file that `moreau run` (or `moreau picture`) writes?
fn is_run_output(name: &str) -> bool {
    let numbered = |prefix: &str, ext: &str| {
        name.strip_prefix(prefix)
            .and_then(|rest| rest.strip_suffix(ext))
            .is_some_and(|digits| !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()))
    };
    matches!(
        name,
        "steps.csv"
            | "walls.csv"
            | "driven.csv"
            | "profile.csv"
            | "summary.json"
            | "grains.pvd"
            | "contacts.pvd"
            | "walls.pvd"
            | "run.gif"
    ) || numbered("grains_", ".vtu")
        || numbered("contacts_", ".vtu")
        || numbered("walls_", ".vtu")
        || numbered("state_", ".png")
        || numbered("problem_", ".dat")
        || numbered("checkpoint_", ".json")
        || [".csv", ".png", ".svg"].iter().any(|ext| numbered("force_pdf_", ext))
}

fn clear_earlier_run(dir: &Path) -> Result<usize> {
    let mut removed = 0;
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let entry = entry?;
        if entry.file_type()?.is_file() && entry.file_name().to_str().is_some_and(is_run_output) {
            std::fs::remove_file(entry.path()).with_context(|| format!("removing {}", entry.path().display()))?;
            removed += 1;
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    #[test]
    fn only_files_named_as_a_run_names_them_are_cleared() {
        for name in [
            "steps.csv",
            "grains_000010.vtu",
            "state_000300.png",
            "problem_000001.dat",
            "walls.pvd",
            "checkpoint_000020.json",
        ] {
            assert!(super::is_run_output(name), "{name}");
        }
        for name in ["notes.txt", "grains_.vtu", "grains_12a.vtu", "my_steps.csv", "state_1.png.bak"] {
            assert!(!super::is_run_output(name), "{name}");
        }
    }
}
