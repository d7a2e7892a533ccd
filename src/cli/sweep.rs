//! `moreau sweep` (work-precision data, plots, performance profiles, time-to-tolerance table)
//! and `moreau friction-study` (iterations to tolerance vs μ on a scene's first step).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::backend::{Backend, DeviceChoice};
use crate::gpu::GpuContext;
use crate::io::plots::{font_available, write_chart, Chart, Series};
use crate::scene::{self, PunchScene};
use crate::solvers::{solve, SolverKind, SolverOptions};
use crate::structure::study::{PunchProblems, StructuralSolver};
use crate::sweep::problems::{first_step_problem, problems_of};
use crate::sweep::structural::structural_study;
use crate::sweep::{markdown_table, profile::profiles, work_precision, Run};

#[derive(clap::Args)]
pub struct SweepArgs {
    /// A problem file (Siconos fc2d), a directory of them, or a scene (.toml).
    target: PathBuf,
    /// Solvers: nlgs, cpg, pcpg, latin, jacobi, apgd; and dual_cg on a structural scene.
    #[arg(long, value_delimiter = ',', default_values_t = ["nlgs", "pcpg", "cpg", "jacobi", "apgd", "latin"].map(String::from))]
    solvers: Vec<String>,
    /// cpu, gpu or both.
    #[arg(long, value_delimiter = ',', default_values_t = ["cpu".to_string()])]
    devices: Vec<String>,
    #[arg(long, value_delimiter = ',', default_values_t = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8])]
    tols: Vec<f64>,
    #[arg(long, default_value_t = 20_000)]
    max_iter: usize,
    /// Tolerances of the performance profiles (default: the middle of --tols); the first is
    /// written as profile.*, each as profile_<tol>.*.
    #[arg(long, value_delimiter = ',')]
    profile_tol: Vec<f64>,
    /// For a scene: the steps whose problems are swept.
    #[arg(long, value_delimiter = ',', default_values_t = [1usize])]
    scene_steps: Vec<usize>,
    #[arg(long, default_value = "out/sweep")]
    out: PathBuf,
    /// Structural scenes: LATIN's k as these multiples of mean diag(M) and of diag(M).
    #[arg(long, value_delimiter = ',', default_values_t = [1.0 / 64.0, 1.0 / 32.0, 1.0 / 16.0, 0.125, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0])]
    latin_k_factors: Vec<f64>,
}

fn write_csv<T: serde::Serialize>(path: &Path, rows: impl IntoIterator<Item = T>) -> Result<()> {
    let mut w = csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?;
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()?;
    Ok(())
}

#[derive(serde::Serialize)]
struct HistoryRow<'a> {
    problem: &'a str,
    solver: &'a str,
    device: &'a str,
    iteration: usize,
    seconds: f64,
    w_products: usize,
    error: f64,
}

