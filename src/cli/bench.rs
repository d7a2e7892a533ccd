//! `moreau bench`: CPU vs GPU on lattice packings of growing size, as a table — time per W
//! product, per projected-Jacobi iteration and per NLGS sweep, and optionally the time to reach a
//! tolerance.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Result};

use crate::backend::Backend;
use crate::gpu::timing::{block_round_time, kernel_times, nlgs_sweep_times};
use crate::gpu::GpuContext;
use crate::problem::generate::lattice_packing;
use crate::problem::ContactProblem;
use crate::solvers::jacobi::jacobi_update;
use crate::solvers::stopping::JudgedMeasure;
use crate::solvers::{solve, SolverKind, SolverOptions};
use crate::stepping::Simulation;

#[derive(clap::Args)]
pub struct BenchArgs {
    /// Approximate contact counts (lattice packings of about that size).
    #[arg(long, value_delimiter = ',', default_values_t = [1_000usize, 10_000, 100_000])]
    sizes: Vec<usize>,
    /// Products (and iterations) per measurement.
    #[arg(long, default_value_t = 50)]
    repeats: usize,
    /// Also solve each problem to this tolerance with Jacobi on both devices (wall time to tol).
    #[arg(long)]
    solve_to: Option<f64>,
    /// Instead of lattices: step this scene on each thread count of --threads-list and time its
    /// steps, its W products and its NLGS sweeps (contact updates per second).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Steps of the scene timed per thread count.
    #[arg(long, default_value_t = 10)]
    steps: usize,
    /// NLGS sweeps timed on the last step's problem.
    #[arg(long, default_value_t = 50)]
    sweeps: usize,
    /// Thread counts compared with --scene (default: 1 and all cores).
    #[arg(long, value_delimiter = ',')]
    threads_list: Vec<usize>,
}

fn lattice_of(contacts: usize) -> (usize, usize) {
    // lattice_packing(nx, ny) has about 2 nx ny contacts; keep it four times wider than tall.
    let ny = ((contacts as f64 / 8.0).sqrt().round() as usize).max(1);
    ((contacts / (2 * ny)).max(1), ny)
}

/// Largest lattice `moreau bench` builds (about 4 GB of operator and vectors).
const MAX_BENCH_CONTACTS: usize = 20_000_000;

