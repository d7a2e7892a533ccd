//! The `moreau` command line.

mod bench;
mod punch;
mod run;
mod sweep;

use crate::backend::Backend;
use crate::io::report::{answer_velocity_error, summary_line, SolveOutput};
use crate::io::siconos::{read_fc2d, write_fc2d, Storage};
use crate::problem::generate;
use crate::solvers::{self, LatinK, NewtonLinear, Ordering, SolverKind, SolverOptions, StopCriterion};
use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "moreau", version, about = "2D granular contact dynamics (NSCD) on CPU and GPU")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

pub use crate::backend::DeviceChoice;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum StorageChoice {
    Auto,
    Dense,
    Sparse,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum GeneratedProblem {
    /// A column of light disks under one heavy disk (mass ratio).
    HeavyColumn,
    /// A square lattice of disks in a box (redundant contacts, random masses and velocities).
    Lattice,
    /// A few random contacts among a few disks.
    Random,
    /// The first step of disks deposited in a 20 cm box, loaded by gravity from rest (`--n` disks;
    /// 2,000 at `--mu 0.3 --seed 7` is scenes/deposit_2k.toml's): hard for every solver when μ > 0.
    Deposit,
}

#[derive(clap::Args)]
struct SolveArgs {
    /// Problem file (Siconos fc2d format).
    file: PathBuf,
    /// Default: interior-point at tolerances of 1e-6 and below (unless --device gpu), nlgs above.
    #[arg(long, value_enum)]
    solver: Option<SolverKind>,
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    device: DeviceChoice,
    /// Tolerance on the natural-map error (or LMGC90's criterion when --criterion says so).
    #[arg(long, default_value_t = 1e-8)]
    tol: f64,
    #[arg(long, default_value_t = 10_000)]
    max_iter: usize,
    #[arg(long, value_enum, default_value_t = StopCriterion::Natural)]
    criterion: StopCriterion,
    /// NLGS relaxation ω.
    #[arg(long, default_value_t = 1.0)]
    omega: f64,
    /// NLGS contact ordering.
    #[arg(long, value_enum, default_value_t = Ordering::Forward)]
    ordering: Ordering,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// NLGS: Anderson acceleration over this many past sweeps (0: off; 5 is a good start).
    #[arg(long, default_value_t = 0)]
    anderson: usize,
    /// Projected Jacobi relaxation.
    #[arg(long, default_value_t = SolverOptions::default().jacobi_omega)]
    jacobi_omega: f64,
    /// LATIN search direction, as a multiple of diag(W), or `auto`: without friction
    /// √(λ_min λ_max) of the scaled W on the contacts expected closed (a few Lanczos
    /// products), with friction 1.
    #[arg(long, default_value = "auto")]
    latin_k: LatinK,
    /// Newton: its linear systems by GMRES on W products, or by a sparse LU of J (direct).
    #[arg(long, value_enum, default_value_t = NewtonLinear::Gmres)]
    newton_linear: NewtonLinear,
    /// LATIN: one k for all, `--latin-k` times the mean of diag(W).
    #[arg(long)]
    latin_k_mean: bool,
    /// APGD iterations between Tresca threshold updates.
    #[arg(long, default_value_t = SolverOptions::default().apgd_threshold_every)]
    apgd_threshold_every: usize,
    /// Record the error every N iterations (0: only at checks).
    #[arg(long, default_value_t = 0)]
    history_every: usize,
    /// Write the result as JSON here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// CPU threads (0: all cores; 1: the sequential reference path).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Exit non-zero (after writing the outputs) when the solve misses its tolerance.
    #[arg(long)]
    strict: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scene file (TOML) and write steps.csv, summary.json, VTK and PNG outputs.
    Run(run::RunArgs),
    /// Solve one frictional contact problem read from a file.
    Solve(SolveArgs),
    /// The probability density of normal forces over their mean, from a run's
    /// contacts_NNNNNN.vtu: force_pdf_NNNNNN.csv and a log-scale chart beside it.
    Stats {
        contacts: PathBuf,
        #[arg(long, default_value_t = 25)]
        bins: usize,
    },
    /// Redraw a run's saved state (its VTK files): grains coloured by tag, speed or pressure,
    /// force chains, axes, scale bar, time and legend, as PNG; or every saved step as an
    /// animated GIF.
    Picture(PictureArgs),
    /// Check a scene file without running it: errors, then warnings about its start (grains
    /// overlapping, outside or inside walls, a time step too long for the fastest grain).
    Check {
        scene: PathBuf,
        /// Exit non-zero when there is any warning.
        #[arg(long)]
        strict: bool,
    },
    /// CPU vs GPU timings (W product, Jacobi iteration, NLGS sweep) on lattice packings of growing size.
    Bench(bench::BenchArgs),
    /// Work-precision data of every solver × device: CSV, plots, performance profiles, table.
    Sweep(sweep::SweepArgs),
    /// Iterations to tolerance vs the friction coefficient on a scene's first step.
    FrictionStudy(sweep::FrictionArgs),
    /// Write a built-in problem as a Siconos fc2d file.
    Generate {
        #[arg(value_enum)]
        kind: GeneratedProblem,
        #[arg(long)]
        out: PathBuf,
        /// Number of light disks (heavy-column), contacts (random) or disks (deposit).
        #[arg(long, default_value_t = 10)]
        n: usize,
        #[arg(long, default_value_t = 1000.0)]
        mass_ratio: f64,
        #[arg(long, default_value_t = 20)]
        nx: usize,
        #[arg(long, default_value_t = 20)]
        ny: usize,
        #[arg(long, default_value_t = 0.5)]
        mu: f64,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(long, value_enum, default_value_t = StorageChoice::Auto)]
        storage: StorageChoice,
    },
}