pub fn sweep_command(a: SweepArgs) -> Result<()> {
    if a.tols.is_empty() || a.tols.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
        bail!("--tols must be positive numbers");
    }
    let mut tols = a.tols.clone();
    tols.sort_by(|x, y| y.total_cmp(x));
    for &p in &a.profile_tol {
        let tightest = *tols.last().expect("tols is not empty");
        if !(p.is_finite() && p > 0.0 && p >= tightest) {
            bail!("--profile-tol {p}: must be finite, > 0 and no finer than the finest of --tols ({tightest:e}), or every solver's profile would be empty");
        }
    }
    let devices: Vec<DeviceChoice> = a
        .devices
        .iter()
        .map(|d| match DeviceChoice::from_name(d) {
            Ok(DeviceChoice::Auto) | Err(_) => bail!("--devices: unknown device {d:?} (cpu, gpu)"),
            Ok(choice) => Ok(choice),
        })
        .collect::<Result<_>>()?;
    let solvers: Vec<StructuralSolver> =
        a.solvers.iter().map(|s| StructuralSolver::parse(s).map_err(anyhow::Error::msg)).collect::<Result<_>>()?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    if a.target.extension().is_some_and(|e| e == "toml") {
        if let scene::AnyScene::Punch(p) = scene::load_any(&a.target)? {
            return structural_sweep(&p, &solvers, &devices, &tols, &a);
        }
    }
    let kinds: Vec<SolverKind> = solvers
        .iter()
        .map(|s| match s {
            StructuralSolver::Primal(k) => Ok(*k),
            StructuralSolver::DualCg => bail!("dual_cg solves the dual of a structural problem: give a punch scene"),
        })
        .collect::<Result<_>>()?;
    let gpu = if devices.contains(&DeviceChoice::Gpu) {
        let ctx = GpuContext::new()?;
        eprintln!("gpu: {}", ctx.describe());
        Some(Backend::gpu(ctx))
    } else {
        None
    };
    let cpu = Backend::cpu();
    let backends: Vec<&Backend> = devices
        .iter()
        .map(|d| match (d, &gpu) {
            (DeviceChoice::Gpu, Some(g)) => g,
            _ => &cpu,
        })
        .collect();
    let problems = problems_of(&a.target, &a.scene_steps)?;
    let tightest = *tols.last().unwrap();
    let runs = work_precision(&problems, &kinds, &backends, tightest, a.max_iter, &mut |line| eprintln!("{line}"))?;
    let names: Vec<String> = problems.iter().map(|(n, _)| n.clone()).collect();
    write_sweep_outputs(&a.out, &names, &runs, &tols, &a.profile_tol)?;
    eprintln!("outputs in {}", a.out.display());
    Ok(())
}

/// work_precision.csv, histories.csv, time_to_tol.md, profile.csv and the charts.
fn write_sweep_outputs(
    out: &Path,
    problems: &[String],
    runs: &[Run],
    tols: &[f64],
    profile_tols: &[f64],
) -> Result<()> {
    write_csv(&out.join("work_precision.csv"), runs.iter().flat_map(|r| tols.iter().map(|&t| r.at(t))))?;
    write_csv(
        &out.join("histories.csv"),
        runs.iter().flat_map(|r| {
            r.history.iter().map(|h| HistoryRow {
                problem: &r.problem,
                solver: &r.solver,
                device: r.device,
                iteration: h.iteration,
                seconds: h.seconds,
                w_products: h.w_products,
                error: h.error,
            })
        }),
    )?;
    let table = markdown_table(runs, tols);
    std::fs::write(out.join("time_to_tol.md"), &table)?;
    println!("{table}");
    let profile_tols = if profile_tols.is_empty() { vec![tols[tols.len() / 2]] } else { profile_tols.to_vec() };
    let profiles: Vec<(f64, Vec<Series>)> = profile_tols.iter().map(|&t| (t, profiles(runs, t))).collect();
    // The first profile under its plain name, every one under its tolerance's.
    let stems = |i: usize, tol: f64| {
        let tagged = format!("profile_{tol:.0e}");
        if i == 0 {
            vec!["profile".to_string(), tagged]
        } else {
            vec![tagged]
        }
    };
    for (i, (tol, profile)) in profiles.iter().enumerate() {
        for stem in stems(i, *tol) {
            write_csv(
                &out.join(format!("{stem}.csv")),
                profile.iter().flat_map(|(label, pts)| pts.iter().map(move |(tau, rho)| (label.clone(), *tau, *rho))),
            )?;
        }
    }
    if !font_available() {
        eprintln!("warning: no font for chart text (install fonts-dejavu-core or set MOREAU_FONT): CSV only");
        return Ok(());
    }
    for name in problems {
        let series: Vec<Series> = runs
            .iter()
            .filter(|r| &r.problem == name)
            .map(|r| {
                let pts = r.history.iter().filter(|h| h.seconds > 0.0).map(|h| (h.seconds, h.error)).collect();
                (format!("{} {}", r.solver, r.device), pts)
            })
            .collect();
        let title = format!("{name}: error vs time");
        let stem = out.join(format!("work_precision_{}", name.replace(['/', '@'], "_")));
        write_chart(
            &stem,
            &Chart { title: &title, x_label: "seconds", y_label: "error", log_x: true, log_y: true, series: &series },
        )?;
    }
    for (i, (tol, profile)) in profiles.iter().enumerate() {
        let title = format!("performance profile at tol {tol:.0e} ({} problems)", problems.len());
        for stem in stems(i, *tol) {
            let chart = Chart {
                title: &title,
                x_label: "τ (time / best time)",
                y_label: "fraction solved",
                log_x: true,
                log_y: false,
                series: profile,
            };
            write_chart(&out.join(stem), &chart)?;
        }
    }
    Ok(())
}