pub fn bench_command(a: BenchArgs) -> Result<()> {
    if a.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    if let Some(&big) = a.sizes.iter().find(|&&s| s > MAX_BENCH_CONTACTS || s == 0) {
        bail!("--sizes {big}: each size must lie in 1..={MAX_BENCH_CONTACTS} contacts");
    }
    if let Some(tol) = a.solve_to.filter(|t| !(t.is_finite() && *t > 0.0)) {
        bail!("--solve-to {tol}: the tolerance must be finite and > 0");
    }
    if let Some(scene) = &a.scene {
        return scene_bench(scene, &a);
    }
    let gpu = match GpuContext::new() {
        Ok(ctx) => Some(Backend::gpu(ctx)),
        Err(e) => {
            eprintln!("no GPU column: {e}");
            None
        }
    };
    let ctx = gpu.as_ref().and_then(|g| g.gpu_context());
    let adapter = ctx.map(|c| c.describe()).unwrap_or_else(|| "none".into());
    println!("GPU: {adapter}");
    if ctx.is_some_and(|c| c.is_software()) {
        println!("(a software adapter: its column measures the CPU running lavapipe, not a GPU)");
    }
    println!(
        "| contacts | CPU W product | GPU W product | ratio | CPU Jacobi it | GPU Jacobi it | ratio | CPU NLGS sweep | GPU NLGS sweep (colours) | ratio | contact updates/s, Jacobi: CPU, GPU | NLGS: CPU, GPU |{}",
        if a.solve_to.is_some() { " CPU to tol | GPU to tol |" } else { "" }
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|{}", if a.solve_to.is_some() { "---|---|" } else { "" });
    for &size in &a.sizes {
        let (nx, ny) = lattice_of(size);
        let p = lattice_packing(nx, ny, 0.5, 1);
        let nc = p.n_contacts();
        let r: Vec<f64> = (0..2 * nc).map(|k| (k as f64 * 0.37).sin().abs()).collect();
        let mut u = vec![0.0; 2 * nc];
        let start = Instant::now();
        for _ in 0..a.repeats {
            p.w.apply(&r, &mut u);
        }
        let cpu_product = start.elapsed().as_secs_f64() / a.repeats as f64;
        let step: Vec<f64> = p.w.diag_blocks().iter().map(|d| 1.0 / (d[0] + d[3])).collect();
        let mut rr = vec![0.0; 2 * nc];
        let start = Instant::now();
        for _ in 0..a.repeats {
            p.velocity_into(&rr, &mut u);
            jacobi_update(&mut rr, &u, &p.mu, &step);
        }
        let cpu_iteration = start.elapsed().as_secs_f64() / a.repeats as f64;
        // The solver simulations run: NLGS sweeps (colours or blocks on threads), no check but
        // the last (a tolerance no sweep count reaches); one sweep's solve taken off, with the
        // colouring and the check it shares, as the GPU's kernel times leave them out. Where
        // noise leaves no positive difference, the whole solve per sweep (an upper bound).
        let sweeps = |n: usize| {
            let opts = SolverOptions { tol: 1e-300, max_iter: n, ..SolverOptions::default() };
            solve(&p, SolverKind::Nlgs, &opts, None).seconds
        };
        let (all, one) = (sweeps(a.repeats + 1), sweeps(1));
        let cpu_sweep = if all > one { (all - one) / a.repeats as f64 } else { all / (a.repeats + 1) as f64 };
        let times = match ctx {
            Some(c) => Some((kernel_times(c, &p, a.repeats)?, nlgs_sweep_times(c, &p, a.repeats, 0)?)),
            None => None,
        };
        let fmt = |s: f64| format!("{:.1} µs", s * 1e6);
        let ratio = |cpu: f64, gpu: f64| format!("{:.2}x", cpu / gpu);
        let rate = |seconds: f64| format!("{:.2e}", nc as f64 / seconds);
        let [gp, gi, gs, rp, ri, rs, gu, gsu]: [String; 8] = match &times {
            Some((t, s)) => [
                fmt(t.product),
                fmt(t.jacobi_iteration),
                format!("{} ({})", fmt(s.sweep), s.colours),
                ratio(cpu_product, t.product),
                ratio(cpu_iteration, t.jacobi_iteration),
                ratio(cpu_sweep, s.sweep),
                rate(t.jacobi_iteration),
                rate(s.sweep),
            ],
            None => std::array::from_fn(|_| "–".into()),
        };
        // A contact update: one contact's share of a Jacobi iteration (product, projection) or of
        // an NLGS sweep (its local solve and its bodies' velocities).
        let mut row = format!(
            "| {nc} | {} | {gp} | {rp} | {} | {gi} | {ri} | {} | {gs} | {rs} | {}, {gu} | {}, {gsu} |",
            fmt(cpu_product),
            fmt(cpu_iteration),
            fmt(cpu_sweep),
            rate(cpu_iteration),
            rate(cpu_sweep)
        );
        if let Some(tol) = a.solve_to {
            let opts = SolverOptions { tol, max_iter: 1_000_000, ..SolverOptions::default() };
            let c = solve(&p, SolverKind::Jacobi, &opts, None);
            row.push_str(&format!(
                " {:.3} s ({} its{}) |",
                c.seconds,
                c.iterations,
                if c.converged { "" } else { ", not converged" }
            ));
            match &gpu {
                Some(backend) => {
                    let g = backend.solve(&p, SolverKind::Jacobi, &opts, None)?;
                    row.push_str(&format!(
                        " {:.3} s ({} its{}) |",
                        g.seconds,
                        g.iterations,
                        if g.converged { "" } else { ", not converged" }
                    ));
                }
                None => row.push_str(" – |"),
            }
        }
        println!("{row}");
    }
    Ok(())
}

/// Steps, products and sweeps of a scene on each thread count, side by side in one run.
fn scene_bench(path: &Path, a: &BenchArgs) -> Result<()> {
    if a.steps == 0 || a.sweeps == 0 {
        bail!("--steps and --sweeps must be at least 1");
    }
    let mut threads = a.threads_list.clone();
    if threads.is_empty() {
        threads = vec![1, std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)];
        threads.dedup();
    }
    if let Some(t) = threads.iter().find(|&&t| t == 0 || t > crate::parallel::MAX_THREADS) {
        bail!("--threads-list {t}: each thread count must lie in 1..={}", crate::parallel::MAX_THREADS);
    }
    let mut reference: Option<ContactProblem> = None;
    let mut scene_options: Option<SolverOptions> = None;
    let mut rows = Vec::new();
    for &t in &threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build()?;
        let row = pool.install(|| -> Result<SceneRow> {
            let scene = crate::scene::load(path)?;
            let opts = scene.settings.options.clone();
            scene_options.get_or_insert_with(|| opts.clone());
            let mut sim = Simulation::new(scene.world, scene.settings)?;
            sim.keep_problems(true);
            let (mut step_s, mut detect_s, mut its, mut contacts) = (0.0, 0.0, 0usize, 0usize);
            for _ in 0..a.steps {
                let r = sim.step()?;
                (step_s, detect_s) = (step_s + r.seconds, detect_s + r.detection_seconds);
                (its, contacts) = (its + r.iterations, contacts + r.contacts);
            }
            if reference.is_none() {
                let Some(last) = sim.last_problem() else {
                    bail!("{}: no contacts in its last timed step: time more steps (--steps)", path.display())
                };
                reference = Some(last.clone());
            }
            let p = reference.as_ref().expect("set above");
            let nc = p.n_contacts();
            // Rolling rows add a third unknown per contact.
            let r: Vec<f64> = vec![0.0; p.unknowns()];
            let mut u = vec![0.0; p.unknowns()];
            let start = Instant::now();
            for _ in 0..a.repeats {
                p.w.apply(&r, &mut u);
            }
            let product = start.elapsed().as_secs_f64() / a.repeats as f64;
            // What a threaded or GPU sweep pays once per solve: a fresh colouring of the contact
            // graph, or the repair of last step's when every contact is kept.
            let (mut fresh, mut repair) = (0.0, 0.0);
            if let crate::problem::Delassus::MatrixFree(op) = &p.w {
                use crate::problem::colouring::Colouring;
                let kept: Vec<Option<u32>> = op.colouring().colour_of_each().into_iter().map(Some).collect();
                let new = vec![None; nc];
                let start = Instant::now();
                for _ in 0..a.repeats {
                    std::hint::black_box(Colouring::repaired(op, &new));
                }
                fresh = start.elapsed().as_secs_f64() / a.repeats as f64;
                let start = Instant::now();
                for _ in 0..a.repeats {
                    std::hint::black_box(Colouring::repaired(op, &kept));
                }
                repair = start.elapsed().as_secs_f64() / a.repeats as f64;
            }
            // Fixed sweeps: a tolerance no sweep count reaches, no check but the last.
            let sweep_opts = SolverOptions { tol: 1e-300, max_iter: a.sweeps, ..opts.clone() };
            let sweeps = crate::solvers::solve(p, SolverKind::Nlgs, &sweep_opts, None);
            let sweep = sweeps.seconds / a.sweeps as f64;
            // A full check as a solve's cadence makes it, on the swept impulses: a product, the
            // error and the measure the scene's criterion judges.
            let measure = JudgedMeasure::new(p, opts.criterion);
            let start = Instant::now();
            for _ in 0..a.repeats {
                let (_, error) = p.velocity_and_error(&sweeps.r, &mut u);
                std::hint::black_box(measure.of(p, &sweeps.r, &u, error));
            }
            let check = start.elapsed().as_secs_f64() / a.repeats as f64;
            Ok(SceneRow {
                threads: t,
                contacts: contacts / a.steps,
                step_ms: 1e3 * step_s / a.steps as f64,
                detect_ms: 1e3 * detect_s / a.steps as f64,
                sweeps_per_step: its as f64 / a.steps as f64,
                product_ms: 1e3 * product,
                colouring_ms: [1e3 * fresh, 1e3 * repair],
                sweep_ms: 1e3 * sweep,
                check_ms: 1e3 * check,
                updates_per_s: nc as f64 / sweep,
            })
        })?;
        rows.push(row);
    }
    println!("scene {} ({} steps timed per thread count; products and sweeps on one problem)", path.display(), a.steps);
    println!("| threads | contacts | ms/step | detection ms | sweeps/step | W product ms | colouring ms: fresh, repaired | NLGS sweep ms | full check ms (sweeps) | contact updates/s | sweep speed-up |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let base = rows[0].sweep_ms;
    for r in &rows {
        println!(
            "| {} | {} | {:.1} | {:.2} | {:.1} | {:.3} | {:.3}, {:.3} | {:.3} | {:.3} ({:.2}) | {:.2e} | {:.2}x |",
            r.threads,
            r.contacts,
            r.step_ms,
            r.detect_ms,
            r.sweeps_per_step,
            r.product_ms,
            r.colouring_ms[0],
            r.colouring_ms[1],
            r.sweep_ms,
            r.check_ms,
            r.check_ms / r.sweep_ms,
            r.updates_per_s,
            base / r.sweep_ms
        );
    }
    if let (Some(p), Some(opts)) = (&reference, &scene_options) {
        gpu_scene_rows(p, opts, a)?;
    }
    Ok(())
}

