//! Each solver on the 7,002-contact Siconos problem: time per iteration and time to error 1e-6.
//! `cargo bench --bench solvers` (needs shared/ beside the repository).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use moreau::io::siconos::read_fc2d;
use moreau::problem::generate::lattice_packing;
use moreau::solvers::Ordering;
use moreau::{solve, SolverKind, SolverOptions};
use std::path::PathBuf;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/siconos-fc2d/fc2d_granularflowonwall_07002_00801.dat");
    let Ok(problem) = read_fc2d(&path) else {
        eprintln!("skipping: {} not readable", path.display());
        return;
    };
    let mut per_iter = c.benchmark_group("7002_contacts/10_iterations");
    per_iter.sample_size(10).measurement_time(Duration::from_secs(3));
    for kind in SolverKind::ALL {
        // tol = 0 is never reached: exactly 10 iterations.
        let opts = SolverOptions { tol: f64::MIN_POSITIVE, max_iter: 10, ..Default::default() };
        per_iter.bench_with_input(BenchmarkId::from_parameter(kind), &kind, |b, &k| {
            b.iter(|| solve(&problem, k, &opts, None))
        });
    }
    per_iter.finish();

    let mut to_tol = c.benchmark_group("7002_contacts/to_1e-6");
    to_tol.sample_size(10).measurement_time(Duration::from_secs(10));
    // LATIN and APGD do not reach 1e-6 on this file within 20,000 iterations (see the solve tests).
    for (kind, ordering) in [
        (SolverKind::Nlgs, Ordering::Forward),
        (SolverKind::Nlgs, Ordering::Symmetric),
        (SolverKind::Pcpg, Ordering::Forward),
        (SolverKind::Cpg, Ordering::Forward),
        (SolverKind::Jacobi, Ordering::Forward),
    ] {
        let opts = SolverOptions { tol: 1e-6, max_iter: 20_000, ordering, ..Default::default() };
        let id = if kind == SolverKind::Nlgs { format!("{kind}_{ordering:?}") } else { kind.to_string() };
        to_tol.bench_with_input(BenchmarkId::from_parameter(id), &kind, |b, &k| {
            b.iter(|| solve(&problem, k, &opts, None))
        });
    }
    to_tol.finish();

    // Matrix-free product at growing sizes (W never assembled).
    let mut product = c.benchmark_group("matrix_free_w_product");
    for side in [32usize, 100, 316] {
        let p = lattice_packing(side, side, 0.5, 1);
        let x = vec![1.0; 2 * p.n_contacts()];
        let mut y = vec![0.0; x.len()];
        product.bench_with_input(BenchmarkId::from_parameter(p.n_contacts()), &side, |b, _| {
            b.iter(|| p.w.apply(&x, &mut y))
        });
    }
    product.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