#[derive(serde::Serialize)]
struct EnergyRow<'a> {
    problem: &'a str,
    solver: &'a str,
    iteration: usize,
    seconds: f64,
    w_products: usize,
    error: f64,
    energy_error: f64,
}

/// The structural sweep (founding paper, Fig. 17.1): each solver on the condensed punch, its
/// natural-map error against time (work_precision.csv and the common outputs), its energy-norm
/// error against iterations (energy_convergence.csv and chart), and LATIN's k sweep (latin_k.csv
/// and chart).
fn structural_sweep(
    scene: &PunchScene,
    solvers: &[StructuralSolver],
    devices: &[DeviceChoice],
    tols: &[f64],
    a: &SweepArgs,
) -> Result<()> {
    if devices.contains(&DeviceChoice::Gpu) {
        eprintln!("{}: structural problems run on the CPU only; the gpu column is skipped", scene.name);
    }
    let t = std::time::Instant::now();
    let problems = PunchProblems::new(&scene.model)?;
    eprintln!(
        "{}: {} dofs condensed on {} contact dofs in {:.3} s",
        scene.name,
        scene.model.n_dofs(),
        scene.model.n_contacts(),
        t.elapsed().as_secs_f64()
    );
    let tightest = *tols.last().unwrap();
    if let Some(f) = a.latin_k_factors.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
        bail!("--latin-k-factors {f}: each factor must be finite and > 0");
    }
    let opts = SolverOptions { tol: tightest, max_iter: a.max_iter, ..scene.options.clone() };
    let study =
        structural_study(&scene.name, &problems, solvers, &a.latin_k_factors, &opts, &mut |line| eprintln!("{line}"));
    write_csv(&a.out.join("latin_k.csv"), study.latin_k.iter())?;
    for diagonal in [false, true] {
        match study.best_latin_factor(diagonal) {
            Some(b) => eprintln!(
                "LATIN, k = factor × {}: best factor {} ({} its to {tightest:.0e}, {:.4} s)",
                if diagonal { "diag(M)" } else { "mean diag(M)" },
                b.factor,
                b.iterations,
                b.seconds
            ),
            None => eprintln!("LATIN: no factor reached {tightest:.0e}"),
        }
    }
    if let Some((lo, hi)) = problems.extreme_eigenvalues() {
        eprintln!(
            "M / mean diag(M): eigenvalues in [{lo:.3e}, {hi:.3e}]; the augmented-Lagrangian optimum √(λ_min λ_max) = {:.3e}",
            (lo * hi).sqrt()
        );
    }
    let (runs, energy, rows) = (&study.runs, &study.energy, &study.latin_k);
    write_sweep_outputs(&a.out, std::slice::from_ref(&scene.name), runs, tols, &a.profile_tol)?;
    write_csv(
        &a.out.join("energy_convergence.csv"),
        energy.iter().flat_map(|(label, r)| {
            r.points.iter().map(|p| EnergyRow {
                problem: &scene.name,
                solver: label,
                iteration: p.iteration,
                seconds: p.seconds,
                w_products: p.w_products,
                error: p.error,
                energy_error: p.energy_error,
            })
        }),
    )?;
    if font_available() {
        let series: Vec<Series> = energy
            .iter()
            .map(|(label, r)| {
                let pts = r
                    .points
                    .iter()
                    .filter(|p| p.energy_error > 0.0)
                    .map(|p| (p.iteration.max(1) as f64, p.energy_error));
                (label.clone(), pts.collect())
            })
            .collect();
        let title = format!("{}: energy-norm error vs iterations", scene.name);
        write_chart(
            &a.out.join("energy_convergence"),
            &Chart {
                title: &title,
                x_label: "iterations",
                y_label: "‖z − z*‖_M / ‖z*‖_M",
                log_x: true,
                log_y: true,
                series: &series,
            },
        )?;
        let series: Vec<Series> = [false, true]
            .iter()
            .map(|&diagonal| {
                let label = if diagonal { "k = factor · diag(M)" } else { "k = factor · mean diag(M)" };
                let pts = rows
                    .iter()
                    .filter(|r| r.per_contact_diagonal == diagonal)
                    .map(|r| (r.factor, if r.converged { r.iterations as f64 } else { f64::NAN }))
                    .collect();
                (label.to_string(), pts)
            })
            .collect();
        let title = format!("{}: LATIN iterations to {tightest:.0e} vs k", scene.name);
        write_chart(
            &a.out.join("latin_k"),
            &Chart {
                title: &title,
                x_label: "factor",
                y_label: "iterations",
                log_x: true,
                log_y: true,
                series: &series,
            },
        )?;
    }
    eprintln!("outputs in {}", a.out.display());
    Ok(())
}

