//! `moreau run SCENE`: simulate a scene file and write its outputs.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};

use super::punch::{run_punch, PunchOverrides};
use super::{choose_backend_for_scene, set_threads, DeviceChoice};
use crate::io::checkpoint::{fingerprint, read_checkpoint, write_checkpoint};
use crate::io::run_output::{RunOutput, RunSummary};
use crate::io::siconos::{write_fc2d, Storage};
use crate::scene;
use crate::solvers::SolverKind;
use crate::stepping::Simulation;

#[derive(clap::Args)]
pub struct RunArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Number of steps (default: the scene's; after --restart, those left to the scene's last).
    #[arg(long)]
    steps: Option<usize>,
    /// Go on from a checkpoint of this scene file (`[output] checkpoint_every`): the steps
    /// after it are those the first run would have taken (same solver, threads and device).
    #[arg(long)]
    restart: Option<PathBuf>,
    /// Solver of every step (default: the scene's).
    #[arg(long, value_enum)]
    solver: Option<SolverKind>,
    /// Time step in seconds (default: the scene's; the scene's number of steps is kept). After
    /// --restart at another step, the checkpoint's impulses are scaled to it.
    #[arg(long)]
    time_step: Option<f64>,
    /// Solver tolerance (default: the scene's).
    #[arg(long)]
    tol: Option<f64>,
    #[arg(long)]
    max_iter: Option<usize>,
    /// Stopping test of every solve (default: the scene's, else natural).
    #[arg(long, value_enum)]
    criterion: Option<crate::solvers::StopCriterion>,
    /// NLGS: Anderson acceleration over this many past sweeps (default: the scene's; 0: off).
    #[arg(long)]
    anderson: Option<usize>,
    /// NLGS: focused sweeps after each full sweep, over the contacts around its largest changes
    /// (default: the scene's; 0: off).
    #[arg(long)]
    focus: Option<usize>,
    /// GPU NLGS: sweep blocks of contacts this many times per dispatch instead of a dispatch per
    /// colour and sweep (default: the scene's; 0: colour sweeps; at most 64).
    #[arg(long)]
    block_sweeps: Option<usize>,
    /// NLGS contact ordering (default: the scene's, else forward; `colours` sweeps colour by
    /// colour as the GPU does).
    #[arg(long, value_enum)]
    ordering: Option<crate::solvers::Ordering>,
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    device: DeviceChoice,
    /// Output directory (default: out/<scene name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write VTK files every N steps, and at the last (default: the scene's; 0 = never).
    #[arg(long)]
    vtk_every: Option<usize>,
    /// Step whose PNG picture is written (default: the scene's, else the last step).
    #[arg(long)]
    picture_step: Option<usize>,
    /// Write the contact problem of this step as a Siconos fc2d file (repeatable).
    #[arg(long)]
    dump_problem: Vec<usize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// CPU threads for detection and solves (0: all cores; 1: the sequential reference path).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Exit non-zero (after writing the outputs) when any step misses its tolerance.
    #[arg(long)]
    strict: bool,
    /// Write the last step's grains as a grains CSV file (`x,y,r,vx,vy,spin,tag,material,fixed`), which a
    /// scene's `[[grains]] file` starts from: a deposit settled once, studied many times.
    #[arg(long)]
    save_grains: Option<PathBuf>,
    /// Stop after the first step that leaves the grains at rest: their root-mean-square speed
    /// (m/s, from their kinetic energy, rotation included) at most this. The steps bound the run;
    /// the last outputs (VTK, picture, --save-grains) are those of the step at rest.
    #[arg(long)]
    until_rest: Option<f64>,
}

/// Non-converged steps reported one by one; the rest are counted in the summary and steps.csv.
const WARNINGS_SHOWN: usize = 5;