/// On the same problem, a GPU's NLGS sweep alone (kernels, no check) and its NLGS solve at the
/// scene's tolerance from r = 0: the difference per sweep is what the solve's checks cost.
fn gpu_scene_rows(p: &ContactProblem, opts: &SolverOptions, a: &BenchArgs) -> Result<()> {
    if p.has_rolling() {
        println!("no GPU rows: {}", crate::backend::ROLLING_ON_CPU);
        return Ok(());
    }
    let ctx = match GpuContext::new() {
        Ok(ctx) => ctx,
        Err(e) => {
            println!("no GPU rows: {e}");
            return Ok(());
        }
    };
    println!("GPU: {}", ctx.describe());
    if ctx.is_software() {
        println!("(a software adapter: these rows measure the CPU running lavapipe, not a GPU)");
    }
    let depth = opts.anderson.min(crate::gpu::anderson::MAX_DEPTH);
    let times = nlgs_sweep_times(&ctx, p, a.sweeps, depth)?;
    let sweep = times.sweep;
    let backend = Backend::gpu(ctx);
    println!("| Anderson | contacts | NLGS sweep ms (kernels only) | colours | largest colour's dispatch ms | contact updates/s | solve to tol {:.0e}: sweeps, ms per GPU sweep (a work list's: per round) | error estimates, judged in f64 (CPU ms) |", opts.tol);
    println!("|---|---|---|---|---|---|---|---|");
    // The plain sweeps, and the scene's mixing when it has one: what the mixer saves in sweeps
    // and costs per sweep.
    let depths = if opts.anderson > 0 { vec![0, opts.anderson] } else { vec![0] };
    for anderson in depths {
        let opts = SolverOptions { anderson, ..opts.clone() };
        let solved = backend.solve(p, SolverKind::Nlgs, &opts, None)?;
        // A plateau of mixed f32 sweeps hands the rest to plain ones, a plateau in f32 to the
        // CPU: the sweeps of each part, and the time a sweep of the first.
        let c = solved.gpu_checks;
        // The work list's thresholded sweeps count sweeps' worth of updates: time a round.
        let first = solved.parts.first().map_or((solved.iterations, solved.seconds), |g| (g.iterations, g.seconds));
        let rounds = if c.counted { c.rounds } else { first.0 };
        let per_sweep = (rounds > 0).then(|| first.1 / rounds as f64);
        let mut sweeps = match solved.parts.len() {
            0 => solved.iterations.to_string(),
            _ => solved
                .parts
                .iter()
                .enumerate()
                .map(|(i, part)| match (i, part.device.as_str()) {
                    (0, _) => part.iterations.to_string(),
                    (_, "gpu") => format!("{} plain", part.iterations),
                    _ => format!("{} in f64 on the CPU", part.iterations),
                })
                .collect::<Vec<_>>()
                .join(" + "),
        };
        if c.counted {
            sweeps = format!("{sweeps} sweeps' worth in {} rounds", c.rounds);
        }
        println!(
            "| {} | {} | {:.4} | {} | {:.4} | {:.2e} | {}{}, {} | {}, {} ({:.1}) |",
            anderson,
            p.n_contacts(),
            1e3 * sweep,
            times.colours,
            1e3 * times.largest_colour,
            p.n_contacts() as f64 / sweep,
            sweeps,
            if solved.converged { "" } else { " (not converged)" },
            per_sweep.map_or("–".into(), |s| format!("{:.4}", 1e3 * s)),
            c.estimates,
            c.judged,
            1e3 * c.judge_seconds
        );
    }
    if let Some(m) = &times.mixing {
        let [dots, fit, mix, rebuild] = m.stages.map(|t| 1e3 * t);
        println!(
            "Anderson {depth} on the GPU, kernels only (ms a dispatch): dots {dots:.4}, fit {fit:.4}, mix {mix:.4}, velocities' rebuild {rebuild:.4}; a sweep with its mixing {:.4} against {:.4} plain",
            1e3 * m.mixed_sweep,
            1e3 * sweep
        );
    }
    block_sweep_rows(&backend, p, opts, a.sweeps)
}