#[derive(clap::Args)]
pub struct FrictionArgs {
    /// Scene whose first step is solved (the founding paper uses a box compaction).
    scene: PathBuf,
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 0.1, 0.2, 0.3, 0.5, 0.8])]
    mus: Vec<f64>,
    #[arg(long, value_delimiter = ',', default_values_t = [SolverKind::Nlgs, SolverKind::Cpg, SolverKind::Pcpg])]
    solvers: Vec<SolverKind>,
    #[arg(long, default_value_t = 1e-4)]
    tol: f64,
    #[arg(long, default_value_t = 100_000)]
    max_iter: usize,
    #[arg(long, default_value = "out/friction")]
    out: PathBuf,
}

#[derive(serde::Serialize)]
struct FrictionRow {
    mu: f64,
    solver: String,
    contacts: usize,
    converged: bool,
    iterations: usize,
    error: f64,
    seconds: f64,
}

pub fn friction_command(a: FrictionArgs) -> Result<()> {
    if a.mus.iter().any(|m| !(m.is_finite() && *m >= 0.0)) {
        bail!("--mus must be finite and >= 0");
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut rows = Vec::new();
    for &mu in &a.mus {
        let p = first_step_problem(&a.scene, mu)?;
        for &solver in &a.solvers {
            let opts = SolverOptions { tol: a.tol, max_iter: a.max_iter, ..SolverOptions::default() };
            let r = solve(&p, solver, &opts, None);
            eprintln!(
                "μ = {mu}: {} on {} contacts: {} its, error {:.2e}, {:.3} s{}",
                solver.name(),
                p.n_contacts(),
                r.iterations,
                r.error,
                r.seconds,
                if r.converged { "" } else { " (NOT CONVERGED)" }
            );
            rows.push(FrictionRow {
                mu,
                solver: solver.name().into(),
                contacts: p.n_contacts(),
                converged: r.converged,
                iterations: r.iterations,
                error: r.error,
                seconds: r.seconds,
            });
        }
    }
    write_csv(&a.out.join("friction_study.csv"), rows.iter())?;
    let series: Vec<Series> = a
        .solvers
        .iter()
        .map(|s| {
            (
                s.name().to_string(),
                rows.iter().filter(|r| r.solver == s.name()).map(|r| (r.mu, r.iterations as f64)).collect(),
            )
        })
        .collect();
    if font_available() {
        let title = format!("iterations to {:.0e} vs friction, first step of {}", a.tol, a.scene.display());
        write_chart(
            &a.out.join("friction_study"),
            &Chart { title: &title, x_label: "μ", y_label: "iterations", log_x: false, log_y: true, series: &series },
        )?;
    } else {
        eprintln!("warning: no font for chart text (install fonts-dejavu-core or set MOREAU_FONT): CSV only");
    }
    eprintln!("outputs in {}", a.out.display());
    Ok(())
}
