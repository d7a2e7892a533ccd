//! The scale work: a stopping rule that stops, a device choice users can trust, mixed precision,
//! threads that give the same results run after run, grains from CSV files, one backend for
//! every solver × criterion × device.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

mod common;

use std::path::Path;

use moreau::backend::{gpu_refusal, Backend, DeviceChoice, F32_FLOOR};
use moreau::gpu::GpuContext;
use moreau::problem::generate::lattice_packing;
use moreau::solvers::stopping::{check_work, CHECK_WORK};
use moreau::solvers::{solve, NewtonLinear, Ordering, SolverKind, SolverOptions, StopCriterion, StopReason};
use moreau::stepping::Simulation;
use moreau::ContactProblem;
use rand::{rngs::SmallRng, seq::SliceRandom, SeedableRng};

fn on_threads<T: Send>(n: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap().install(f)
}

/// A warm start as a time step has one: the solution of a neighbouring problem (q shifted by 2 %).
fn warm_started(p: &ContactProblem) -> (ContactProblem, Vec<f64>) {
    let mut near = p.clone();
    near.q.iter_mut().enumerate().for_each(|(k, q)| *q *= 1.0 + 0.02 * ((k as f64) * 0.7).sin());
    let r0 =
        solve(&near, SolverKind::Nlgs, &SolverOptions { tol: 1e-6, max_iter: 2_000, ..Default::default() }, None).r;
    (p.clone(), r0)
}

/// The contact problem of step `steps` of a shipped scene.
fn scene_problem(path: &str, steps: usize) -> ContactProblem {
    let s = moreau::scene::load(Path::new(path)).unwrap();
    let mut sim = Simulation::new(s.world, s.settings).unwrap();
    sim.keep_problems(true);
    for _ in 0..steps {
        sim.step().unwrap();
    }
    sim.last_problem().expect("contacts").clone()
}

#[test]
fn a_warm_started_solve_stops_within_one_check_of_meeting_tol() {
    // A deep pile of heavy grains: the change of r between sweeps stays above tol long after
    // the error has met it, so the light rule alone ran such solves to max_iter.
    let (p, r0) = warm_started(&scene_problem("scenes/pile_10k.toml", 2));
    // A matrix-free problem's natural-map check is one pass: checked every 5 sweeps, not 10.
    let cadence = check_work(&p, StopCriterion::Natural);
    assert_eq!(cadence, moreau::solvers::stopping::ONE_PASS_CHECK_WORK);
    for tol in [1e-4, 1e-5, 1e-6] {
        // Where the error first meets tol, from the error after every sweep.
        let traced = SolverOptions { tol: 1e-14, max_iter: 300, history_every: 1, ..Default::default() };
        let history = solve(&p, SolverKind::Nlgs, &traced, Some(&r0)).history;
        let k = history.iter().find(|h| h.error <= tol).map(|h| h.iteration).expect("NLGS reaches tol");
        let run = solve(&p, SolverKind::Nlgs, &SolverOptions { tol, max_iter: 3000, ..Default::default() }, Some(&r0));
        assert!(run.converged && run.stop == StopReason::Converged, "tol {tol:e}: {}", run.stop_reason);
        assert!(
            run.iterations <= k + cadence,
            "tol {tol:e}: met at sweep {k}, stopped at {} (cadence {cadence})",
            run.iterations
        );
    }
}

#[test]
fn stop_reasons_are_named_the_same_way_everywhere() {
    let p = lattice_packing(10, 5, 0.5, 1);
    let short = solve(&p, SolverKind::Jacobi, &SolverOptions { tol: 1e-12, max_iter: 3, ..Default::default() }, None);
    assert_eq!((short.stop, short.converged), (StopReason::MaxIter, false), "{}", short.stop_reason);
    let done = solve(&p, SolverKind::Cpg, &SolverOptions { tol: 1e-6, ..Default::default() }, None);
    assert_eq!(done.stop, StopReason::Converged, "{}", done.stop_reason);
}

#[test]
fn auto_never_takes_the_software_adapter_nor_a_tolerance_below_the_f32_floor() {
    let opts = SolverOptions { tol: 1e-4, ..Default::default() };
    let auto = Backend::choose(DeviceChoice::Auto, SolverKind::Nlgs, &opts).unwrap();
    match GpuContext::hardware() {
        Err(_) => assert!(!auto.is_gpu(), "no hardware GPU here, yet auto chose {}", auto.describe()),
        Ok(_) => assert!(auto.gpu_context().is_some_and(|c| !c.is_software()), "{}", auto.describe()),
    }
    let tight = SolverOptions { tol: F32_FLOOR / 10.0, ..Default::default() };
    let auto = Backend::choose(DeviceChoice::Auto, SolverKind::Nlgs, &tight).unwrap();
    assert!(!auto.is_gpu(), "tol below the f32 floor must stay on the CPU: {}", auto.describe());
    assert!(auto.describe().contains("f32"), "{}", auto.describe());
    // What the GPU lacks keeps auto on the CPU and makes `gpu` fail by name, before any adapter.
    let latin = Backend::choose(DeviceChoice::Auto, SolverKind::Latin, &opts).unwrap();
    assert!(!latin.is_gpu() && latin.describe().contains("latin"), "{}", latin.describe());
    let e = Backend::choose(DeviceChoice::Gpu, SolverKind::Latin, &opts).err().expect("latin refused on the gpu");
    assert!(e.to_string().contains("no latin solver"), "{e}");
    // A scene too small to gain from a GPU stays on the CPU under `auto`, and says so; a large
    // one is decided as any solve is; `gpu` asked for is never turned down for size.
    let scene = |choice, bodies| Backend::choose_for_scene(choice, SolverKind::Nlgs, &opts, None, bodies).unwrap();
    let small = scene(DeviceChoice::Auto, 400);
    assert!(!small.is_gpu() && small.describe().contains("400 bodies"), "{}", small.describe());
    let large = scene(DeviceChoice::Auto, 10_000);
    assert!(!large.describe().contains("bodies"), "{}", large.describe());
    assert_eq!(large.is_gpu(), GpuContext::hardware().is_ok(), "{}", large.describe());
    if common::gpu_context().is_some() {
        assert!(scene(DeviceChoice::Gpu, 400).is_gpu());
    }
    // What the GPU cannot do at all is said first.
    let latin = Backend::choose_for_scene(DeviceChoice::Auto, SolverKind::Latin, &opts, None, 400).unwrap();
    assert!(latin.describe().contains("latin"), "{}", latin.describe());
}

