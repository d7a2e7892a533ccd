//! `moreau bench`: CPU vs GPU on lattice packings of growing size, as a table — time per W
//! product and per projected-Jacobi iteration, and optionally the time to reach a tolerance.

use std::time::Instant;

use anyhow::{bail, Result};

use crate::backend::Backend;
use crate::gpu::{timing::kernel_times, GpuContext};
use crate::problem::generate::lattice_packing;
use crate::solvers::jacobi::jacobi_update;
use crate::solvers::{solve, SolverKind, SolverOptions};

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
}

fn lattice_of(contacts: usize) -> (usize, usize) {
    // lattice_packing(nx, ny) has about 2 nx ny contacts; keep it four times wider than tall.
    let ny = ((contacts as f64 / 8.0).sqrt().round() as usize).max(1);
    ((contacts / (2 * ny)).max(1), ny)
}

pub fn bench_command(a: BenchArgs) -> Result<()> {
    if a.repeats == 0 {
        bail!("--repeats must be at least 1");
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
        "| contacts | CPU W product | GPU W product | ratio | CPU Jacobi it | GPU Jacobi it | ratio |{}",
        if a.solve_to.is_some() { " CPU to tol | GPU to tol |" } else { "" }
    );
    println!("|---|---|---|---|---|---|---|{}", if a.solve_to.is_some() { "---|---|" } else { "" });
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
        let times = match ctx {
            Some(c) => Some(kernel_times(c, &p, a.repeats)?),
            None => None,
        };
        let fmt = |s: f64| format!("{:.1} µs", s * 1e6);
        let (gp, gi, rp, ri) = match &times {
            Some(t) => (
                fmt(t.product),
                fmt(t.jacobi_iteration),
                format!("{:.2}x", cpu_product / t.product),
                format!("{:.2}x", cpu_iteration / t.jacobi_iteration),
            ),
            None => ("–".into(), "–".into(), "–".into(), "–".into()),
        };
        let mut row = format!("| {nc} | {} | {gp} | {rp} | {} | {gi} | {ri} |", fmt(cpu_product), fmt(cpu_iteration));
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