pub fn run_command(a: RunArgs) -> Result<()> {
    let mut scene = match scene::load_any(&a.scene)? {
        scene::AnyScene::Granular(s) => *s,
        scene::AnyScene::Punch(p) => {
            if let Some(flag) = [(a.time_step.is_some(), "--time-step"), (a.until_rest.is_some(), "--until-rest")]
                .into_iter()
                .find_map(|(given, flag)| given.then_some(flag))
            {
                bail!("{flag}: {} is a punch scene, a static problem without time steps", a.scene.display());
            }
            let overrides = PunchOverrides {
                solver: a.solver,
                tol: a.tol,
                max_iter: a.max_iter,
                device: a.device,
                out: a.out.clone(),
            };
            return run_punch(*p, overrides);
        }
    };
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    for n in &scene.notes {
        eprintln!("note: {n}");
    }
    let restart = a.restart.as_ref().map(|path| read_checkpoint(path, &a.scene)).transpose()?;
    let start = restart.as_ref().map_or(0, |c| c.steps_done);
    let steps = match a.steps {
        Some(0) => bail!("--steps must be at least 1"),
        Some(s) => s,
        None if start < scene.steps => scene.steps - start,
        None => bail!("the checkpoint is at step {start}, the scene's last: give --steps to go further"),
    };
    let last = start + steps;
    if let Some(speed) = a.until_rest.filter(|v| !(v.is_finite() && *v > 0.0)) {
        bail!("--until-rest {speed}: a speed in m/s, finite and > 0");
    }
    if let (Some(path), Some(why)) = (&a.save_grains, crate::io::grains::unsavable(&scene.world)) {
        bail!("--save-grains {}: {why}", path.display());
    }
    apply_overrides(&mut scene, &a)?;
    set_threads(a.threads)?;
    let (vtk_every, picture_step) = output_steps(&a, &scene, start, last)?;
    let first = start + 1;
    let cpu_only = crate::backend::cpu_only(&scene.world);
    let bodies = scene.world.bodies.len();
    let backend = choose_backend_for_scene(a.device, scene.settings.solver, &scene.settings.options, cpu_only, bodies)?;
    let default_dir = match start {
        0 => scene.name.clone(),
        k => format!("{}_from_{k}", scene.name),
    };
    let out_dir = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(default_dir));
    // Only checkpoints need the scene file's fingerprint.
    let fingerprint = match scene.output.checkpoint_every {
        0 => String::new(),
        _ => fingerprint(&std::fs::read(&a.scene).with_context(|| format!("reading {}", a.scene.display()))?),
    };
    let mut summary = RunSummary {
        scene: scene.name.clone(),
        device: match backend.adapter_name() {
            None => "cpu".into(),
            Some(adapter) => format!("gpu ({adapter})"),
        },
        threads: rayon::current_num_threads(),
        solver: scene.settings.solver.name().to_string(),
        tol: scene.settings.options.tol,
        criterion: scene.settings.options.criterion.name().to_string(),
        effects: scene.world.effects.names().iter().map(|s| s.to_string()).collect(),
        bodies: scene.world.bodies.len(),
        ..RunSummary::default()
    };
    let diameter = scene.world.mean_diameter();
    let gravity_step = scene.world.effects.gravity_step(scene.settings.h);
    eprintln!(
        "{}: {} bodies, {} walls, effects [{}], h = {:e}, {} steps, solver {} tol {:.0e}",
        scene.name,
        scene.world.bodies.len(),
        scene.world.walls.len(),
        summary.effects.join(", "),
        scene.settings.h,
        steps,
        summary.solver,
        summary.tol
    );
    let mut per_step = PerStep {
        dump_problem: a.dump_problem.clone(),
        wall_forces: scene.output.wall_forces,
        profile_every: if scene.output.profile { scene.output.every } else { 0 },
        checkpoint_every: scene.output.checkpoint_every,
        scene_name: scene.name.clone(),
        fingerprint,
        vtk_every,
        last,
        picture_step,
    };
    let mut sim = Simulation::new(scene.world, scene.settings)?;
    sim.set_backend(backend)?;
    if let Some(c) = &restart {
        sim.restore(c)?;
        eprintln!("restarting from step {start} (t = {}) of {}", c.time, a.restart.as_ref().unwrap().display());
    }
    for w in sim.check().with_context(|| format!("checking {}", a.scene.display()))? {
        eprintln!("warning: {w}");
    }
    sim.keep_problems(!per_step.dump_problem.is_empty());
    let (mut output, cleared) = RunOutput::create(&out_dir)?;
    if cleared > 0 {
        eprintln!("removed {cleared} file(s) of an earlier run from {}", out_dir.display());
    }
    let bar = if a.quiet { ProgressBar::hidden() } else { ProgressBar::new(steps as u64) };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} steps {per_sec} {msg} [{elapsed_precise} < {eta}]")
            .expect("valid progress template"),
    );
    bar.enable_steady_tick(Duration::from_millis(500));
    if per_step.vtk_every > 0 {
        output.vtk(&sim)?; // the start (step 0, or the checkpoint's step)
    }
    for _ in 0..steps {
        let report = match sim.step() {
            Ok(report) => report,
            Err(e) => {
                // Keep what was written, and the last good state, for the user to inspect.
                bar.finish_and_clear();
                summary.close();
                summary.failure = Some(e.to_string());
                output.vtk(&sim)?;
                output.finish(&summary)?;
                let kept = match sim.steps_done() {
                    k if k == start => "the initial state (VTK)".to_string(),
                    k => format!("the outputs of steps {first} to {k} and the state after step {k} (VTK)"),
                };
                bail!("{}: {e}\n{kept} are in {}", a.scene.display(), out_dir.display());
            }
        };
        let speed = a.until_rest.map(|_| sim.world.bodies.rms_speed()).unwrap_or(f64::INFINITY);
        let at_rest = a.until_rest.is_some_and(|v| speed <= v);
        if at_rest {
            // This step is the run's last: its VTK, profile and (unless another was asked) picture.
            if per_step.picture_step == per_step.last {
                per_step.picture_step = report.step;
            }
            per_step.last = report.step;
        }
        per_step.write(&sim, &report, &mut output, &mut summary, &bar)?;
        if at_rest {
            bar.suspend(|| eprintln!("at rest after step {}: the grains' rms speed is {speed:.3e} m/s", report.step));
            break;
        }
        if let (Some(v), true) = (a.until_rest, report.step == last) {
            bar.suspend(|| {
                eprintln!(
                    "warning: not at rest after step {last}: the grains' rms speed is {speed:.3e} m/s, above {v:e}"
                )
            });
        }
    }
    bar.finish_and_clear();
    if let Some(path) = &a.save_grains {
        crate::io::grains::write_grains(&sim.world, path).map_err(|e| anyhow::anyhow!("--save-grains: {e}"))?;
        eprintln!("grains of step {} in {}", sim.steps_done(), path.display());
    }
    finish_run(summary, output, &out_dir, (diameter, gravity_step), a.strict)
}