#[test]
fn mixed_precision_reaches_1e_8_from_the_gpu() {
    let Some(ctx) = common::gpu_context() else { return };
    let backend = Backend::gpu(ctx);
    let p = lattice_packing(16, 8, 0.5, 2);
    for kind in [SolverKind::Nlgs, SolverKind::Pcpg] {
        let opts = SolverOptions { tol: 1e-8, max_iter: 50_000, ..Default::default() };
        let r = backend.solve(&p, kind, &opts, None).unwrap();
        assert!(r.converged && r.error <= 1e-8, "{kind}: {:.2e} ({})", r.error, r.stop_reason);
        let devices: Vec<&str> = r.parts.iter().map(|p| p.device.as_str()).collect();
        assert_eq!(devices, ["gpu", "cpu"], "{kind}: {}", r.stop_reason);
        assert!(r.parts[0].error > 1e-8, "{kind}: the f32 part alone should not reach 1e-8");
        assert_eq!(r.iterations, r.parts[0].iterations + r.parts[1].iterations);
        assert_eq!(r.gpu_iterations(), r.parts[0].iterations, "{kind}: the GPU's part");
    }
    // Anderson acceleration mixes on both devices: the f32 sweeps on the GPU, then the f64 finish
    // on the CPU, each saying so. A history deeper than the GPU's kernels keep is cut and said.
    let opts = SolverOptions { tol: 1e-8, max_iter: 50_000, anderson: 5, ..Default::default() };
    let r = backend.solve(&p, SolverKind::Nlgs, &opts, None).unwrap();
    assert!(r.converged && r.error <= 1e-8, "anderson: {:.2e} ({})", r.error, r.stop_reason);
    assert!(r.notes.iter().any(|n| n.starts_with("Anderson acceleration over 5 sweeps (on the GPU)")), "{:?}", r.notes);
    assert!(r.notes.iter().any(|n| n.starts_with("Anderson acceleration over 5 sweeps,")), "{:?}", r.notes);
    let line = Backend::choose(DeviceChoice::Gpu, SolverKind::Nlgs, &opts).unwrap().describe();
    assert!(!line.contains("Anderson"), "{line}");
    let deep = SolverOptions { anderson: 12, ..opts };
    let line = Backend::choose(DeviceChoice::Gpu, SolverKind::Nlgs, &deep).unwrap().describe();
    assert!(line.contains("keeps at most 8 sweeps (anderson = 12)"), "{line}");
}

#[test]
fn every_solver_criterion_and_device_is_refused_up_front_or_solves() {
    let p = lattice_packing(6, 3, 0.5, 4);
    let criteria = [
        StopCriterion::Natural,
        StopCriterion::Quad,
        StopCriterion::Maxm,
        StopCriterion::Qm16,
        StopCriterion::Velocity,
    ];
    let mut backends = vec![Backend::cpu()];
    backends.extend(common::gpu_context().map(Backend::gpu));
    for backend in &backends {
        for kind in SolverKind::ALL {
            for criterion in criteria {
                let opts = SolverOptions { tol: 1e-4, max_iter: 20_000, criterion, ..Default::default() };
                match (backend.check(kind, &opts), gpu_refusal(kind, &opts)) {
                    (Err(e), Some(why)) => {
                        assert!(backend.is_gpu() && e.to_string().contains(&why), "{kind}/{criterion:?}: {e}")
                    }
                    (Ok(()), refusal) => {
                        assert!(!backend.is_gpu() || refusal.is_none(), "{kind}/{criterion:?} not refused on the gpu");
                        let r = backend.solve(&p, kind, &opts, None).unwrap();
                        assert!(r.error.is_finite(), "{kind}/{criterion:?} on {}", backend.name());
                        assert_eq!(r.converged, r.stop == StopReason::Converged, "{kind}: {}", r.stop_reason);
                        // The reported measure is the one that decided, whichever the criterion.
                        if matches!(criterion, StopCriterion::Natural | StopCriterion::Velocity) {
                            let judged = r.judged_error;
                            assert_eq!(r.converged, judged <= opts.tol, "{kind}/{criterion:?}: {judged:e}");
                        }
                    }
                    (Err(e), None) => panic!("{kind}/{criterion:?}: refused for no stated reason: {e}"),
                }
            }
        }
    }
}