/// Runs the command line; the exit code says whether it succeeded.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run(args) => run::run_command(args),
        Command::Solve(args) => solve_command(args),
        Command::Check { scene, strict } => check_command(&scene, strict),
        Command::Stats { contacts, bins } => stats_command(&contacts, bins),
        Command::Picture(args) => picture_command(args),
        Command::Bench(args) => bench::bench_command(args),
        Command::Sweep(args) => sweep::sweep_command(args),
        Command::FrictionStudy(args) => sweep::friction_command(args),
        Command::Generate { kind, out, n, mass_ratio, nx, ny, mu, seed, storage } => {
            if !(mu.is_finite() && mu >= 0.0) {
                bail!("--mu {mu}: the friction coefficient must be finite and >= 0");
            }
            if !(mass_ratio.is_finite() && mass_ratio > 0.0) {
                bail!("--mass-ratio {mass_ratio}: must be finite and > 0");
            }
            if n == 0 || nx == 0 || ny == 0 {
                bail!("--n {n} --nx {nx} --ny {ny}: each must be at least 1");
            }
            // About two contacts per lattice site, and the problem file grows with them.
            const MAX_GENERATED_CONTACTS: usize = 20_000_000;
            let sites = nx.saturating_mul(ny);
            if sites.saturating_mul(2) > MAX_GENERATED_CONTACTS || n > MAX_GENERATED_CONTACTS {
                bail!("--nx {nx} --ny {ny} --n {n}: at most {MAX_GENERATED_CONTACTS} contacts can be generated");
            }
            let problem = match kind {
                GeneratedProblem::HeavyColumn => generate::heavy_column(n, mass_ratio, mu),
                GeneratedProblem::Lattice => generate::lattice_packing(nx, ny, mu, seed),
                GeneratedProblem::Random => generate::random_small(n, mu, seed),
                GeneratedProblem::Deposit => crate::sweep::problems::deposit_problem(n, mu, seed)?,
            };
            let storage = match storage {
                StorageChoice::Dense => Storage::Dense,
                StorageChoice::Sparse => Storage::Sparse,
                StorageChoice::Auto if problem.n_contacts() <= 16 => Storage::Dense,
                StorageChoice::Auto => Storage::Sparse,
            };
            write_fc2d(&problem, storage, &out)?;
            println!("wrote {} ({} contacts)", out.display(), problem.n_contacts());
            Ok(())
        }
    }
}

#[derive(clap::Args)]
struct PictureArgs {
    /// A run's output directory (with grains_NNNNNN.vtu, contacts_… and walls_…).
    dir: PathBuf,
    /// Step to draw (default: the last saved).
    #[arg(long, conflicts_with = "animate")]
    step: Option<usize>,
    /// What colours the grains.
    #[arg(long, default_value = "tag", value_parser = crate::io::picture::Colouring::NAMES)]
    color: String,
    /// Picture width in pixels.
    #[arg(long, default_value_t = 1200)]
    width: u32,
    /// Every saved step as an animated GIF (default file: DIR/run.gif).
    #[arg(long)]
    animate: bool,
    /// Time between the frames of an animation (ms).
    #[arg(long, default_value_t = 100)]
    frame_ms: u32,
    /// Output file (default: DIR/state_NNNNNN.png, or DIR/run.gif).
    #[arg(long)]
    out: Option<PathBuf>,
}