/// The scene's solver settings as the command line overrides them.
fn apply_overrides(scene: &mut scene::Scene, a: &RunArgs) -> Result<()> {
    if let Some(s) = a.solver {
        scene.settings.solver = s;
    }
    if let Some(h) = a.time_step {
        if !(h.is_finite() && h > 0.0) {
            bail!("--time-step {h}: must be finite and > 0");
        }
        scene.settings.h = h;
    }
    if let Some(t) = a.tol {
        if !(t.is_finite() && t > 0.0) {
            bail!("--tol {t}: must be finite and > 0");
        }
        scene.settings.options.tol = t;
    }
    if let Some(c) = a.criterion {
        scene.settings.options.criterion = c;
    }
    if let Some(m) = a.max_iter {
        if m == 0 {
            bail!("--max-iter must be at least 1");
        }
        scene.settings.options.max_iter = m;
    }
    if let Some(m) = a.anderson {
        scene.settings.options.anderson = m;
    }
    if let Some(k) = a.focus {
        scene.settings.options.focus = k;
    }
    if let Some(o) = a.ordering {
        scene.settings.options.ordering = o;
    }
    if let Some(k) = a.block_sweeps {
        scene.settings.options.block_sweeps = k;
    }
    scene.settings.options.validate()?;
    Ok(())
}

/// What is written after each step: its rows, a problem dump, a checkpoint, VTK, the picture.
struct PerStep {
    dump_problem: Vec<usize>,
    wall_forces: bool,
    /// Write profile.csv every this many steps (0: never) and at the last.
    profile_every: usize,
    checkpoint_every: usize,
    scene_name: String,
    /// The scene file's fingerprint (checkpoints only).
    fingerprint: String,
    vtk_every: usize,
    last: usize,
    picture_step: usize,
}