#[test]
fn threaded_products_are_the_same_bits_as_the_sequential_ones() {
    let p = lattice_packing(80, 40, 0.5, 5);
    assert!(p.n_contacts() > moreau::parallel::PARALLEL_MIN);
    let r: Vec<f64> = (0..2 * p.n_contacts()).map(|k| ((k as f64) * 0.37).sin().abs()).collect();
    let product = |threads| {
        on_threads(threads, || {
            let mut u = vec![0.0; r.len()];
            p.w.apply(&r, &mut u);
            u
        })
    };
    let (one, two) = (product(1), product(2));
    assert!(one.iter().zip(&two).all(|(a, b)| a.to_bits() == b.to_bits()), "threaded W r differs");
}

#[test]
fn threaded_nlgs_converges_and_is_the_same_on_two_and_four_threads() {
    let p = lattice_packing(80, 40, 0.5, 6);
    let opts = SolverOptions { tol: 1e-6, max_iter: 20_000, ..Default::default() };
    let runs: Vec<_> =
        [1, 2, 4, 2].iter().map(|&t| on_threads(t, || solve(&p, SolverKind::Nlgs, &opts, None))).collect();
    for (t, r) in [1, 2, 4, 2].iter().zip(&runs) {
        assert!(r.converged && r.error <= 1e-6, "{t} threads: {:.2e} {}", r.error, r.stop_reason);
    }
    let bits = |r: &moreau::SolveReport| r.r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&runs[1]), bits(&runs[2]), "two and four threads sweep in the same colour order");
    assert_eq!(bits(&runs[1]), bits(&runs[3]), "two threads, run twice");
}

#[test]
fn the_vector_solvers_update_on_threads_and_give_the_same_bits_on_one_two_and_four() {
    // Jacobi, CPG, PCPG, APGD and LATIN update their vectors in chunks on threads above
    // PARALLEL_MIN contacts; every chunk must do what one thread does. The same problem with
    // `W` matrix-free (steps) and explicit (files: `moreau solve`).
    let free = lattice_packing(80, 40, 0.5, 7);
    assert!(free.n_contacts() > moreau::parallel::PARALLEL_MIN);
    let mut explicit = free.clone();
    explicit.w = moreau::problem::Delassus::Sparse(free.w.to_block_sparse());
    let start = moreau::problem::residual::error_of(&free, &vec![0.0; 2 * free.n_contacts()]).0;
    let opts = SolverOptions { tol: 1e-12, max_iter: 40, ..Default::default() };
    let bits = |r: &moreau::SolveReport| r.r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (p, w) in [(&free, "matrix-free"), (&explicit, "explicit")] {
        for kind in [SolverKind::Jacobi, SolverKind::Cpg, SolverKind::Pcpg, SolverKind::Apgd, SolverKind::Latin] {
            let runs: Vec<_> = [1, 2, 4].iter().map(|&t| on_threads(t, || solve(p, kind, &opts, None))).collect();
            let error = runs[0].error;
            assert!(error < 0.5 * start, "{kind:?}, {w} W: no progress, {error:.2e} from {start:.2e}");
            for (t, run) in [2, 4].iter().zip(&runs[1..]) {
                assert_eq!(run.iterations, runs[0].iterations, "{kind:?}, {w} W, on {t} threads");
                assert_eq!(bits(run), bits(&runs[0]), "{kind:?}, {w} W: {t} threads differ from one");
            }
        }
    }
}

#[test]
fn anderson_mixing_runs_on_threads_and_is_the_same_on_two_and_four() {
    let p = lattice_packing(80, 40, 0.5, 6);
    let opts = SolverOptions { tol: 1e-8, max_iter: 20_000, ..Default::default() };
    let mixed = SolverOptions { anderson: 5, ..opts.clone() };
    let plain = on_threads(2, || solve(&p, SolverKind::Nlgs, &opts, None));
    let runs: Vec<_> =
        [1, 2, 4, 2].iter().map(|&t| on_threads(t, || solve(&p, SolverKind::Nlgs, &mixed, None))).collect();
    for (t, r) in [1, 2, 4, 2].iter().zip(&runs) {
        assert!(r.converged && r.error <= 1e-8, "{t} threads: {:.2e} {}", r.error, r.stop_reason);
        assert!(r.notes.iter().any(|n| n.starts_with("Anderson acceleration over 5 sweeps")), "{:?}", r.notes);
    }
    // The mixing accelerates the threaded (block) sweeps too. Measured: 666 against 10,236 sweeps.
    assert!(5 * runs[1].iterations < plain.iterations, "{} against {} sweeps", runs[1].iterations, plain.iterations);
    let bits = |r: &moreau::SolveReport| r.r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&runs[1]), bits(&runs[2]), "two and four threads mix in the same order");
    assert_eq!(bits(&runs[1]), bits(&runs[3]), "two threads, run twice");
}