fn picture_command(a: PictureArgs) -> Result<()> {
    use crate::io::picture::{default_path, saved_steps, write_gif, write_png, Colouring, Frame};
    if !(200..=8000).contains(&a.width) {
        bail!("--width {}: must lie in 200..=8000 pixels", a.width);
    }
    let colouring: Colouring = a.color.parse().map_err(|e: String| anyhow::anyhow!(e))?;
    let steps = saved_steps(&a.dir)?;
    if !crate::io::plots::font_available() {
        eprintln!(
            "warning: no TrueType font (install fonts-dejavu-core or set MOREAU_FONT): no axes, legend or labels"
        );
    }
    if a.animate {
        let frames = steps.iter().map(|&s| Frame::read(&a.dir, s)).collect::<Result<Vec<_>>>()?;
        let path = a.out.unwrap_or_else(|| default_path(&a.dir, None));
        write_gif(&frames, colouring, a.width, a.frame_ms, &path)?;
        println!(
            "wrote {} ({} frames, steps {} to {})",
            path.display(),
            frames.len(),
            steps[0],
            steps[steps.len() - 1]
        );
        return Ok(());
    }
    let step = a.step.unwrap_or(steps[steps.len() - 1]);
    if !steps.contains(&step) {
        bail!("--step {step}: {} has VTK files of steps {}", a.dir.display(), list_steps(&steps));
    }
    let frame = Frame::read(&a.dir, step)?;
    let path = a.out.unwrap_or_else(|| default_path(&a.dir, Some(step)));
    write_png(&frame, colouring, a.width, &path)?;
    println!(
        "wrote {} (step {step}, {} grains, {} contacts, coloured by {})",
        path.display(),
        frame.grains.len(),
        frame.chains.len(),
        a.color
    );
    Ok(())
}

/// `0, 50, 100, …, 500` (at most a dozen named).
fn list_steps(steps: &[usize]) -> String {
    let named: Vec<String> = steps.iter().take(12).map(|s| s.to_string()).collect();
    if steps.len() > 12 {
        format!("{}, … {} (of {})", named.join(", "), steps[steps.len() - 1], steps.len())
    } else {
        named.join(", ")
    }
}

fn stats_command(path: &std::path::Path, bins: usize) -> Result<()> {
    if !(1..=10_000).contains(&bins) {
        bail!("--bins {bins}: must lie in 1..=10000");
    }
    let impulses = crate::io::vtk::read_cell_array(path, "normal_impulse")?;
    let (pdf, mean, carried) = crate::stepping::normal_force_pdf(&impulses, bins);
    if carried == 0 {
        bail!("{}: no contact carries a force ({} contacts)", path.display(), impulses.len());
    }
    let above = impulses.iter().filter(|&&f| f > mean).count();
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("contacts");
    let stem = path.with_file_name(format!("force_pdf{}", stem.strip_prefix("contacts").unwrap_or(stem)));
    let mut csv = String::from("force_over_mean,density\n");
    pdf.iter().for_each(|(x, d)| csv.push_str(&format!("{x},{d}\n")));
    let csv_path = stem.with_extension("csv");
    std::fs::write(&csv_path, csv).with_context(|| format!("writing {}", csv_path.display()))?;
    println!(
        "{}: {} contacts, {carried} carry a force; mean normal impulse {mean:.4e}; {:.1} % above the mean",
        path.display(),
        impulses.len(),
        100.0 * above as f64 / carried as f64
    );
    let positive: Vec<(f64, f64)> = pdf.iter().copied().filter(|p| p.1 > 0.0).collect();
    let series = [("P(f / <f>)".to_string(), positive)];
    let chart = crate::io::plots::Chart {
        title: "normal forces",
        x_label: "f / <f>",
        y_label: "probability density",
        log_x: false,
        log_y: true,
        series: &series,
    };
    if crate::io::plots::font_available() {
        crate::io::plots::write_chart(&stem, &chart)?;
        println!("wrote {} and {}.png/.svg", csv_path.display(), stem.display());
    } else {
        println!("wrote {} (no font for the chart)", csv_path.display());
    }
    Ok(())
}

fn check_command(path: &std::path::Path, strict: bool) -> Result<()> {
    let scene = match crate::scene::load_any(path)? {
        crate::scene::AnyScene::Granular(s) => *s,
        crate::scene::AnyScene::Punch(p) => {
            println!("{}: a structural (punch) scene; it loads and is valid", p.name);
            return Ok(());
        }
    };
    let (bodies, walls) = (scene.world.bodies.len(), scene.world.walls.len());
    let (h, steps, name) = (scene.settings.h, scene.steps, scene.name.clone());
    let alert = scene.settings.alert;
    let mut sim = crate::Simulation::from_loaded(scene)?;
    let warnings = sim.check().with_context(|| format!("{}", path.display()))?.to_vec();
    for w in &warnings {
        println!("warning: {w}");
    }
    for n in sim.notes() {
        println!("note: {n}");
    }
    println!(
        "{name}: {bodies} bodies, {walls} walls, h = {h:e}, {steps} steps, alert {alert:.3e}: {}",
        match warnings.len() {
            0 => "no warning".to_string(),
            n => format!("{n} warning(s)"),
        }
    );
    if strict && !warnings.is_empty() {
        bail!("--strict: {} warning(s) about {}", warnings.len(), path.display());
    }
    Ok(())
}

