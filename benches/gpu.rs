//! CPU vs GPU per W product and per projected-Jacobi iteration on lattice packings of 1k, 10k and
//! 100k contacts (1M with MOREAU_BENCH_1M=1), and NLGS time to error 1e-4 at 1k and 10k. GPU entries need an adapter; on the software
//! adapter they time lavapipe, not a GPU. `moreau bench` prints the same as a table.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use moreau::gpu::{timing::kernel_times, GpuContext};
use moreau::problem::generate::lattice_packing;
use moreau::solvers::jacobi::jacobi_update;

fn gpu_vs_cpu(c: &mut Criterion) {
    let ctx = GpuContext::new().map_err(|e| eprintln!("GPU entries skipped: {e}")).ok();
    if let Some(ctx) = &ctx {
        eprintln!("adapter: {}", ctx.describe());
    }
    let mut sizes = vec![(25usize, 20usize), (100, 50), (316, 158)];
    if std::env::var("MOREAU_BENCH_1M").is_ok_and(|v| v == "1") {
        sizes.push((1000, 500));
    }
    let mut group = c.benchmark_group("gpu_vs_cpu");
    group.sample_size(10);
    for (nx, ny) in sizes {
        let p = lattice_packing(nx, ny, 0.5, 1);
        let nc = p.n_contacts();
        let r: Vec<f64> = (0..2 * nc).map(|k| (k as f64 * 0.37).sin().abs()).collect();
        let mut u = vec![0.0; 2 * nc];
        group.bench_function(format!("w_product/cpu/{nc}"), |b| b.iter(|| p.w.apply(&r, &mut u)));
        let step: Vec<f64> = p.w.diag_blocks().iter().map(|d| 1.0 / (d[0] + d[3])).collect();
        let mut rr = vec![0.0; 2 * nc];
        group.bench_function(format!("jacobi_iteration/cpu/{nc}"), |b| {
            b.iter(|| {
                p.velocity_into(&rr, &mut u);
                jacobi_update(&mut rr, &u, &p.mu, &step);
            })
        });
        // Time to error 1e-4 (cold start), NLGS on both devices: the sizes a sample finishes quickly.
        let to_tol = moreau::SolverOptions { tol: 1e-4, max_iter: 100_000, ..Default::default() };
        if nc <= 20_000 {
            group.bench_function(format!("nlgs_to_1e-4/cpu/{nc}"), |b| {
                b.iter(|| moreau::solve(&p, moreau::SolverKind::Nlgs, &to_tol, None))
            });
            if let Some(ctx) = &ctx {
                group.bench_function(format!("nlgs_to_1e-4/gpu/{nc}"), |b| {
                    b.iter(|| moreau::gpu::solve(ctx, &p, moreau::SolverKind::Nlgs, &to_tol, None).unwrap())
                });
            }
        }
        if let Some(ctx) = &ctx {
            group.bench_function(format!("w_product/gpu/{nc}"), |b| {
                b.iter_custom(|n| {
                    Duration::from_secs_f64(kernel_times(ctx, &p, n.max(1) as usize).unwrap().product * n as f64)
                })
            });
            group.bench_function(format!("jacobi_iteration/gpu/{nc}"), |b| {
                b.iter_custom(|n| {
                    Duration::from_secs_f64(
                        kernel_times(ctx, &p, n.max(1) as usize).unwrap().jacobi_iteration * n as f64,
                    )
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, gpu_vs_cpu);
criterion_main!(benches);