#[test]
fn focused_sweeps_meet_tol_and_give_the_same_bits_on_every_run() {
    // A step's warm start where little has changed: a frictionless packing's answer, with the
    // free velocities of 20 of its contacts 1 % off.
    let mut p = lattice_packing(80, 40, 0.0, 6);
    let solved =
        solve(&p, SolverKind::Nlgs, &SolverOptions { tol: 1e-9, max_iter: 50_000, ..Default::default() }, None);
    assert!(solved.converged, "{}", solved.stop_reason);
    p.q.iter_mut().step_by(2).take(20).for_each(|q| *q *= 1.01);
    let r0 = solved.r;
    let focused = SolverOptions { tol: 1e-8, max_iter: 50_000, focus: 19, ..Default::default() };
    let full_sweeps = SolverOptions { focus: 0, ..focused.clone() };
    let plain = on_threads(1, || solve(&p, SolverKind::Nlgs, &full_sweeps, Some(&r0)));
    let runs: Vec<_> =
        [1, 1, 2, 2].iter().map(|&t| on_threads(t, || solve(&p, SolverKind::Nlgs, &focused, Some(&r0)))).collect();
    for (t, r) in [1, 1, 2, 2].iter().zip(&runs) {
        assert!(r.converged && r.error <= 1e-8, "{t} threads: {:.2e} {}", r.error, r.stop_reason);
        // Iterations count sweeps' worth of contact updates. Measured: 1,072 against 4,663.
        assert!(2 * r.iterations < plain.iterations, "{t} threads: {} against {}", r.iterations, plain.iterations);
        // "focused sweeps: N of M full sweeps were followed by …": some were.
        let note = r.notes.iter().find_map(|n| n.strip_prefix("focused sweeps: ")).expect("the focus's note");
        let followed: usize = note.split(' ').next().and_then(|n| n.parse().ok()).expect("a count");
        assert!(followed > 0, "{t} threads: {note}");
    }
    let bits = |r: &moreau::SolveReport| r.r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&runs[0]), bits(&runs[1]), "one thread, run twice");
    assert_eq!(bits(&runs[2]), bits(&runs[3]), "two threads, run twice");
    // A problem with an explicit W has no bodies to focus around: full sweeps, said so.
    let explicit = ContactProblem { w: moreau::problem::Delassus::Sparse(p.w.to_block_sparse()), ..p.clone() };
    let opts = SolverOptions { max_iter: 3, ..focused };
    let r = solve(&explicit, SolverKind::Nlgs, &opts, Some(&r0));
    assert!(r.notes.iter().any(|n| n.starts_with("focused sweeps skipped")), "{:?}", r.notes);
}

/// `p`'s answer under the velocity test at 1e-7: a warm start for the work-list tests.
fn answer_to_1e7(p: &ContactProblem) -> Vec<f64> {
    let opts = SolverOptions {
        tol: 1e-7,
        max_iter: 50_000,
        anderson: 5,
        criterion: StopCriterion::Velocity,
        ..Default::default()
    };
    let solved = solve(p, SolverKind::Nlgs, &opts, None);
    assert!(solved.converged, "{}", solved.stop_reason);
    solved.r
}

/// NLGS on a work list under the velocity test.
fn work_list(tol: f64, max_iter: usize) -> SolverOptions {
    SolverOptions {
        tol,
        max_iter,
        criterion: StopCriterion::Velocity,
        ordering: Ordering::Worklist,
        ..Default::default()
    }
}

#[test]
fn a_work_list_meets_the_velocity_test_in_fewer_updates_and_the_same_bits_on_any_threads() {
    // A step's warm start: the answer of a frictional pile's step (the 400-disk pile's 120th,
    // 595 contacts) for free velocities up to 2 % off.
    let mut p = scene_problem("scenes/pile.toml", 120);
    let r0 = answer_to_1e7(&p);
    p.q.iter_mut().enumerate().for_each(|(k, q)| *q *= 1.0 + 0.02 * ((k as f64) * 0.7).sin());
    let listed = work_list(1e-4, 50_000);
    let full_sweeps = SolverOptions { ordering: Ordering::Forward, ..listed.clone() };
    let plain = on_threads(1, || solve(&p, SolverKind::Nlgs, &full_sweeps, Some(&r0)));
    assert!(plain.converged, "{}", plain.stop_reason);
    let runs: Vec<_> =
        [1, 1, 2, 2].iter().map(|&t| on_threads(t, || solve(&p, SolverKind::Nlgs, &listed, Some(&r0)))).collect();
    let diag = p.w.diag_blocks();
    for (t, r) in [1, 1, 2, 2].iter().zip(&runs) {
        // The velocity test, recomputed here from the returned impulses.
        let u = p.velocity(&r.r);
        let velocity = moreau::problem::residual::velocity_error(&diag, &p.q, &p.mu, &r.r, &u);
        assert!(r.converged && velocity <= 1e-4, "{t} threads: {velocity:.2e} {}", r.stop_reason);
        // Iterations count sweeps' worth of contact updates. Measured: 19 against 1,163.
        assert!(10 * r.iterations < plain.iterations, "{t} threads: {} against {}", r.iterations, plain.iterations);
        assert!(r.notes.iter().any(|n| n.starts_with("work list over 1 block")), "{:?}", r.notes);
    }
    let bits = |r: &moreau::SolveReport| r.r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&runs[0]), bits(&runs[1]), "one thread, run twice");
    assert_eq!(bits(&runs[0]), bits(&runs[2]), "one block: two threads give one thread's bits");
    // Under the natural map, not a per-contact test, the list is refilled until it is met.
    let natural = SolverOptions { criterion: StopCriterion::Natural, tol: 1e-6, ..listed.clone() };
    let r = solve(&p, SolverKind::Nlgs, &natural, Some(&r0));
    assert!(r.converged && r.error <= 1e-6, "natural map: {:.2e} {}", r.error, r.stop_reason);
    // From zero the error is everywhere: full sweeps until the list is worth keeping.
    let cold = solve(&p, SolverKind::Nlgs, &listed, None);
    assert!(cold.converged, "from zero: {}", cold.stop_reason);
    assert!(cold.notes.iter().any(|n| n.contains("work list") && !n.contains(" 0 full sweeps")), "{:?}", cold.notes);
    // A problem with an explicit W has no bodies to list neighbours by: forward sweeps, said so.
    let explicit = ContactProblem { w: moreau::problem::Delassus::Sparse(p.w.to_block_sparse()), ..p.clone() };
    let r = solve(&explicit, SolverKind::Nlgs, &SolverOptions { max_iter: 3, ..listed }, Some(&r0));
    assert!(r.notes.iter().any(|n| n.contains("worklist ordering needs a matrix-free problem")), "{:?}", r.notes);
}