/// Tolerances from which `moreau solve` defaults to the interior point: over the problem set it
/// solves the most problems at 1e-6 and 1e-8 (13 and 12 of 16, the next best 12 and 9) and is the
/// fastest on the largest (BENCHMARKS.md, performance profiles); above, plain NLGS wins on fixed costs.
const TIGHT_TOL: f64 = 1e-6;

/// The solver of `moreau solve` when none is named: the interior point at tight tolerances on
/// the CPU, NLGS otherwise (it alone runs on the GPU).
fn default_solver(tol: f64, device: DeviceChoice) -> SolverKind {
    if tol <= TIGHT_TOL && device != DeviceChoice::Gpu {
        SolverKind::InteriorPoint
    } else {
        SolverKind::Nlgs
    }
}

/// Picks the device for solves of `solver` with `opts` (the backend decides) and says which.
pub(crate) fn choose_backend(choice: DeviceChoice, solver: SolverKind, opts: &SolverOptions) -> Result<Backend> {
    let backend = Backend::choose(choice, solver, opts)?;
    eprintln!("device: {}", backend.describe());
    Ok(backend)
}

/// [`choose_backend`] for the steps of a scene of `bodies` bodies, which only the CPU solves
/// when `cpu_only` says why (`backend::cpu_only`).
pub(crate) fn choose_backend_for_scene(
    choice: DeviceChoice,
    solver: SolverKind,
    opts: &SolverOptions,
    cpu_only: Option<&'static str>,
    bodies: usize,
) -> Result<Backend> {
    let backend = Backend::choose_for_scene(choice, solver, opts, cpu_only, bodies)?;
    eprintln!("device: {}", backend.describe());
    Ok(backend)
}

/// A solver option error worded as the command line's flag (`--max-iter 0: …`).
pub(crate) fn option_error(e: solvers::OptionError) -> anyhow::Error {
    anyhow::anyhow!("--{} {}: {}", e.name.replace('_', "-"), e.value, e.rule)
}

/// Runs the rest of the command on a rayon pool of `threads` threads (0: all cores).
pub(crate) fn set_threads(threads: usize) -> Result<()> {
    crate::parallel::check_thread_count(threads).map_err(|e| anyhow::anyhow!("--{e}"))?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .map_err(|e| anyhow::anyhow!("--threads {threads}: {e}"))
}

fn solve_command(a: SolveArgs) -> Result<()> {
    set_threads(a.threads)?;
    let problem = read_fc2d(&a.file)?;
    let opts = SolverOptions {
        tol: a.tol,
        max_iter: a.max_iter,
        criterion: a.criterion,
        omega: a.omega,
        ordering: a.ordering,
        seed: a.seed,
        anderson: a.anderson,
        jacobi_omega: a.jacobi_omega,
        latin_k: a.latin_k,
        latin_k_mean: a.latin_k_mean,
        newton_linear: a.newton_linear,
        apgd_threshold_every: a.apgd_threshold_every,
        history_every: a.history_every,
        ..Default::default()
    };
    opts.validate().map_err(option_error)?;
    let solver = a.solver.unwrap_or_else(|| {
        let kind = default_solver(a.tol, a.device);
        eprintln!("solver: {kind} (the default at tol {:e}; --solver to choose)", a.tol);
        kind
    });
    let backend = choose_backend(a.device, solver, &opts)?;
    let report = crate::parallel::on_pool(|| backend.solve(&problem, solver, &opts, None))?;
    let adapter = backend.adapter_name();
    let device = backend.name();
    println!("{}", summary_line(&report, device, a.tol));
    for note in &report.notes {
        println!("  {note}");
    }
    // The natural map's scale is ‖r‖ where impulses outweigh velocities (heavy grains): say how
    // far the worst contact is from stopping, in the free velocities' units.
    let velocity_error = answer_velocity_error(&problem, &report);
    if !opts.criterion.is_velocity_test() {
        println!(
            "  worst contact: residual {velocity_error:.3e} of the largest free velocity (the velocity test's measure; --criterion velocity holds every contact to tol)"
        );
    }
    if !report.converged {
        eprintln!("warning: {} did not converge: {}", report.solver, report.stop_reason);
    }
    if let Some(out) = &a.out {
        let name = a.file.display().to_string();
        let mut output = SolveOutput::new(&name, device, &opts, &report, velocity_error);
        output.adapter = adapter.as_deref();
        let json = serde_json::to_string(&output)?;
        std::fs::write(out, json).with_context(|| format!("writing {}", out.display()))?;
    }
    if a.strict && !report.converged {
        bail!(
            "--strict: {} did not reach tol {:e} ({}; error {:.3e})",
            report.solver,
            a.tol,
            report.stop_reason,
            report.judged_error
        );
    }
    Ok(())
}