impl PerStep {
    fn write(
        &self,
        sim: &Simulation,
        report: &crate::stepping::StepReport,
        output: &mut RunOutput,
        summary: &mut RunSummary,
        bar: &ProgressBar,
    ) -> Result<()> {
        let start = Instant::now();
        output.record(report, &sim.measures())?;
        output.record_driven(sim)?;
        if self.wall_forces {
            output.record_walls(sim)?;
        }
        summary.add(report);
        if !report.converged && summary.unconverged_steps <= WARNINGS_SHOWN {
            bar.suspend(|| {
                eprintln!(
                    "warning: step {}: {} did not converge ({}; error {:.2e}){}",
                    report.step,
                    summary.solver,
                    report.stop_reason,
                    report.error,
                    if summary.unconverged_steps == WARNINGS_SHOWN { "; further ones are only counted" } else { "" }
                )
            });
        }
        bar.set_message(format!("{} contacts, {} its, err {:.1e}", report.contacts, report.iterations, report.error));
        bar.inc(1);
        if self.dump_problem.contains(&report.step) {
            let path = output.dir.join(format!("problem_{:06}.dat", report.step));
            match sim.last_problem() {
                Some(p) => {
                    write_fc2d(p, Storage::Sparse, &path)?;
                    bar.suspend(|| eprintln!("wrote {} ({} contacts)", path.display(), p.n_contacts()));
                }
                None => bar.suspend(|| eprintln!("warning: step {} has no contact: no problem to dump", report.step)),
            }
        }
        if self.checkpoint_every > 0 && report.step.is_multiple_of(self.checkpoint_every) {
            let mut c = sim.checkpoint();
            (c.scene, c.scene_fingerprint) = (self.scene_name.clone(), self.fingerprint.clone());
            write_checkpoint(&c, &output.dir.join(format!("checkpoint_{:06}.json", report.step)))?;
        }
        if self.vtk_every > 0 && (report.step.is_multiple_of(self.vtk_every) || report.step == self.last) {
            output.vtk(sim)?;
        }
        if self.profile_every > 0 && (report.step.is_multiple_of(self.profile_every) || report.step == self.last) {
            output.record_profile(sim)?;
        }
        if report.step == self.picture_step {
            let path = output.dir.join(format!("state_{:06}.png", report.step));
            let frame = crate::io::picture::Frame::of(sim);
            crate::io::picture::write_png(&frame, crate::io::picture::Colouring::Tag, 1200, &path)?;
        }
        summary.output_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }
}

/// Which steps write VTK (every how many; 0: none) and which is pictured, checked against the
/// run's steps `start + 1 ..= last` (problem dumps too).
fn output_steps(a: &RunArgs, scene: &scene::Scene, start: usize, last: usize) -> Result<(usize, usize)> {
    let vtk_every = match (a.vtk_every, scene.output.vtk) {
        (Some(n), _) => n,
        (None, true) => scene.output.every,
        (None, false) => 0,
    };
    let first = start + 1;
    if !a.dump_problem.is_empty() && scene.world.effects.rolling_resistance {
        bail!("--dump-problem: the scene has rolling resistance (3 unknowns per contact); the fc2d format holds 2");
    }
    if let Some(&late) = a.dump_problem.iter().find(|&&k| k < first || k > last) {
        bail!("--dump-problem {late}: the run has steps {first} to {last}");
    }
    let picture_step = match (a.picture_step, scene.output.picture_step) {
        (Some(k), _) if k < first || k > last => bail!("--picture-step {k}: the run has steps {first} to {last}"),
        (Some(k), _) => k,
        (None, Some(k)) if k > last || k < first => {
            eprintln!("warning: the scene's picture_step {k} is outside steps {first} to {last}: the picture is of step {last}");
            last
        }
        (None, k) => k.unwrap_or(last),
    };
    Ok((vtk_every, picture_step))
}

/// How many steps of gravity (g h) the velocity test's scale may reach before the run warns
/// that a few fast grains loosened every contact's bound.
const LOOSE_VELOCITY_SCALE: f64 = 10.0;

/// Closes the summary, says how the run went and writes the last files; `strict` makes missed
/// tolerances an error. With the mean grain diameter and the velocity a step of gravity gives
/// (0 without gravity).
fn finish_run(
    mut summary: RunSummary,
    output: RunOutput,
    out_dir: &std::path::Path,
    (diameter, gravity_step): (f64, f64),
    strict: bool,
) -> Result<()> {
    summary.close();
    summary.max_penetration_per_diameter = if diameter > 0.0 { summary.max_penetration / diameter } else { 0.0 };
    println!("{}", summary.line());
    let scale = summary.max_velocity_scale;
    if summary.under_velocity_test() && gravity_step > 0.0 && scale > LOOSE_VELOCITY_SCALE * gravity_step {
        eprintln!(
            "warning: the velocity test held contacts to tol × up to {scale:.3} m/s, {:.0}× a step of gravity \
             (g h = {gravity_step:.2e} m/s): a few fast grains loosen every contact's bound, and a resting pile \
             can creep (velocity_scale in steps.csv; BENCHMARKS.md, \"The velocity test's scale follows the \
             fastest grain\"); criterion = step-velocity holds every contact to tol × g h instead",
            scale / gravity_step
        );
    }
    if summary.unconverged_steps > 0 {
        eprintln!(
            "warning: {} of {} steps did not reach tol {:.0e} (see {}/steps.csv)",
            summary.unconverged_steps,
            summary.steps,
            summary.tol,
            out_dir.display()
        );
    }
    output.finish(&summary)?;
    eprintln!("outputs in {}", out_dir.display());
    if strict && summary.unconverged_steps > 0 {
        bail!("--strict: {} of {} steps missed tol {:.0e}", summary.unconverged_steps, summary.steps, summary.tol);
    }
    Ok(())
}