#[test]
fn a_work_list_checks_the_full_error_when_its_list_empties_and_by_cost_alone() {
    // The 400-disk pile's 120th step from zero at tol 1e-3: full sweeps, then the list (120
    // sweeps' worth in all, measured). Each sweep's worth changes little of the iterate, so the
    // light rule (check when ‖Δr‖/‖r‖ ≤ tol) called 8 extra checks, at iterations 94-102.
    let p = scene_problem("scenes/pile.toml", 120);
    let r = solve(&p, SolverKind::Nlgs, &work_list(1e-3, 50_000), None);
    assert!(r.converged, "{}", r.stop_reason);
    assert_eq!(check_work(&p, StopCriterion::Velocity), CHECK_WORK, "a velocity test's check is two passes");
    let checked: Vec<usize> = r.history.iter().map(|h| h.iteration).collect();
    assert!(
        checked.iter().all(|&k| k % CHECK_WORK == 0 || k == r.iterations),
        "checks at {checked:?} of {} iterations: only every {CHECK_WORK} and when the list empties",
        r.iterations
    );
}

#[test]
fn the_gpu_keeps_the_work_list_as_thresholded_sweeps_that_leave_converged_contacts_alone() {
    let Some(ctx) = common::gpu_context() else { return };
    let gpu = Backend::gpu(ctx);
    // The disturbed lattice of the test below: 6,400 contacts at their answer but for 30 whose
    // free velocities moved by up to 2 %.
    let mut p = lattice_packing(80, 40, 0.5, 6);
    let r0 = answer_to_1e7(&p);
    p.q.iter_mut().enumerate().take(2060).skip(2000).for_each(|(k, q)| *q *= 1.0 + 0.02 * ((k as f64) * 0.7).sin());
    let listed = work_list(1e-3, 2_000);
    let colours = SolverOptions { ordering: Ordering::Colours, ..listed.clone() };
    let plain = gpu.solve(&p, SolverKind::Nlgs, &colours, Some(&r0)).unwrap();
    let list = gpu.solve(&p, SolverKind::Nlgs, &listed, Some(&r0)).unwrap();
    assert!(list.notes.iter().any(|n| n.starts_with("work list on the GPU")), "{:?}", list.notes);
    // The velocity test recomputed in f64 from the returned impulses, as the CPU judges it.
    let u = p.velocity(&list.r);
    let velocity = moreau::problem::residual::velocity_error(&p.w.diag_blocks(), &p.q, &p.mu, &list.r, &u);
    assert!(list.converged && velocity <= 1e-3, "{velocity:.2e} {}", list.stop_reason);
    // Plain colour sweeps spread the change over the lattice: measured, 1.9e-3 after 2,000; the
    // thresholded ones met tol by the check at sweep 512 (checks come every 16-512 sweeps).
    assert!(
        !plain.converged && 2 * list.iterations < plain.iterations,
        "{} against {}",
        list.iterations,
        plain.iterations
    );
    // Its emptying is the velocity test's: under the natural map the GPU refuses the list.
    let natural = SolverOptions { criterion: StopCriterion::Natural, ..listed };
    let refused = gpu.check(SolverKind::Nlgs, &natural).unwrap_err().to_string();
    assert!(refused.contains("criterion = velocity"), "{refused}");
}

#[test]
fn a_work_list_over_blocks_hands_moved_contacts_across_and_gives_the_same_bits_on_any_threads() {
    // A lattice of 6,400 contacts numbered row by row (7 blocks of 1,024), at its answer to 1e-7
    // but for the free velocities of contacts 1,000-1,029, moved by up to 2 %: they straddle the
    // first two blocks' boundary.
    let mut p = lattice_packing(80, 40, 0.5, 6);
    let r0 = answer_to_1e7(&p);
    p.q.iter_mut().enumerate().take(2060).skip(2000).for_each(|(k, q)| *q *= 1.0 + 0.02 * ((k as f64) * 0.7).sin());
    let listed = work_list(1e-3, 500);
    // Full sweeps spread the change over the lattice: measured, not converged in 5,000.
    let full_sweeps = SolverOptions { ordering: Ordering::Forward, ..listed.clone() };
    let plain = solve(&p, SolverKind::Nlgs, &full_sweeps, Some(&r0));
    assert!(!plain.converged, "forward sweeps met tol in {} sweeps", plain.iterations);
    let threads = [1, 2, 4, 2];
    let runs: Vec<_> =
        threads.iter().map(|&t| on_threads(t, || solve(&p, SolverKind::Nlgs, &listed, Some(&r0)))).collect();
    let diag = p.w.diag_blocks();
    for (t, r) in threads.iter().zip(&runs) {
        let u = p.velocity(&r.r);
        let velocity = moreau::problem::residual::velocity_error(&diag, &p.q, &p.mu, &r.r, &u);
        // Measured: 5 sweeps' worth of updates.
        assert!(r.converged && velocity <= 1e-3 && r.iterations <= 50, "{t} threads: {velocity:.2e} {}", r.stop_reason);
        // Several blocks, and an emptied list that met the test the first time: a contact moved
        // by another block's update was handed to its own block's list.
        let note = r.notes.iter().find(|n| n.starts_with("work list over")).expect("the work list's note");
        assert!(!note.starts_with("work list over 1 block") && note.contains("halved 0 times"), "{note}");
    }
    let bits = |r: &moreau::SolveReport| r.r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (t, r) in threads.iter().zip(&runs).skip(1) {
        assert_eq!(bits(&runs[0]), bits(r), "{t} threads give one thread's bits");
    }
}

