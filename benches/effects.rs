//! What an effect costs: the same deposited packing (5,000 disks under gravity) with friction
//! and rotation switched on and off. Measures the matrix-free product W r (the operator's own
//! cost), 10 NLGS sweeps on the first step's problem (includes the physics: sticking and
//! sliding contacts take different paths) and one whole step (detection + up to 200 sweeps),
//! and prints the memory of the operator and the bodies.

use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use moreau::problem::Delassus;
use moreau::scene;
use moreau::solvers::{solve, SolverOptions};
use moreau::stepping::Simulation;

fn scene_with(effects: &str) -> String {
    format!(
        r#"
effects = ["gravity"{effects}]
[time]
step = 1e-3
steps = 1
[solver]
tol = 1e-4
max_iter = 200
[contact]
friction = 0.5
[[material]]
name = "grain"
density = 2600.0
[[wall]]
container = {{ min = [0.0, 0.0], max = [0.2, 0.3] }}
[[generate]]
kind = "deposition"
count = 5000
radius = [0.0008, 0.0012]
region = {{ min = [0.0, 0.0], max = [0.2, 0.3] }}
seed = 1
"#
    )
}

fn effects(c: &mut Criterion) {
    let variants = [
        ("friction+rotation", r#", "friction", "rotation""#),
        ("friction", r#", "friction""#),
        ("rotation", r#", "rotation""#),
        ("neither", ""),
    ];
    let mut group = c.benchmark_group("effects");
    group.sample_size(20);
    for (name, fx) in variants {
        let text = scene_with(fx);
        let s = scene::parse(&text, Path::new("effects.toml")).unwrap();
        let body_bytes = s.world.bodies.memory_bytes();
        let mut sim = Simulation::new(s.world.clone(), s.settings.clone()).unwrap();
        sim.keep_problems(true);
        sim.step().unwrap();
        let problem = sim.last_problem().unwrap().clone();
        let Delassus::MatrixFree(op) = &problem.w else { unreachable!() };
        eprintln!(
            "effects/{name}: {} contacts, operator {} B, bodies {} B",
            problem.n_contacts(),
            op.memory_bytes(),
            body_bytes
        );
        let r: Vec<f64> = (0..2 * problem.n_contacts()).map(|k| (k as f64 * 0.37).sin().abs()).collect();
        let mut out = vec![0.0; r.len()];
        group.bench_function(format!("w_product/{name}"), |b| b.iter(|| problem.w.apply(&r, &mut out)));
        let sweeps = SolverOptions { tol: 1e-300, max_iter: 10, ..SolverOptions::default() };
        group.bench_function(format!("nlgs_10_sweeps/{name}"), |b| {
            b.iter(|| solve(&problem, moreau::SolverKind::Nlgs, &sweeps, None))
        });
        group.bench_function(format!("one_step/{name}"), |b| {
            b.iter_batched(
                || Simulation::new(s.world.clone(), s.settings.clone()).unwrap(),
                |mut sim| sim.step().unwrap(),
                criterion::BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, effects);
criterion_main!(benches);