/// Block sweeps beside the colour sweeps above (matrix-free problems): a round's kernels alone,
/// and the solve to tol, for a few sweeps of each block a dispatch.
fn block_sweep_rows(backend: &Backend, p: &ContactProblem, opts: &SolverOptions, rounds: usize) -> Result<()> {
    let Some(ctx) = backend.gpu_context().filter(|_| matches!(p.w, crate::problem::Delassus::MatrixFree(_))) else {
        return Ok(());
    };
    println!("| block sweeps | dispatches a round | round ms (kernels only) | ms a sweep's worth | solve to tol {:.0e}: rounds, sweeps' worth, ms |", opts.tol);
    println!("|---|---|---|---|---|");
    for inner in [1, 4, 16] {
        let (round, dispatches) = block_round_time(ctx, p, rounds, inner)?;
        let opts = SolverOptions { block_sweeps: inner, anderson: 0, ..opts.clone() };
        let solved = backend.solve(p, SolverKind::Nlgs, &opts, None)?;
        println!(
            "| {inner} | {dispatches} | {:.4} | {:.4} | {}{}, {}, {:.1} |",
            1e3 * round,
            1e3 * round / inner as f64,
            solved.iterations,
            if solved.converged { "" } else { " (not converged)" },
            solved.iterations * inner,
            1e3 * solved.seconds
        );
    }
    Ok(())
}

struct SceneRow {
    threads: usize,
    contacts: usize,
    step_ms: f64,
    detect_ms: f64,
    sweeps_per_step: f64,
    product_ms: f64,
    /// A fresh colouring, and the repair of one whose contacts are all kept.
    colouring_ms: [f64; 2],
    sweep_ms: f64,
    /// A full check: a product, the error and the judged measure.
    check_ms: f64,
    updates_per_s: f64,
}