#[test]
fn colour_ordered_nlgs_is_the_forward_sweep_of_the_problem_numbered_by_colour_on_any_threads() {
    let p = lattice_packing(80, 40, 0.5, 6);
    let opts = SolverOptions { tol: 1e-6, max_iter: 20_000, ordering: Ordering::Colours, ..Default::default() };
    let runs: Vec<_> = [1, 2, 4].iter().map(|&t| on_threads(t, || solve(&p, SolverKind::Nlgs, &opts, None))).collect();
    for (t, r) in [1, 2, 4].iter().zip(&runs) {
        assert!(r.converged && r.error <= 1e-6, "{t} threads: {:.2e} {}", r.error, r.stop_reason);
    }
    let bits = |r: &[f64]| r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&runs[0].r), bits(&runs[1].r), "one and two threads sweep in the same colour order");
    assert_eq!(bits(&runs[0].r), bits(&runs[2].r), "one and four threads");
    // The same as one thread's forward sweep over the problem numbered colour by colour.
    let moreau::problem::Delassus::MatrixFree(op) = &p.w else { unreachable!() };
    let (colouring, numbered) = moreau::solvers::nlgs::colour_ordered(&p, op);
    let forward = SolverOptions { ordering: Ordering::Forward, ..opts.clone() };
    let reference = on_threads(1, || solve(&numbered, SolverKind::Nlgs, &forward, None));
    assert_eq!(reference.iterations, runs[0].iterations);
    let back: Vec<f64> =
        colouring.order.iter().flat_map(|&a| [runs[0].r[2 * a as usize], runs[0].r[2 * a as usize + 1]]).collect();
    assert_eq!(bits(&back), bits(&reference.r));
    // A different order from the contacts' own: the sweep counts differ.
    let own = on_threads(1, || solve(&p, SolverKind::Nlgs, &forward, None));
    assert_ne!(own.iterations, runs[0].iterations);
    // An explicit W has no bodies to colour by: forward, said so.
    let explicit = ContactProblem { w: moreau::problem::Delassus::Sparse(p.w.to_block_sparse()), ..p.clone() };
    let r = solve(&explicit, SolverKind::Nlgs, &SolverOptions { max_iter: 3, ..opts }, None);
    assert!(r.notes.iter().any(|n| n.starts_with("colour ordering needs a matrix-free problem")), "{:?}", r.notes);
}

/// A scene stepped `steps` times on `threads` threads: every position's bits.
fn stepped(threads: usize, steps: usize) -> Vec<u64> {
    on_threads(threads, || {
        let mut s = moreau::scene::load(Path::new("scenes/pile_10k.toml")).unwrap();
        // Whole steps, each its 200 sweeps (the first steps need thousands to meet tol 1e-4).
        s.settings.options.max_iter = 200;
        let mut sim = Simulation::new(s.world, s.settings).unwrap();
        for _ in 0..steps {
            let r = sim.step().unwrap();
            assert!(r.error.is_finite(), "step {}: {}", r.step, r.stop_reason);
        }
        sim.world.bodies.position.iter().flat_map(|p| [p.x.to_bits(), p.y.to_bits()]).collect()
    })
}

#[test]
fn one_and_two_threads_each_give_the_same_steps_on_every_run() {
    assert_eq!(stepped(1, 2), stepped(1, 2), "one thread, run twice");
    assert_eq!(stepped(2, 2), stepped(2, 2), "two threads, run twice");
}

#[test]
fn grains_come_from_a_csv_file_and_bad_files_name_line_and_column() {
    let dir = Scratch::new("grains");
    let scene = |csv: &str| {
        std::fs::write(dir.join("packing.csv"), csv).unwrap();
        let toml = r#"
name = "csv"
effects = ["gravity", "friction", "rotation"]
[time]
step = 1e-3
steps = 3
[[material]]
name = "glass"
density = 2500.0
[[wall]]
container = { min = [0.0, 0.0], max = [1.0, 1.0] }
[[grains]]
file = "packing.csv"
"#;
        moreau::scene::parse(toml, &dir.join("scene.toml"))
    };
    let s = scene("x,y,r,vx\n0.2,0.1,0.05,1.0\n0.5,0.1,0.05,0\n0.8,0.1,0.05,0\n").unwrap();
    assert_eq!(s.world.bodies.len(), 3);
    assert_eq!(s.world.bodies.velocity[0].x, 1.0);
    let mut sim = Simulation::new(s.world, s.settings).unwrap();
    assert!(sim.step().unwrap().error.is_finite());
    let e = scene("x,y,r\n0.2,0.1,0.05\n0.5,oops,0.05\n").unwrap_err().to_string();
    assert!(e.contains("grains[0].file") && e.contains("line 3, column 2 (y)"), "{e}");
    let e = scene("x,y,r\n0.2,0.1,-1\n").unwrap_err().to_string();
    assert!(e.contains("line 2, column 3 (r)"), "{e}");
    let e = scene("x,y,diameter\n").unwrap_err().to_string();
    assert!(e.contains("line 1, column 3") && e.contains("diameter"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A packing handed over in no spatial order (here a shuffled lattice) is numbered in rows across
/// it: its contacts then fall into bands, which threads and the GPU's block sweeps need. With
/// `order = "file"` the file's order is kept, and every block would touch every other. (A file
/// whose grains already lie together keeps its order: `saved_grains_start_a_scene_where_the_run_left_them`.)
#[test]
fn a_shuffled_packing_from_a_file_is_numbered_in_rows_unless_asked_not_to() {
    let dir = Scratch::new("shuffled");
    // 100 × 30 disks of radius 0.05 touching on a square lattice, shuffled.
    let in_rows: Vec<String> = (0..30)
        .flat_map(|i| {
            (0..100).map(move |j| format!("{},{},0.05,{}\n", 0.05 + 0.1 * j as f64, 0.05 + 0.1 * i as f64, 100 * i + j))
        })
        .collect();
    let write =
        |rows: &[String]| std::fs::write(dir.join("packing.csv"), format!("x,y,r,tag\n{}", rows.concat())).unwrap();
    let mut shuffled = in_rows.clone();
    shuffled.shuffle(&mut SmallRng::seed_from_u64(3));
    write(&shuffled);
    let problem_of = |order: &str| {
        let toml = format!(
            r#"
name = "shuffled"
effects = ["gravity", "friction", "rotation"]
[time]
step = 1e-3
steps = 1
[solver]
max_iter = 20
[[material]]
name = "glass"
density = 2500.0
[[wall]]
container = {{ min = [0.0, 0.0], max = [10.0, 4.0] }}
[[grains]]
file = "packing.csv"
{order}
"#
        );
        let s = moreau::scene::parse(&toml, &dir.join("scene.toml")).map_err(|e| e.to_string())?;
        let (tags, notes) = (s.world.bodies.tag.clone(), s.notes.clone());
        let mut sim = Simulation::new(s.world, s.settings).unwrap();
        sim.keep_problems(true);
        assert!(sim.step().unwrap().error.is_finite());
        Ok::<_, String>((tags, notes, sim.last_problem().expect("contacts").clone()))
    };
    for (order, in_rows) in
        [("", true), (r#"order = "auto""#, true), (r#"order = "space""#, true), (r#"order = "file""#, false)]
    {
        let (tags, notes, p) = problem_of(order).unwrap();
        // The renumbering `auto` chose is said; one asked for is not.
        let said = notes.iter().any(|n| n.contains("3000 grains") && n.contains("numbered in rows"));
        assert_eq!(said, order.is_empty() || order.contains("auto"), "{order:?}: {notes:?}");
        let moreau::problem::Delassus::MatrixFree(op) = &p.w else { panic!("a step's problem is matrix-free") };
        assert!(p.n_contacts() > 5_000, "{}", p.n_contacts());
        let blocks = moreau::solvers::nlgs::block_colours(op, p.n_contacts());
        assert_eq!(blocks.is_some(), in_rows, "{order:?}: blocks in bands");
        // In rows, the lattice's own row-major numbering (its tags) comes back.
        let row_major = tags.iter().enumerate().all(|(k, &t)| t as usize == k);
        assert_eq!(row_major, in_rows, "{order:?}: the bodies' tags in order: {:?}", &tags[..5]);
    }
    // The file in rows: `auto` keeps its order, and says nothing.
    write(&in_rows);
    let (tags, notes, _) = problem_of("").unwrap();
    assert!(notes.is_empty() && tags.iter().enumerate().all(|(k, &t)| t as usize == k), "{notes:?}");
    let e = problem_of(r#"order = "random""#).unwrap_err();
    assert!(e.contains("grains[0].order") && e.contains("\"random\""), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_cpu_colouring_is_proper_on_matrix_free_and_explicit_operators() {
    let p = scene_problem("scenes/pile.toml", 20);
    let c = moreau::problem::colouring::Colouring::of(&p.w);
    assert!(c.n_colours() >= 2 && c.order.len() == p.n_contacts());
    assert!(c.is_proper(moreau::problem::colouring::Colouring::neighbours_in(&p.w)));
    let explicit = moreau::problem::Delassus::Sparse(p.w.to_block_sparse());
    let c = moreau::problem::colouring::Colouring::of(&explicit);
    assert!(c.is_proper(moreau::problem::colouring::Colouring::neighbours_in(&explicit)));
}

/// On threads, NLGS sweeps a pile by blocks of contacts (bands of the packing), each in contact
/// order: closer to the sequential sweep than a sweep in contact-colour order, and the same bits
/// on any thread count ≥ 2. Grains numbered in no spatial order leave no bands: the sweep colours
/// contacts instead.
#[test]
fn threaded_nlgs_sweeps_bands_of_a_pile_and_colours_contacts_when_there_are_none() {
    let p = scene_problem("scenes/pile_10k.toml", 3);
    let moreau::problem::Delassus::MatrixFree(op) = &p.w else { panic!("a step's problem is matrix-free") };
    let blocks = moreau::solvers::nlgs::block_colours(op, p.n_contacts()).expect("a deposited pile is banded");
    assert!(blocks.len() <= 3 && blocks.iter().all(|c| c.len() >= 2), "{} block colours", blocks.len());
    let opts = SolverOptions { tol: 1e-6, max_iter: 20_000, ..Default::default() };
    let runs: Vec<_> = [1, 2, 4].iter().map(|&t| on_threads(t, || solve(&p, SolverKind::Nlgs, &opts, None))).collect();
    for r in &runs {
        assert!(r.converged, "{}", r.stop_reason);
    }
    assert!(op.colouring_if_built().is_none(), "the block sweep needs no contact colouring");
    let bits = |r: &moreau::SolveReport| r.r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&runs[1]), bits(&runs[2]), "two and four threads sweep the same blocks");
    // Measured: 550 sweeps sequentially, 570 by blocks.
    assert!(
        runs[1].iterations * 10 <= runs[0].iterations * 11,
        "{} against {}",
        runs[1].iterations,
        runs[0].iterations
    );

    // The same contacts in random order: every block touches every other one.
    let mut order: Vec<usize> = (0..p.n_contacts()).collect();
    order.shuffle(&mut SmallRng::seed_from_u64(1));
    assert!(moreau::solvers::nlgs::block_colours(&op.permuted(&order), p.n_contacts()).is_none());
}

#[test]
fn newton_and_nlgs_newton_reach_tight_tolerances_on_small_problems() {
    for (nx, ny, mu) in [(12, 6, 0.0), (12, 6, 0.3), (20, 8, 0.5)] {
        let p = lattice_packing(nx, ny, mu, 7);
        let lu = SolverOptions { newton_linear: NewtonLinear::Direct, ..Default::default() };
        for (kind, base) in [
            (SolverKind::Newton, SolverOptions::default()),
            (SolverKind::Newton, lu),
            (SolverKind::NlgsNewton, SolverOptions::default()),
        ] {
            let opts = SolverOptions { tol: 1e-10, max_iter: 2_000, ..base };
            let r = solve(&p, kind, &opts, None);
            assert!(r.converged && r.error <= 1e-10, "{kind} on {nx}x{ny} mu {mu}: {:.2e} {}", r.error, r.stop_reason);
            // Newton steps, not NLGS fallbacks (10 counted iterations each), do the work:
            // measured 10–27 iterations for Newton; NLGS–Newton 5–115 (NLGS alone: 500–2,500).
            let most = if kind == SolverKind::Newton { 40 } else { 200 };
            assert!(r.iterations <= most, "{kind} on {nx}x{ny} mu {mu}: {} iterations", r.iterations);
        }
    }
}

/// The first step of a frictionless deposit (1,000 disks dropped and rolled into place, then
/// loaded by gravity from r = 0): NLGS needs thousands of sweeps, NLGS–Newton a handful of
/// corrections (the Tresca energy is then the problem's own).
#[test]
fn nlgs_newton_solves_a_frictionless_deposit_in_a_few_iterations() {
    let dir = Scratch::new("deposit");
    let scene = dir.join("deposit.toml");
    std::fs::write(
        &scene,
        r#"name = "deposit"
effects = ["gravity", "friction", "rotation"]
[time]
step = 2e-3
steps = 1
[contact]
friction = 0.0
[[material]]
name = "glass"
density = 2500.0
[[wall]]
container = { min = [0.0, 0.0], max = [0.15, 1.0] }
[[generate]]
kind = "deposition"
count = 1000
radius = [0.002, 0.003]
region = { min = [0.0, 0.0], max = [0.15, 1.0] }
seed = 7
"#,
    )
    .unwrap();
    let p = scene_problem(scene.to_str().unwrap(), 1);
    std::fs::remove_dir_all(&dir).ok();
    assert!(p.n_contacts() > 1_500, "{} contacts", p.n_contacts());
    let opts = SolverOptions { tol: 1e-8, max_iter: 50_000, ..Default::default() };
    let nlgs = solve(&p, SolverKind::Nlgs, &opts, None);
    let newton = solve(&p, SolverKind::NlgsNewton, &opts, None);
    // Anderson acceleration of the same sweeps: measured 31× fewer on a 2,000-disk deposit to 1e-6.
    let anderson = solve(&p, SolverKind::Nlgs, &SolverOptions { anderson: 5, ..opts.clone() }, None);
    assert!(anderson.converged, "anderson: {}", anderson.stop_reason);
    common::assert_mixing_paid("deposit", &anderson, nlgs.iterations - 1, 10, "Anderson acceleration over 5 sweeps");
    assert!(nlgs.converged && newton.converged, "{} / {}", nlgs.stop_reason, newton.stop_reason);
    // Measured: 11 iterations against NLGS's 3,317 (2,000 disks: 15 against 14,943).
    assert!(
        50 * newton.iterations < nlgs.iterations,
        "NLGS–Newton {} iterations, NLGS {}",
        newton.iterations,
        nlgs.iterations
    );
}
