//! The GPU path on whatever adapter wgpu finds (the software adapter, lavapipe, in CI): every
//! kernel against its CPU mirror on random data, and the GPU solvers against the CPU reference.
//! Without an adapter these tests say so and pass, unless MOREAU_REQUIRE_GPU=1 (set by CI).

mod common;

use std::path::Path;

use moreau::gpu::colouring::{BlockColouring, Colouring};
use moreau::gpu::cpu;
use moreau::gpu::layout::{to_f32_pairs, BsrLayout, MatrixFreeLayout, NO_ANTAGONIST};
use moreau::gpu::{stages, GpuContext};
use moreau::problem::generate::{lattice_packing, random_small};
use moreau::problem::{ContactProblem, Delassus};
use moreau::solvers::{solve, SolverKind, SolverOptions};
use rand::{Rng, SeedableRng};

/// Kernel and mirror agree to a few f32 roundings of the largest term (fused multiply-adds may
/// round differently): |gpu − cpu| ≤ 1e-5 · max(1, |cpu|_∞).
fn assert_close(gpu: &[f32], cpu: &[f32], what: &str) {
    assert_eq!(gpu.len(), cpu.len());
    let scale = cpu.iter().fold(1.0f32, |m, x| m.max(x.abs()));
    for (k, (g, c)) in gpu.iter().zip(cpu).enumerate() {
        assert!((g - c).abs() <= 1e-5 * scale, "{what}[{k}]: gpu {g} vs cpu {c} (scale {scale})");
    }
}

/// A simulation step's matrix-free problem: the pile after 60 steps, with the given effects.
fn pile_problem(effects: &str) -> ContactProblem {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pile.toml")).unwrap();
    let text = text.replace(r#"effects = ["gravity", "friction", "rotation"]"#, &format!("effects = [{effects}]"));
    let s = moreau::scene::parse(&text, Path::new("pile.toml")).unwrap();
    let mut sim = moreau::stepping::Simulation::new(s.world, s.settings).unwrap();
    sim.keep_problems(true);
    for _ in 0..60 {
        sim.step().unwrap();
    }
    sim.last_problem().unwrap().clone()
}

/// The pile's problem with a third of its grains held along x and a third along y
/// (`hold_velocity`), none that touches a wall (whose infinite mass would leave the contact
/// nothing to move along its normal): the kernels' packed inverse masses against the operator's.
fn held_pile_problem() -> ContactProblem {
    let mut p = pile_problem(r#""gravity", "friction", "rotation""#);
    let Delassus::MatrixFree(op) = &p.w else { panic!("the pile is matrix-free") };
    let layout = MatrixFreeLayout::new(op);
    let mut on_wall = vec![false; layout.inv_mass.len()];
    for c in layout.contacts.iter().filter(|c| c.j == NO_ANTAGONIST) {
        on_wall[c.i as usize] = true;
    }
    let held = (0..on_wall.len()).map(|k| if on_wall[k] { [false; 2] } else { [k % 3 == 0, k % 3 == 1] }).collect();
    p.w = Delassus::MatrixFree(op.clone().with_held_axes(held).unwrap());
    p
}

#[test]
fn every_kernel_matches_its_cpu_mirror() {
    let Some(ctx) = common::gpu_context() else { return };
    let mut rng = rand::rngs::SmallRng::seed_from_u64(11);
    let problems = [
        ("lattice", lattice_packing(30, 20, 0.4, 3)),
        ("pile", pile_problem(r#""gravity", "friction", "rotation""#)),
        ("pile without rotation", pile_problem(r#""gravity", "friction""#)),
        ("frictionless pile", pile_problem(r#""gravity""#)),
        ("pile with held grains", held_pile_problem()),
    ];
    for (name, p) in &problems {
        let nc = p.n_contacts();
        // A frictionless operator's tangential rows are decoupled placeholders: r_t ≡ 0 there.
        let t_scale = if p.is_frictionless() { 0.0 } else { 1.0 };
        let r: Vec<[f32; 2]> = (0..nc).map(|_| [rng.gen_range(0.0..1.0), t_scale * rng.gen_range(-0.5..0.5)]).collect();
        let q: Vec<[f32; 2]> = (0..nc).map(|_| [rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)]).collect();
        let Delassus::MatrixFree(op) = &p.w else { panic!("{name} is matrix-free") };
        let layout = MatrixFreeLayout::new(op);
        let nb = layout.inv_mass.len();
        let gpu_v = stages::body_accumulate(&ctx, &layout, &r).unwrap();
        let mut cpu_v = vec![[0.0f32; 4]; nb];
        cpu::body_accumulate::body_accumulate(&layout, &r, &mut cpu_v);
        assert_close(gpu_v.as_flattened(), cpu_v.as_flattened(), &format!("{name}: body_accumulate"));
        let gpu_u = stages::contact_gather(&ctx, &layout, &cpu_v, &q).unwrap();
        let mut cpu_u = vec![[0.0f32; 2]; nc];
        cpu::contact_gather::contact_gather(&layout, &cpu_v, &q, &mut cpu_u);
        assert_close(gpu_u.as_flattened(), cpu_u.as_flattened(), &format!("{name}: contact_gather"));
        // The mirrors compose to the f64 operator: u = W r + q.
        let r64: Vec<f64> = r.as_flattened().iter().map(|&x| x as f64).collect();
        let mut w_r = vec![0.0; 2 * nc];
        p.w.apply(&r64, &mut w_r);
        let exact: Vec<f32> = w_r.iter().zip(q.as_flattened()).map(|(a, b)| (*a + *b as f64) as f32).collect();
        assert_close(cpu_u.as_flattened(), &exact, &format!("{name}: mirrors vs f64 W"));
        // The same operator in block-sparse form.
        let bsr = BsrLayout::new(&p.w.to_block_sparse());
        let gpu_b = stages::bsr_product(&ctx, &bsr, &r, &q).unwrap();
        let mut cpu_b = vec![[0.0f32; 2]; nc];
        cpu::bsr_product::bsr_product(&bsr, &r, &q, &mut cpu_b);
        assert_close(gpu_b.as_flattened(), cpu_b.as_flattened(), &format!("{name}: bsr_product"));
        assert_close(cpu_b.as_flattened(), &exact, &format!("{name}: bsr mirror vs f64 W"));
        // Jacobi update.
        let mu: Vec<f32> = p.mu.iter().map(|&m| m as f32).collect();
        let step: Vec<f32> = (0..nc).map(|_| rng.gen_range(0.1..2.0)).collect();
        let gpu_r = stages::jacobi_update(&ctx, &cpu_u, &mu, &step, &r).unwrap();
        let mut cpu_r = r.clone();
        cpu::jacobi_update::jacobi_update(&cpu_u, &mu, &step, &mut cpu_r);
        assert_close(gpu_r.as_flattened(), cpu_r.as_flattened(), &format!("{name}: jacobi_update"));
        assert!(cpu_r.iter().zip(&mu).all(|(r, m)| r[0] >= 0.0 && r[1].abs() <= m * r[0] * (1.0 + 1e-6)));
        // The fused iteration (one dispatch, by body) from (r, v = M⁻¹ Bᵀ r): its mirror is the
        // three kernels' iteration to the bit, and v of its new impulses.
        let (r_fused, v_fused) = stages::jacobi_fused(&ctx, &layout, (&q, &mu, &step), (&r, &cpu_v)).unwrap();
        let (mut cpu_r_fused, mut cpu_v_fused) = (vec![[0.0f32; 2]; nc], vec![[0.0f32; 4]; nb]);
        cpu::jacobi_fused::jacobi_fused(&layout, &q, &mu, &step, (&r, &cpu_v), &mut cpu_r_fused, &mut cpu_v_fused);
        assert_close(r_fused.as_flattened(), cpu_r_fused.as_flattened(), &format!("{name}: jacobi_fused r"));
        assert_close(v_fused.as_flattened(), cpu_v_fused.as_flattened(), &format!("{name}: jacobi_fused v"));
        let mut v_of_r = vec![[0.0f32; 4]; nb];
        cpu::body_accumulate::body_accumulate(&layout, &cpu_r, &mut v_of_r);
        assert!(
            cpu_r_fused == cpu_r && cpu_v_fused == v_of_r,
            "{name}: jacobi_fused's mirror is not the three kernels'"
        );
        // Coloured NLGS, colour by colour, on both forms of W.
        let diag: Vec<[f32; 4]> = p.w.diag_blocks().iter().map(|d| d.map(|x| x as f32)).collect();
        let colouring = Colouring::matrix_free(&layout);
        assert!(colouring.n_colours() >= 2, "{name}: {} colours", colouring.n_colours());
        // Plain (threshold 0), then as the work list's sweeps with the median contact's residual
        // in velocity units as threshold: about half the contacts are left alone.
        let c: Vec<f32> = diag.iter().map(|d| d[0]).collect();
        let residuals: Vec<f32> =
            (0..nc).map(|a| cpu::single_contact::velocity_residual(c[a], r[a], cpu_u[a], mu[a])).collect();
        let mut sorted = residuals.clone();
        sorted.sort_by(f32::total_cmp);
        for threshold in [0.0, sorted[nc / 2]] {
            let (mut r_cpu, mut v_cpu) = (r.clone(), cpu_v.clone());
            let mut counted = 0;
            for colour in 0..colouring.n_colours() {
                let r_before = r_cpu.clone();
                let ((r_gpu, v_gpu), updated_gpu) =
                    stages::nlgs_colour(&ctx, &layout, &diag, &q, &mu, &colouring, colour, threshold, &r_cpu, &v_cpu)
                        .unwrap();
                let contacts = colouring.colour(colour);
                let updated =
                    cpu::nlgs_colour::nlgs_colour(&layout, &diag, &q, &mu, contacts, threshold, &mut r_cpu, &mut v_cpu);
                let what = format!("{name}: nlgs_colour {colour}, threshold {threshold:e}");
                assert_close(r_gpu.as_flattened(), r_cpu.as_flattened(), &format!("{what} r"));
                assert_close(v_gpu.as_flattened(), v_cpu.as_flattened(), &format!("{what} v"));
                // The kernel counts what it updated (the work list's sweeps), as the mirror does.
                assert_eq!(updated_gpu, updated, "{what}: contacts updated");
                let moved = contacts.iter().filter(|&&a| r_cpu[a as usize] != r_before[a as usize]).count() as u32;
                assert!(threshold == 0.0 || updated >= moved, "{what}: {updated} counted, {moved} moved");
                counted += updated;
                // Continue both from the mirror's state so differences cannot compound.
            }
            // Plain sweeps count nothing; thresholded ones some of the contacts.
            assert!(
                if threshold == 0.0 { counted == 0 } else { counted > 0 && counted < nc as u32 },
                "{name}: {counted}"
            );
            // The first colour saw the starting velocities: its contacts within the threshold
            // kept their impulses, the others moved.
            let first = colouring.colour(0).iter().map(|&a| a as usize);
            let kept = first.clone().filter(|&a| r_cpu[a] == r[a]).count();
            let within = first.clone().filter(|&a| residuals[a] <= threshold).count();
            assert_eq!(kept, within, "{name}, threshold {threshold:e}: {kept} kept, {within} within");
            assert!(threshold == 0.0 || (within > 0 && within < first.count()), "{name}: {within} within");
        }
        // Block sweeps: blocks of 64 contacts (several a problem, in several block colours),
        // each swept three times a dispatch, plain and thresholded.
        let blocks = BlockColouring::new(&layout, &colouring, 64);
        assert!(blocks.blocks.n_colours() >= 2, "{name}: {} block colours", blocks.blocks.n_colours());
        for threshold in [0.0, sorted[nc / 2]] {
            let (mut r_cpu, mut v_cpu) = (r.clone(), cpu_v.clone());
            for block_colour in 0..blocks.blocks.n_colours() {
                let w = (&diag[..], &q[..], &mu[..]);
                let (r_gpu, v_gpu) =
                    stages::nlgs_blocks(&ctx, &layout, w, &blocks, block_colour, 3, threshold, (&r_cpu, &v_cpu))
                        .unwrap();
                cpu::nlgs_blocks::nlgs_blocks(&layout, w, &blocks, block_colour, 3, threshold, &mut r_cpu, &mut v_cpu);
                let what = format!("{name}: nlgs_blocks {block_colour}, threshold {threshold:e}");
                assert_close(r_gpu.as_flattened(), r_cpu.as_flattened(), &format!("{what} r"));
                assert_close(v_gpu.as_flattened(), v_cpu.as_flattened(), &format!("{what} v"));
            }
        }
        let colouring = Colouring::block_sparse(&bsr);
        let mut r_cpu = r.clone();
        for colour in 0..colouring.n_colours() {
            let r_gpu = stages::nlgs_colour_bsr(&ctx, &bsr, &diag, &q, &mu, &colouring, colour, &r_cpu).unwrap();
            cpu::nlgs_colour_bsr::nlgs_colour_bsr(&bsr, &diag, &q, &mu, colouring.colour(colour), &mut r_cpu);
            assert_close(r_gpu.as_flattened(), r_cpu.as_flattened(), &format!("{name}: nlgs_colour_bsr {colour}"));
        }
    }
}

#[test]
fn colourings_are_proper_and_a_coloured_sweep_is_a_gauss_seidel_sweep() {
    for p in [lattice_packing(40, 20, 0.4, 2), pile_problem(r#""gravity", "friction", "rotation""#)] {
        let Delassus::MatrixFree(op) = &p.w else { unreachable!() };
        let layout = MatrixFreeLayout::new(op);
        let c = Colouring::matrix_free(&layout);
        let bsr = BsrLayout::new(&p.w.to_block_sparse());
        let adjacency = moreau::gpu::colouring::bsr_adjacency(&bsr);
        // Contacts that share a moving body have a block of W between them: a proper colouring of
        // the block pattern is what exact GS semantics need.
        assert!(c.is_proper(|a, out| out.extend_from_slice(&adjacency[a])), "matrix-free colouring is not proper");
        let cb = Colouring::block_sparse(&bsr);
        assert!(cb.is_proper(|a, out| out.extend_from_slice(&adjacency[a])));
        let mut seen = c.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..p.n_contacts() as u32).collect::<Vec<_>>());
        // Block sweeps' layout: each block holds its run of contacts colour by colour, and two
        // blocks of one block colour share no moving body.
        let blocks = BlockColouring::new(&layout, &c, 100);
        let colour_of = c.colour_of_each();
        let n_blocks = p.n_contacts().div_ceil(100);
        for b in 0..n_blocks {
            let mut members: Vec<u32> = (0..blocks.colours).flat_map(|k| blocks.contacts(b, k).to_vec()).collect();
            assert!(
                (0..blocks.colours).all(|k| blocks.contacts(b, k).iter().all(|&a| colour_of[a as usize] == k as u32))
            );
            members.sort_unstable();
            assert_eq!(members, (b as u32 * 100..((b + 1) * 100).min(p.n_contacts()) as u32).collect::<Vec<_>>());
        }
        let moving = |k: u32| k != moreau::gpu::layout::NO_ANTAGONIST && layout.inv_mass[k as usize] != [0.0, 0.0];
        for k in 0..blocks.blocks.n_colours() {
            let mut owner = vec![None; layout.inv_mass.len()];
            for &b in blocks.blocks.colour(k) {
                for a in (0..blocks.colours).flat_map(|c| blocks.contacts(b as usize, c)) {
                    let contact = &layout.contacts[*a as usize];
                    for body in [contact.i, contact.j].into_iter().filter(|&body| moving(body)) {
                        let first = *owner[body as usize].get_or_insert(b);
                        assert_eq!(first, b, "blocks {first} and {b} of block colour {k} share body {body}");
                    }
                }
            }
        }
        assert!(blocks.blocks.n_colours() >= 2 && n_blocks > blocks.blocks.n_colours());
        // One coloured sweep (mirror, colour by colour) equals sequential GS in colour order.
        let nc = p.n_contacts();
        let q = to_f32_pairs(&p.q);
        let mu: Vec<f32> = p.mu.iter().map(|&m| m as f32).collect();
        let diag: Vec<[f32; 4]> = p.w.diag_blocks().iter().map(|d| d.map(|x| x as f32)).collect();
        let (mut r1, mut r2) = (vec![[0.0f32; 2]; nc], vec![[0.0f32; 2]; nc]);
        for colour in 0..cb.n_colours() {
            cpu::nlgs_colour_bsr::nlgs_colour_bsr(&bsr, &diag, &q, &mu, cb.colour(colour), &mut r1);
        }
        for &a in &cb.order {
            cpu::nlgs_colour_bsr::nlgs_colour_bsr(&bsr, &diag, &q, &mu, &[a], &mut r2);
        }
        assert_eq!(r1, r2);
    }
}

#[test]
fn gpu_solvers_solve_what_the_cpu_solves() {
    let Some(ctx) = common::gpu_context() else { return };
    let opts = SolverOptions { tol: 1e-5, max_iter: 200_000, ..SolverOptions::default() };
    let mut cases: Vec<(String, ContactProblem)> = vec![
        ("random_small".into(), random_small(3, 0.5, 7)),
        ("lattice 20×10".into(), lattice_packing(20, 10, 0.3, 1)),
        ("pile step 60".into(), pile_problem(r#""gravity", "friction", "rotation""#)),
        ("frictionless pile step 60".into(), pile_problem(r#""gravity""#)),
    ];
    for f in [
        "FC2D_SliderCrankLagrangian00000.dat",
        "FC2D_SliderCrankLagrangian00001.dat",
        "fc2d_granularflowonwall_00667_00000.dat",
    ] {
        if let Some(path) = common::shared_data(f) {
            cases.push((f.into(), moreau::io::siconos::read_fc2d(&path).unwrap()));
        }
    }
    for f in ["fc2d_granularflowonwall_02020_00213.dat", "fc2d_granularflowonwall_07002_00801.dat"] {
        if let Some(path) = common::shared_data(f) {
            cases.push((f.into(), moreau::io::siconos::read_fc2d(&path).unwrap()));
        }
    }
    let kinds = [SolverKind::Nlgs, SolverKind::Pcpg, SolverKind::Cpg, SolverKind::Jacobi, SolverKind::Apgd];
    let mut frictionless = 0;
    for ((name, p), kind) in cases.iter().flat_map(|c| kinds.map(|k| (c, k))) {
        if matches!(kind, SolverKind::Jacobi | SolverKind::Cpg | SolverKind::Apgd) && p.n_contacts() > 1500 {
            continue; // 10^4–10^5 iterations on the large granular files
        }
        let name = &format!("{name} ({})", kind.name());
        let cpu = solve(p, kind, &opts, None);
        let gpu = moreau::gpu::solve(&ctx, p, kind, &opts, None).unwrap();
        eprintln!(
            "{name}: cpu {} its error {:.2e}; gpu {} its error {:.2e} ({})",
            cpu.iterations, cpu.error, gpu.iterations, gpu.error, gpu.stop_reason
        );
        assert!(cpu.converged, "{name}: the CPU reference did not converge");
        // The f64 error of the f32 answer reaches 1e-5 (the GPU path's stated floor here).
        assert!(gpu.converged && gpu.error <= 1e-5, "{name}: gpu error {:.2e} ({})", gpu.error, gpu.stop_reason);
        common::check_solution(p, &gpu.r, 1e-4).unwrap_or_else(|e| panic!("{name}: {e}"));
        // Without friction u = W r + q is the same for every solution (the gradient of a convex
        // quadratic is constant on its minimisers): the same local velocities as the CPU answer,
        // within the f32 floor, on the problem's scale. With friction neither r nor u is unique,
        // and the error measure above is the judge.
        if p.mu.iter().all(|&m| m == 0.0) {
            frictionless += 1;
            let scale = cpu.u.iter().chain(&p.q).fold(1e-12f64, |m, x| m.max(x.abs()));
            let du = cpu.u.iter().zip(&gpu.u).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(du <= 1e-3 * scale, "{name}: |u_gpu − u_cpu| = {du:.2e} of {scale:.2e}");
        }
    }
    assert!(frictionless >= 5, "the frictionless pile's velocities were compared for every solver");
    // Starting from the converged f32 answer costs almost nothing.
    let p = &cases[1].1;
    let first = moreau::gpu::solve(&ctx, p, SolverKind::Jacobi, &opts, None).unwrap();
    let again = moreau::gpu::solve(&ctx, p, SolverKind::Jacobi, &opts, Some(&first.r)).unwrap();
    assert!(again.converged && again.iterations <= 16, "warm start took {} iterations", again.iterations);
    let _ = to_f32_pairs(&[0.0, 0.0]);
}

/// Projected Jacobi on the GPU runs an iteration a dispatch (`jacobi_fused`, over two buffers of
/// impulses and velocities), so its rounds are pairs of iterations: the report counts
/// iterations, as the CPU's does, and an odd `max_iter` stops one short and says why.
#[test]
fn gpu_jacobi_counts_its_paired_iterations_against_max_iter() {
    let Some(ctx) = common::gpu_context() else { return };
    let p = lattice_packing(20, 10, 0.3, 1);
    for (max_iter, ran) in [(8, 8), (7, 6), (40, 40)] {
        let opts = SolverOptions { tol: 1e-30, max_iter, ..Default::default() };
        let run = moreau::gpu::solve(&ctx, &p, SolverKind::Jacobi, &opts, None).unwrap();
        assert!(
            !run.converged && run.iterations == ran,
            "max_iter {max_iter}: {} ({})",
            run.iterations,
            run.stop_reason
        );
        assert_eq!(2 * run.gpu_checks.rounds, ran, "max_iter {max_iter}: rounds");
        assert_eq!(run.w_products, ran + 1, "max_iter {max_iter}: products");
        let noted = run.notes.iter().any(|n| n.contains("run in pairs"));
        assert_eq!(noted, max_iter % 2 == 1, "max_iter {max_iter}: {:?}", run.notes);
        let history = run.history.iter().map(|h| h.iteration).collect::<Vec<_>>();
        assert!(history.iter().all(|&k| k % 2 == 0 && k <= ran), "max_iter {max_iter}: checks at {history:?}");
    }
}

/// A GPU solve runs its first batch before it may stop, as the CPU's sweeps run before their
/// first check: a warm start that meets tol is not handed back unchanged (on an H200 the pile at
/// rest under the natural map sank 11× deeper than on the CPU when it was), and a converged
/// batch is returned even where its f32 error lies above the warm start's, as the CPU returns
/// its converged last iterate.
#[test]
fn a_gpu_solve_sweeps_before_it_stops_even_from_a_warm_start_that_meets_tol() {
    let Some(ctx) = common::gpu_context() else { return };
    let p = lattice_packing(30, 15, 0.5, 2);
    let loose = solve(&p, SolverKind::Nlgs, &SolverOptions { tol: 1e-3, ..Default::default() }, None);
    assert!(loose.converged, "{}", loose.stop_reason);
    let opts = SolverOptions { tol: 1e-2, anderson: 0, ..Default::default() };
    for kind in [SolverKind::Nlgs, SolverKind::Jacobi, SolverKind::Pcpg] {
        let run = moreau::gpu::solve(&ctx, &p, kind, &opts, Some(&loose.r)).unwrap();
        assert!(run.converged && run.iterations >= 1, "{kind}: {} iterations ({})", run.iterations, run.stop_reason);
        // What comes back is the batch's, not the warm start in f32.
        let scale = loose.r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let moved = run.r.iter().zip(&loose.r).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(moved > 1e-5 * scale, "{kind}: moved {moved:.2e} of {scale:.2e}");
    }
}

/// The step-velocity test on the GPU holds every contact to tol × g h, as on the CPU: the stack
/// beside a grain sliding at 3 m/s (whose 3 m/s would be the velocity test's scale), colour
/// sweeps and the work list's thresholded sweeps, each contact's residual checked in f64 from
/// what the GPU returns.
#[test]
fn the_gpu_holds_every_contact_to_a_step_of_gravity_under_the_step_velocity_test() {
    use moreau::solvers::{Ordering, StopCriterion};
    let Some(ctx) = common::gpu_context() else { return };
    let (p, g_h, tol) = (common::stack_beside_a_sliding_grain(), 9.81e-3, 1e-2);
    for ordering in [Ordering::Colours, Ordering::Worklist] {
        let opts = SolverOptions {
            tol,
            max_iter: 20_000,
            criterion: StopCriterion::StepVelocity,
            ordering,
            anderson: 0,
            ..Default::default()
        };
        let run = moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &opts, None).unwrap();
        assert!(run.converged, "{ordering:?}: {}", run.stop_reason);
        let worst = common::worst_contact_residual(&p, &run.r, false) / g_h;
        assert!(worst <= tol, "{ordering:?}: a contact at {worst:e} of g h");
    }
}

/// The 400-disk pile's 120th step (595 contacts) for free velocities up to 2 % off, and its
/// answer to 1e-7 before: a step's warm start.
fn pile_step_warm_start() -> (ContactProblem, Vec<f64>) {
    use moreau::solvers::StopCriterion;
    let s = moreau::scene::load(Path::new("scenes/pile.toml")).unwrap();
    let mut sim = moreau::stepping::Simulation::new(s.world, s.settings).unwrap();
    sim.keep_problems(true);
    for _ in 0..120 {
        sim.step().unwrap();
    }
    let mut p = sim.last_problem().expect("contacts").clone();
    let exact =
        SolverOptions { tol: 1e-7, max_iter: 100_000, criterion: StopCriterion::Velocity, ..Default::default() };
    let r0 = solve(&p, SolverKind::Nlgs, &exact, None).r;
    p.q.iter_mut().enumerate().for_each(|(k, q)| *q *= 1.0 + 0.02 * ((k as f64) * 0.7).sin());
    (p, r0)
}

/// The work list's thresholded sweeps count their iterations as the CPU's list does, in sweeps'
/// worth of contact updates, so `max_iter` bounds the same work on both devices: a pile step's
/// answer for free velocities 2 % off is met again in more rounds than `max_iter` and fewer
/// sweeps' worth, where counting rounds stopped it at `max_iter`; colour sweeps with no
/// threshold count rounds; a solve held to one sweep's worth stops there.
#[test]
fn the_gpu_work_list_counts_sweeps_worth_of_updates_as_the_cpu_list_does() {
    use moreau::gpu::driver::ROUNDS_PER_COUNTED_ITERATION;
    use moreau::solvers::{Ordering, StopCriterion};
    let Some(ctx) = common::gpu_context() else { return };
    let (p, r0) = pile_step_warm_start();
    // (The f32 sweeps stall near 3.5e-4 of the velocity test here.)
    let listed = |max_iter| SolverOptions {
        tol: 5e-4,
        max_iter,
        criterion: StopCriterion::Velocity,
        ordering: Ordering::Worklist,
        anderson: 0,
        ..Default::default()
    };
    let run = moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &listed(5), Some(&r0)).unwrap();
    let rounds = run.gpu_checks.rounds;
    assert!(run.converged && run.iterations <= 5, "{} ({} sweeps' worth)", run.stop_reason, run.iterations);
    assert!(rounds > 5 && rounds > run.iterations, "{rounds} rounds, {} sweeps' worth", run.iterations);
    assert!(run.gpu_checks.counted);
    assert!(
        run.notes.iter().any(|n| n.contains("contact updates") && n.contains(&format!("in {rounds} rounds"))),
        "{:?}",
        run.notes
    );
    // Colour sweeps with no threshold count rounds, as before.
    let swept = SolverOptions { ordering: Ordering::Colours, ..listed(5) };
    let plain = moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &swept, Some(&r0)).unwrap();
    assert_eq!(plain.gpu_checks.rounds, plain.iterations);
    assert!(!plain.gpu_checks.counted);
    // A bound of one sweep's worth: the updates stop there, the rounds by 32 (with a batch).
    let short =
        moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &SolverOptions { tol: 1e-9, ..listed(1) }, Some(&r0)).unwrap();
    assert!(
        !short.converged && short.gpu_checks.rounds <= ROUNDS_PER_COUNTED_ITERATION + 16,
        "{} rounds",
        short.gpu_checks.rounds
    );
}

/// Near tol a GPU solve checks every √(4 × rounds run), from 16 to 128 rounds: the batch queued
/// past the check that stops it, dropped, stays that small against the rounds run (a batch that
/// doubled while the error stayed near tol ran the 10,000-disk pile at rest to twice the rounds
/// it needed). A pile step's warm start for free velocities 2 % off, under the work list's
/// thresholded sweeps and colour sweeps, and a lattice from zero.
#[test]
fn a_gpu_solve_near_tol_queues_past_its_last_check_a_batch_small_against_its_rounds() {
    use moreau::gpu::driver::near_tol_batch;
    use moreau::solvers::{Ordering, StopCriterion};
    let Some(ctx) = common::gpu_context() else { return };
    let (p, r0) = pile_step_warm_start();
    let warm = |ordering, tol| SolverOptions {
        tol,
        max_iter: 20_000,
        criterion: StopCriterion::Velocity,
        ordering,
        anderson: 0,
        ..Default::default()
    };
    let lattice = lattice_packing(20, 10, 0.3, 3);
    let runs = [
        ("work list", &p, warm(Ordering::Worklist, 5e-4), Some(&r0[..])),
        ("colour sweeps", &p, warm(Ordering::Colours, 5e-4), Some(&r0[..])),
        ("lattice", &lattice, SolverOptions { tol: 1e-5, max_iter: 20_000, ..Default::default() }, None),
    ];
    for (name, p, opts, r0) in runs {
        let run = moreau::gpu::solve(&ctx, p, SolverKind::Nlgs, &opts, r0).unwrap();
        let (rounds, dropped) = (run.gpu_checks.rounds, run.gpu_checks.discarded);
        assert!(run.converged, "{name}: {}", run.stop_reason);
        assert!(dropped > 0 && dropped <= near_tol_batch(rounds), "{name}: {dropped} dropped after {rounds} rounds");
    }
}

/// Block sweeps (`block_sweeps`: each workgroup sweeps a block of 4,096 contacts several times
/// a dispatch) solve what colour sweeps solve, judged in f64 on the CPU, in fewer dispatches: a
/// lattice of about 5,000 contacts (two blocks), plain and as the work list's thresholded sweeps.
/// (Dispatches counted from the iterations: the process-wide counters see the other tests' GPU
/// work.)
#[test]
fn block_sweeps_solve_what_colour_sweeps_solve_in_fewer_dispatches() {
    use moreau::solvers::{Ordering, StopCriterion};
    let Some(ctx) = common::gpu_context() else { return };
    let p = lattice_packing(72, 36, 0.3, 1);
    let Delassus::MatrixFree(op) = &p.w else { unreachable!() };
    let colouring = op.colouring();
    let block = moreau::gpu::colouring::BLOCK_CONTACTS;
    let block_colours = BlockColouring::new(&MatrixFreeLayout::new(op), colouring, block).blocks.n_colours();
    assert!(p.n_contacts() > block && block_colours < colouring.n_colours());
    for (criterion, ordering, tol) in
        [(StopCriterion::Natural, Ordering::Forward, 1e-5), (StopCriterion::Velocity, Ordering::Worklist, 1e-4)]
    {
        let dispatches = [0, 4].map(|block_sweeps| {
            let opts =
                SolverOptions { tol, max_iter: 100_000, criterion, ordering, block_sweeps, ..Default::default() };
            let run = moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &opts, None).unwrap();
            let what = format!("{ordering:?}, block sweeps {block_sweeps}");
            assert!(run.converged, "{what}: {}", run.stop_reason);
            let judged = moreau::solvers::stopping::JudgedMeasure::new(&p, criterion);
            let (natural, u) = moreau::problem::residual::error_of(&p, &run.r);
            let error = judged.of(&p, &run.r, &u, natural);
            assert!(error <= tol, "{what}: f64 error {error:e}");
            let noted = run.notes.iter().any(|n| n.starts_with("block sweeps: 2 blocks"));
            assert_eq!(noted, block_sweeps > 0, "{what}: {:?}", run.notes);
            // The sweeps' dispatches (the checks' are the same per iteration on both): rounds,
            // which the work list's colour sweeps count apart from their iterations (updates).
            assert!(run.gpu_checks.rounds >= run.iterations, "{what}: {} rounds", run.gpu_checks.rounds);
            run.gpu_checks.rounds * if block_sweeps > 0 { block_colours } else { colouring.n_colours() }
        });
        assert!(dispatches[1] < dispatches[0], "{ordering:?}: {dispatches:?} dispatches");
    }
}

/// Contacts numbered in no spatial order make every block touch every other: such blocks would
/// need more dispatches a round than the contacts' colours, and the GPU sweeps by colours and
/// says why. A lattice of about 51,000 contacts (13 blocks), numbered in space and shuffled.
#[test]
fn blocks_of_contacts_numbered_in_no_spatial_order_give_way_to_colour_sweeps() {
    use rand::seq::SliceRandom;
    let Some(ctx) = common::gpu_context() else { return };
    let p = lattice_packing(160, 160, 0.3, 1);
    let Delassus::MatrixFree(op) = &p.w else { unreachable!() };
    let mut order: Vec<usize> = (0..p.n_contacts()).collect();
    order.shuffle(&mut rand::rngs::SmallRng::seed_from_u64(5));
    let q: Vec<f64> = order.iter().flat_map(|&a| [p.q[2 * a], p.q[2 * a + 1]]).collect();
    let mu: Vec<f64> = order.iter().map(|&a| p.mu[a]).collect();
    let shuffled = ContactProblem::new(Delassus::MatrixFree(op.permuted(&order)), q, mu).unwrap();
    let opts = SolverOptions { tol: 1e-4, max_iter: 2, block_sweeps: 4, ..Default::default() };
    for (name, problem, blocks) in [("in space", &p, true), ("shuffled", &shuffled, false)] {
        let run = moreau::gpu::solve(&ctx, problem, SolverKind::Nlgs, &opts, None).unwrap();
        let noted = |start: &str| run.notes.iter().any(|n| n.starts_with(start));
        assert_eq!(noted("block sweeps: 13 blocks"), blocks, "{name}: {:?}", run.notes);
        assert_eq!(noted("block sweeps not used, its blocks would need more dispatches"), !blocks, "{name}");
    }
}

/// A simulation stepped with block sweeps keeps the CPU run's physics: `scenes/pile.toml` (400
/// disks falling into a box, NLGS at tol 1e-4 with Anderson 5), 60 steps on the CPU and on the
/// GPU with 4 sweeps of each block a dispatch. Every GPU step converges (judged in f64) and the
/// largest overlap stays within 25 % of the CPU run's (the trajectories part once the f32
/// solves differ).
#[test]
fn a_pile_stepped_with_block_sweeps_keeps_the_cpu_runs_physics() {
    let Some(ctx) = common::gpu_context() else { return };
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pile.toml")).unwrap();
    let run = |gpu: Option<GpuContext>| {
        let mut s = moreau::scene::parse(&text, Path::new("pile.toml")).unwrap();
        s.settings.options.block_sweeps = 4;
        let mut sim = moreau::stepping::Simulation::new(s.world, s.settings).unwrap();
        if let Some(ctx) = gpu {
            sim.set_backend(moreau::backend::Backend::gpu(ctx)).unwrap();
        }
        (0..60).map(|_| sim.step().unwrap()).collect::<Vec<_>>()
    };
    let (cpu, gpu) = (run(None), run(Some(ctx)));
    for r in &gpu {
        assert!(r.converged && r.error <= 1e-4, "step {}: {}", r.step, r.stop_reason);
    }
    assert!(gpu.iter().any(|r| r.gpu_iterations > 0), "no step swept on the GPU");
    let worst = |rs: &[moreau::stepping::StepReport]| rs.iter().map(|r| r.max_penetration).fold(0.0, f64::max);
    let (c, g) = (worst(&cpu), worst(&gpu));
    assert!(c > 0.0 && g <= 1.25 * c, "largest overlap: GPU {g:.3e} m, CPU {c:.3e} m");
}

/// The velocity test on the GPU is the CPU's: on a column of heavy grains the natural-map error
/// is met long before the worst contact is; asked for the velocity test, the GPU stops only
/// when the f64 velocity measure of what it returns is within tol, as the CPU does.
#[test]
fn the_gpu_stops_on_the_velocity_test_as_the_cpu_does() {
    use moreau::problem::generate::heavy_column;
    use moreau::problem::residual::velocity_error;
    use moreau::solvers::StopCriterion;
    let Some(ctx) = common::gpu_context() else { return };
    let p = heavy_column(30, 100.0, 0.5);
    let diag = p.w.diag_blocks();
    let worst = |r: &[f64], u: &[f64]| velocity_error(&diag, &p.q, &p.mu, r, u);
    for kind in [SolverKind::Nlgs, SolverKind::Pcpg] {
        let run = |criterion| {
            let opts = SolverOptions { tol: 1e-4, max_iter: 200_000, criterion, ..SolverOptions::default() };
            moreau::gpu::solve(&ctx, &p, kind, &opts, None).unwrap()
        };
        let (natural, velocity) = (run(StopCriterion::Natural), run(StopCriterion::Velocity));
        eprintln!(
            "{kind}: natural test {} its, velocity measure {:.2e}; velocity test {} its, {:.2e}",
            natural.iterations,
            worst(&natural.r, &natural.u),
            velocity.iterations,
            velocity.judged_error
        );
        assert!(velocity.converged, "{kind}: {}", velocity.stop_reason);
        assert_eq!(velocity.judged_error, worst(&velocity.r, &velocity.u), "{kind}: judged in f64 on what it returns");
        assert!(velocity.judged_error <= 1e-4);
        // NLGS meets the natural test thousands of sweeps before the velocity test (1e-2 against
        // 1e-4). PCPG converges within a few dozen iterations either way: whether its natural
        // stop misses the velocity test depends on where the checks fall, not on the criterion.
        if kind == SolverKind::Nlgs {
            assert!(worst(&natural.r, &natural.u) > 1e-4, "{kind}: the natural test alone should miss it");
            assert!(velocity.iterations > natural.iterations, "{kind}");
        }
        assert!(velocity.iterations >= natural.iterations, "{kind}");
    }
}

/// A GPU solve says how it checked its error: a converged one was judged in f64 at least once,
/// never more often than it estimated, and at most once per batch of 8 iterations; a CPU solve
/// reports no GPU check. `moreau bench --scene` times the GPU's sweep alone beside its solve.
#[test]
fn a_gpu_solve_counts_its_checks_and_the_scene_bench_times_its_sweep() {
    let Some(ctx) = common::gpu_context() else { return };
    let p = lattice_packing(20, 10, 0.3, 3);
    let opts = SolverOptions { tol: 1e-5, max_iter: 20_000, ..SolverOptions::default() };
    let gpu = moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &opts, None).unwrap();
    assert!(gpu.converged, "{}", gpu.stop_reason);
    let c = gpu.gpu_checks;
    assert!(c.judged >= 1 && c.estimates >= c.judged && c.judge_seconds > 0.0, "{c:?}");
    assert!(8 * c.estimates <= gpu.iterations + 8, "{c:?} for {} iterations", gpu.iterations);
    let said = format!("{} error estimates on the GPU, {} of them judged in f64", c.estimates, c.judged);
    assert!(gpu.notes.iter().any(|n| n.starts_with(&said)), "{:?}", gpu.notes);
    let cpu = solve(&p, SolverKind::Nlgs, &opts, None);
    assert_eq!((cpu.gpu_checks.estimates, cpu.gpu_checks.judged), (0, 0));
    assert_eq!((gpu.gpu_iterations(), cpu.gpu_iterations()), (gpu.iterations, 0));

    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pile.toml");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_moreau"))
        .args(["bench", "--steps", "3", "--sweeps", "4", "--threads-list", "1", "--scene"])
        .arg(&scene)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let row = out.lines().skip_while(|l| !l.contains("NLGS sweep ms (kernels only)")).nth(2).expect("a GPU row");
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let (sweep_ms, colours, dispatch_ms): (f64, usize, f64) =
        (cells[3].parse().unwrap(), cells[4].parse().unwrap(), cells[5].parse().unwrap());
    assert!(sweep_ms > 0.0 && sweep_ms.is_finite() && dispatch_ms > 0.0 && colours >= 2, "{row}");
    // pile.toml mixes over 5 sweeps: a second row solves with the mixer.
    let mixed = out.lines().skip_while(|l| !l.contains("NLGS sweep ms (kernels only)")).nth(3).expect("a mixed row");
    assert!(mixed.starts_with("| 5 |") && cells[1] == "0", "{row}\n{mixed}");
    // And the mixer's stages are timed one by one, each a positive time.
    let stages =
        out.lines().find(|l| l.starts_with("Anderson 5 on the GPU, kernels only")).expect("the mixer's stages");
    let times: Vec<f64> = (stages.split_once("):").expect("timed stages").1)
        .split([',', ';'])
        .filter_map(|part| part.split_whitespace().find_map(|word| word.parse::<f64>().ok()))
        .collect();
    assert!(times.len() == 5 && times.iter().all(|t| *t > 0.0 && t.is_finite()), "{stages}");
}

/// `moreau bench` on lattices times the NLGS sweep on both devices beside the product and the
/// Jacobi iteration, and its update rates are the contacts over those times.
#[test]
fn the_lattice_bench_times_nlgs_sweeps_on_both_devices() {
    if common::gpu_context().is_none() {
        return;
    }
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_moreau"))
        .args(["bench", "--sizes", "1000", "--repeats", "3"])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let header = out.lines().find(|l| l.starts_with("| contacts |")).expect("a header");
    let row = out.lines().find(|l| l.starts_with("| 1001 |")).expect("the 1,001-contact row");
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    assert_eq!(header.split('|').count(), cells.len(), "{header}\n{row}");
    let micros = |cell: &str| cell.split_whitespace().next().and_then(|v| v.parse::<f64>().ok()).expect(cell);
    let (cpu_sweep, gpu_sweep) = (micros(cells[8]), micros(cells[9]));
    let colours: usize = cells[9].split(['(', ')']).nth(1).and_then(|c| c.parse().ok()).expect(cells[9]);
    assert!(cpu_sweep > 0.0 && gpu_sweep > 0.0 && colours >= 2, "{row}");
    let rates: Vec<f64> = cells[12].split(',').map(|v| v.trim().parse().expect(v)).collect();
    for (rate, micros) in rates.iter().zip([cpu_sweep, gpu_sweep]) {
        let expected = 1001.0 / (micros * 1e-6);
        assert!((rate / expected - 1.0).abs() < 0.02, "{rate} against {expected}: {row}");
    }
}

#[test]
fn a_solver_the_gpu_lacks_is_a_clear_error() {
    let Some(ctx) = common::gpu_context() else { return };
    let p = random_small(2, 0.3, 1);
    let e = moreau::gpu::solve(&ctx, &p, SolverKind::Latin, &SolverOptions::default(), None).unwrap_err();
    assert!(e.to_string().contains("no latin solver"), "{e}");
    let maxm = SolverOptions { criterion: moreau::solvers::StopCriterion::Maxm, ..SolverOptions::default() };
    let e = moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &maxm, None).unwrap_err();
    assert!(e.to_string().contains("maxm"), "{e}");
}

/// A scene stepped with its solves on the GPU.
/// Steps `sim` `steps` times, each step converged and some of its iterations on the GPU.
fn steps_converged_on_the_gpu(sim: &mut moreau::stepping::Simulation, steps: usize) {
    let mut on_gpu = 0;
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged, "{r:?}");
        on_gpu += r.gpu_iterations;
    }
    assert!(on_gpu > 0, "no iteration ran on the GPU");
}

fn gpu_simulation(ctx: GpuContext, toml: &str) -> (moreau::stepping::Simulation, usize) {
    let s = moreau::scene::parse(toml, Path::new("gpu_scene.toml")).unwrap();
    let steps = s.steps;
    let mut sim = moreau::stepping::Simulation::new(s.world, s.settings).unwrap();
    sim.set_backend(moreau::backend::Backend::gpu(ctx)).unwrap();
    (sim, steps)
}

/// The position projection of a GPU-stepped simulation sweeps on the GPU and separates the
/// grains as the CPU's does: the 400-disk pile with 4 solver sweeps a step, so that the θ-update
/// leaves overlaps to project, 40 steps on each device. Tolerance: the GPU run's largest overlap
/// within 25 % of the CPU run's (the trajectories part once the f32 solves differ).
#[test]
fn the_position_projection_sweeps_on_the_gpu_and_separates_as_on_the_cpu() {
    let Some(ctx) = common::gpu_context() else { return };
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pile.toml")).unwrap();
    let text = text.replace("max_iter = 5000", "max_iter = 4");
    assert!(text.contains("max_iter = 4"), "scenes/pile.toml changed its max_iter");
    let run = |gpu: Option<GpuContext>| {
        let s = moreau::scene::parse(&text, Path::new("pile.toml")).unwrap();
        let mut sim = moreau::stepping::Simulation::new(s.world, s.settings).unwrap();
        if let Some(ctx) = gpu {
            sim.set_backend(moreau::backend::Backend::gpu(ctx)).unwrap();
        }
        (0..40).map(|_| sim.step().unwrap()).collect::<Vec<_>>()
    };
    let (cpu, gpu) = (run(None), run(Some(ctx)));
    let worst = |rs: &[moreau::stepping::StepReport]| rs.iter().map(|r| r.max_penetration).fold(0.0, f64::max);
    // Where at most 1 % of the contacts went deep the CPU's local pass projects them, no sweeps;
    // here the grains fall in and far more do.
    let projected: Vec<_> = gpu.iter().filter(|r| 100 * r.projected > r.contacts).collect();
    assert!(projected.len() >= 10, "only {} GPU steps needed the projection's sweeps", projected.len());
    // At least 100 projection sweeps (one dispatch or more each) beside the solve's 4.
    for r in &projected {
        assert!(
            r.gpu_dispatches > 100,
            "step {}: {} dispatches: the projection ran on the CPU",
            r.step,
            r.gpu_dispatches
        );
        assert!(r.projection_seconds > 0.0);
    }
    assert!(cpu.iter().all(|r| r.gpu_dispatches == 0 && r.gpu_iterations == 0 && r.gpu_checks.estimates == 0));
    // Every GPU solve estimated its error at least once, and judged in f64 no more often.
    let checks: Vec<_> = gpu.iter().filter(|r| r.iterations > 0).map(|r| r.gpu_checks).collect();
    assert!(!checks.is_empty() && checks.iter().all(|c| c.estimates >= 1 && c.judged <= c.estimates), "{checks:?}");
    // Four sweeps a step meet no plateau: every iteration of a GPU step ran on the GPU.
    let split: Vec<(usize, usize)> = gpu.iter().map(|r| (r.gpu_iterations, r.iterations)).collect();
    assert!(split.iter().all(|(g, i)| g == i) && split.iter().any(|&(g, _)| g > 0), "{split:?}");
    let (c, g) = (worst(&cpu), worst(&gpu));
    assert!(c > 0.0 && g <= 1.25 * c, "largest overlap: GPU {g:.3e} m, CPU {c:.3e} m");
}

#[test]
fn scenes_stepped_on_the_gpu_keep_the_cpu_physics_checks() {
    let Some(ctx) = common::gpu_context() else { return };
    // A block on a 30° incline with μ = 0.3 slides at g (sin θ − μ cos θ), within 1 %.
    let t = 30f64.to_radians();
    let (dir, n) = ((t.cos(), -t.sin()), (t.sin(), t.cos()));
    let incline = format!(
        r#"
effects = ["gravity", "friction"]
[time]
step = 1e-3
steps = 300
[solver]
name = "jacobi"
tol = 1e-6
[contact]
friction = 0.3
[[material]]
name = "m"
density = 1000.0
[[wall]]
segment = [[0.0, 0.0], [{}, {}]]
[[body]]
disk = {{ center = [{}, {}], radius = 0.1 }}
"#,
        20.0 * dir.0,
        20.0 * dir.1,
        2.0 * dir.0 + 0.1 * n.0,
        2.0 * dir.1 + 0.1 * n.1
    );
    let (mut sim, steps) = gpu_simulation(ctx, &incline);
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged, "step {}: {}", r.step, r.stop_reason);
    }
    let a = (sim.velocity(0).x * dir.0 + sim.velocity(0).y * dir.1) / sim.time();
    let expected = 9.81 * (t.sin() - 0.3 * t.cos());
    assert!((a - expected).abs() <= 0.01 * expected, "a = {a}, expected {expected}");
    // A column of five disks stays at rest.
    let Some(ctx) = common::gpu_context() else { return };
    let mut column = String::from(
        "effects = [\"gravity\", \"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 200\n[solver]\nname = \"jacobi\"\ntol = 1e-6\n[contact]\nfriction = 0.5\n[[material]]\nname = \"m\"\ndensity = 1.0\n[[wall]]\nsegment = [[-2.0, 0.0], [2.0, 0.0]]\n",
    );
    for k in 0..5 {
        column.push_str(&format!("[[body]]\ndisk = {{ center = [0.0, {}], radius = 0.5 }}\n", 0.5 + k as f64));
    }
    let (mut sim, steps) = gpu_simulation(ctx, &column);
    let top = sim.position(4);
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged && r.max_penetration < 1e-6, "{r:?}");
    }
    assert!(sim.position(4).distance(top) < 1e-6, "the column moved by {}", sim.position(4).distance(top));
    // A disk on a belt (a fixed plate moving at 1 m/s, μ = 0.2) rolls on at a third of its speed
    // once its bottom point moves with the belt (0.17 s), as on the CPU (within 1e-4 m/s).
    let Some(ctx) = common::gpu_context() else { return };
    let belt = "effects = [\"gravity\", \"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 300\n[solver]\ntol = 1e-6\n\
                [contact]\nfriction = 0.2\n[[material]]\nname = \"m\"\ndensity = 1000.0\n[[body]]\npolygon = { center = [0.0, -0.05], \
                vertices = [[-5.0, -0.05], [5.0, -0.05], [5.0, 0.05], [-5.0, 0.05]] }\nfixed = true\nvelocity = [1.0, 0.0]\n\
                [[body]]\ndisk = { center = [0.0, 0.1], radius = 0.1 }\n";
    let (mut sim, steps) = gpu_simulation(ctx, belt);
    steps_converged_on_the_gpu(&mut sim, steps);
    assert!((sim.velocity(1).x - 1.0 / 3.0).abs() < 1e-4 && sim.velocity(0) == moreau::DVec2::X, "{}", sim.velocity(1));
}

/// A disk rolls down a 20° slope (μ 0.5) while a dimer, two overlapping disks as one clump,
/// rests on it: on the software adapter as on the CPU. Tolerance: the disk's speed within
/// 0.5 % of ⅔ g sin θ t, the dimer still to 1e-6 m/s (the solves finish in f64 on the CPU).
#[test]
fn a_clump_rests_on_a_slope_on_the_gpu_as_on_the_cpu() {
    let Some(ctx) = common::gpu_context() else { return };
    let (mut sim, steps) = gpu_simulation(ctx, &common::disk_and_dimer_on_a_slope(20.0));
    steps_converged_on_the_gpu(&mut sim, steps);
    let t = 20f64.to_radians();
    let rolling = 2.0 / 3.0 * 9.81 * t.sin() * sim.time();
    let v = sim.velocity(0).dot(moreau::DVec2::new(t.cos(), -t.sin()));
    assert!((v - rolling).abs() < 5e-3 * rolling, "disk {v} m/s, rolling {rolling} m/s");
    assert!(sim.velocity(1).length() < 1e-6, "the dimer moves at {}", sim.velocity(1));
}

/// A block held along x at 1 m/s on a fixed floor (`hold_velocity`), pressed by 400 N, μ 0.3,
/// its steps solved on the software adapter: it keeps 1 m/s to the bit and rests on the floor,
/// which pushes back its weight plus the force and drags on it with μ times that. Tolerance: 1e-6
/// of the load, as on the CPU (the solves finish in f64 there).
#[test]
fn a_block_held_along_x_slides_on_the_gpu_as_on_the_cpu() {
    let Some(ctx) = common::gpu_context() else { return };
    let (mut sim, _) = gpu_simulation(ctx, &common::held_block("force = [0.0, -400.0]"));
    let (load, h) = (100.0 * 9.81 + 400.0, 1e-3);
    let mut on_gpu = 0;
    for k in 1..=100 {
        let report = sim.step().unwrap();
        assert!(report.converged, "step {k}: {report:?}");
        on_gpu += report.gpu_iterations;
        assert_eq!(sim.velocity(1).x, 1.0, "step {k}");
        assert!((sim.position(1).y - 0.1).abs() < 1e-6, "step {k}: y {}", sim.position(1).y);
        let on_block = |c: &moreau::stepping::ContactState| if c.contact.i == 1 { c.force(h) } else { -c.force(h) };
        let force: moreau::DVec2 = sim.contacts().iter().map(on_block).sum();
        assert!((force.y - load).abs() < 1e-6 * load, "step {k}: floor pushes {force} against {load}");
        assert!((force.x + 0.3 * load).abs() < 1e-6 * load, "step {k}: friction {}", force.x);
    }
    assert!(on_gpu > 0, "no iteration ran on the GPU");
}

/// Buffers are taken from the context's pool and written in place: a solve after others of
/// other sizes gives the same bits as on a fresh context, and creates no buffer once the pool
/// holds the sizes it needs.
#[test]
fn pooled_buffers_carry_nothing_from_one_solve_to_the_next() {
    let Some(ctx) = common::gpu_context() else { return };
    let (a, b) = (lattice_packing(24, 10, 0.3, 4), lattice_packing(40, 16, 0.5, 5));
    let opts = SolverOptions { tol: 1e-300, max_iter: 40, ..Default::default() };
    let bits = |r: &[f64]| r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for kind in [SolverKind::Nlgs, SolverKind::Pcpg, SolverKind::Apgd, SolverKind::Jacobi] {
        let first = moreau::gpu::solve(&ctx, &a, kind, &opts, None).unwrap();
        moreau::gpu::solve(&ctx, &b, kind, &opts, None).unwrap();
        let created = ctx.pool.created();
        let again = moreau::gpu::solve(&ctx, &a, kind, &opts, None).unwrap();
        assert_eq!(bits(&first.r), bits(&again.r), "{kind}: a solve after another differs");
        assert_eq!(ctx.pool.created(), created, "{kind}: buffers created for a size the pool holds");
    }
}

/// A pile stepped with its solves on the GPU: each step's colouring is repaired from the last,
/// and after the first steps a step creates no GPU buffer.
#[test]
fn a_gpu_stepped_pile_reuses_its_buffers_and_its_colouring() {
    let Some(ctx) = common::gpu_context() else { return };
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pile.toml")).unwrap();
    let (mut sim, _) = gpu_simulation(ctx, &text);
    sim.keep_problems(true);
    let mut created = Vec::new();
    let mut last: Option<std::collections::HashMap<_, u32>> = None;
    let (mut kept, mut new) = (0, 0);
    for _ in 0..40 {
        let r = sim.step().unwrap();
        assert!(r.error.is_finite(), "{r:?}");
        created.push(sim.backend().gpu_context().unwrap().pool.created());
        if let Some(p) = sim.last_problem() {
            let Delassus::MatrixFree(op) = &p.w else { panic!("a step's problem is matrix-free") };
            let c = op.colouring_if_built().expect("the GPU sweep coloured the graph");
            assert!(c.is_proper(Colouring::neighbours_in(&p.w)));
            // Contacts carried over keep their colour class (the colouring is repaired, not
            // rebuilt): one old colour maps to one new colour.
            let now: std::collections::HashMap<_, u32> =
                sim.contacts().iter().zip(c.colour_of_each()).map(|(s, c)| (s.contact.key(), c)).collect();
            if let Some(last) = &last {
                let mut class = std::collections::HashMap::new();
                for (key, colour) in &now {
                    match last.get(key) {
                        Some(old) => {
                            kept += 1;
                            assert_eq!(*class.entry(*old).or_insert(*colour), *colour, "a kept contact changed class");
                        }
                        None => new += 1,
                    }
                }
            }
            last = Some(now);
        }
    }
    // Measured: 15,291 kept, 778 new.
    assert!(kept > 10_000 && new > 0, "{kept} contacts kept, {new} new");
    // The first step creates what a step uses; while the grains land the contacts grow into new
    // capacities, then a step finds nearly every size pooled: over the last 20 steps, fewer
    // buffers are created than one step uses (without the pool: 20 steps' worth).
    assert!(created[39] - created[19] < created[0], "buffers created by step: {created:?}");
}

fn floats(bytes: &[u8]) -> Vec<f32> {
    bytemuck::cast_slice::<u8, f32>(bytes).to_vec()
}

#[test]
fn reductions_cpg_and_apgd_stages_match_their_mirrors() {
    let Some(ctx) = common::gpu_context() else { return };
    let mut rng = rand::rngs::SmallRng::seed_from_u64(5);
    use moreau::gpu::kernels::Kernels;
    // Deterministic dot products, on sizes around the chunk boundaries.
    for n in [1usize, 255, 1024, 1025, 5000, 70_000] {
        let a: Vec<f32> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let b: Vec<f32> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let parts = cpu::reduce_dot::reduce_dot(&a, &b);
        let len = [n as u32, 0, 0, 0];
        let out = stages::run_raw(
            &ctx,
            |k: &Kernels| &k.reduce_dot,
            &[bytemuck::cast_slice(&a), bytemuck::cast_slice(&b), bytemuck::cast_slice(&vec![0.0f32; parts.len()])],
            &[bytemuck::cast_slice(&len)],
            parts.len() as u32,
            &[2],
        )
        .unwrap();
        let gpu_parts = floats(&out[0]);
        let scale: f32 = a.iter().zip(&b).map(|(x, y)| (x * y).abs()).sum::<f32>().max(1.0);
        for (g, c) in gpu_parts.iter().zip(&parts) {
            assert!((g - c).abs() <= 1e-5 * scale, "reduce_dot n = {n}: {g} vs {c}");
        }
        let job = [parts.len() as u32, 3, 0, 0];
        let out = stages::run_raw(
            &ctx,
            |k: &Kernels| &k.reduce_final,
            &[bytemuck::cast_slice(&parts), bytemuck::cast_slice(&[0.0f32; 8])],
            &[bytemuck::cast_slice(&job)],
            1,
            &[1],
        )
        .unwrap();
        let total = floats(&out[0])[3];
        let exact: f64 = a.iter().zip(&b).map(|(x, y)| *x as f64 * *y as f64).sum();
        assert!((total - cpu::reduce_final::reduce_final(&parts)).abs() <= 1e-5 * scale, "reduce_final n = {n}");
        assert!((total as f64 - exact).abs() <= 1e-5 * scale as f64, "dot n = {n}: {total} vs {exact}");
        // The same inputs give the same bits: the reduction does not depend on scheduling.
        let again = stages::run_raw(
            &ctx,
            |k: &Kernels| &k.reduce_dot,
            &[bytemuck::cast_slice(&a), bytemuck::cast_slice(&b), bytemuck::cast_slice(&vec![0.0f32; parts.len()])],
            &[bytemuck::cast_slice(&len)],
            parts.len() as u32,
            &[2],
        )
        .unwrap();
        assert_eq!(floats(&again[0]), gpu_parts);
    }
    // The CPG stages on random states, every status and sign.
    let nc = 3000;
    let pair = |rng: &mut rand::rngs::SmallRng| {
        [rng.gen_range(-1.0f32..1.0), if rng.gen_bool(0.2) { 0.0 } else { rng.gen_range(-1.0f32..1.0) }]
    };
    let r: Vec<[f32; 2]> = (0..nc).map(|_| pair(&mut rng)).collect();
    let d: Vec<[f32; 2]> = (0..nc).map(|_| pair(&mut rng)).collect();
    let u: Vec<[f32; 2]> = (0..nc).map(|_| pair(&mut rng)).collect();
    let w0: Vec<[f32; 2]> = (0..nc).map(|_| pair(&mut rng)).collect();
    let scale: Vec<[f32; 2]> = (0..nc).map(|_| [rng.gen_range(0.5..2.0), rng.gen_range(0.0..2.0)]).collect();
    let mu: Vec<f32> = (0..nc).map(|k| if k % 7 == 0 { 0.0 } else { rng.gen_range(0.1..1.0) }).collect();
    let status: Vec<u32> = (0..nc).map(|k| (k % 4) as u32).collect();
    let mut scalars = [0.0f32; 16];
    scalars[6] = 0.7; // α
    scalars[7] = -0.3; // β
    scalars[8] = 1.0; // restart
    let g = (nc as u32).div_ceil(64);
    let b = |x: &[[f32; 2]]| bytemuck::cast_slice::<[f32; 2], u8>(x).to_vec();
    let out = stages::run_raw(
        &ctx,
        |k: &Kernels| &k.cpg_update,
        &[
            bytemuck::cast_slice(&scalars),
            &b(&d),
            bytemuck::cast_slice(&mu),
            &b(&r),
            bytemuck::cast_slice(&status),
            bytemuck::cast_slice(&vec![0.0f32; nc]),
        ],
        &[],
        g,
        &[3, 4, 5],
    )
    .unwrap();
    let (mut r_cpu, mut st_cpu, mut ch_cpu) = (r.clone(), status.clone(), vec![0.0f32; nc]);
    cpu::cpg_update::cpg_update(&scalars, &d, &mu, &mut r_cpu, &mut st_cpu, &mut ch_cpu);
    assert_close(&floats(&out[0]), r_cpu.as_flattened(), "cpg_update r");
    assert_eq!(bytemuck::cast_slice::<u8, u32>(&out[1]), &st_cpu[..], "cpg_update status");
    assert_eq!(floats(&out[2]), ch_cpu, "cpg_update changed");
    let out = stages::run_raw(
        &ctx,
        |k: &Kernels| &k.cpg_gradient,
        &[&b(&u), &b(&scale), &b(&d), bytemuck::cast_slice(&status), bytemuck::cast_slice(&mu), &b(&w0), &b(&w0)],
        &[],
        g,
        &[5, 6],
    )
    .unwrap();
    let (mut w_cpu, mut z_cpu) = (w0.clone(), w0.clone());
    cpu::cpg_gradient::cpg_gradient(&u, &scale, &d, &status, &mu, &mut w_cpu, &mut z_cpu);
    assert_close(&floats(&out[0]), w_cpu.as_flattened(), "cpg_gradient w");
    assert_close(&floats(&out[1]), z_cpu.as_flattened(), "cpg_gradient z");
    let out = stages::run_raw(
        &ctx,
        |k: &Kernels| &k.cpg_direction,
        &[bytemuck::cast_slice(&scalars), &b(&w0), &b(&u), &b(&d)],
        &[],
        g,
        &[3],
    )
    .unwrap();
    let mut d_cpu = d.clone();
    cpu::cpg_direction::cpg_direction(&scalars, &w0, &u, &mut d_cpu);
    assert_close(&floats(&out[0]), d_cpu.as_flattened(), "cpg_direction");
    let out = stages::run_raw(
        &ctx,
        |k: &Kernels| &k.cpg_restart,
        &[bytemuck::cast_slice(&scalars), &b(&w0), &b(&d)],
        &[],
        g,
        &[2],
    )
    .unwrap();
    let mut d_cpu = d.clone();
    cpu::cpg_restart::cpg_restart(&scalars, &w0, &mut d_cpu);
    assert_close(&floats(&out[0]), d_cpu.as_flattened(), "cpg_restart");
    // Natural-map residuals (the on-GPU error estimate).
    let out = stages::run_raw(
        &ctx,
        |k: &Kernels| &k.natural_map,
        &[&b(&r), &b(&u), bytemuck::cast_slice(&mu), &b(&w0)],
        &[],
        g,
        &[3],
    )
    .unwrap();
    let mut f_cpu = w0.clone();
    cpu::natural_map::natural_map(&r, &u, &mu, &mut f_cpu);
    assert_close(&floats(&out[0]), f_cpu.as_flattened(), "natural_map");
    // The velocity test's estimate: the largest scaled residual per 1,024 contacts and a sum
    // that a diverged iterate makes non-finite, on sizes around the chunk boundary, against the
    // mirror and against f64; then with one impulse NaN.
    for n in [1usize, 1024, 1025, nc] {
        let c: Vec<f32> = (0..n).map(|_| rng.gen_range(0.1..10.0)).collect();
        let (u, mu) = (&u[..n], &mu[..n]);
        let mut r = r[..n].to_vec();
        let run = |r: &[[f32; 2]], groups: usize| {
            let out = stages::run_raw(
                &ctx,
                |k: &Kernels| &k.velocity_residual,
                &[
                    &b(r),
                    &b(u),
                    bytemuck::cast_slice(mu),
                    bytemuck::cast_slice(&c),
                    bytemuck::cast_slice(&vec![[-1.0f32; 2]; groups]),
                ],
                &[],
                groups as u32,
                &[4],
            )
            .unwrap();
            floats(&out[0])
        };
        let parts = cpu::velocity_residual::velocity_residual(&r, u, mu, &c);
        assert_eq!(parts.len(), n.div_ceil(1024));
        let out = run(&r, parts.len());
        let column = |x: &[f32], k: usize| x.iter().skip(k).step_by(2).copied().collect::<Vec<_>>();
        for (k, what) in [(0, "velocity_residual: largest"), (1, "velocity_residual: witness")] {
            assert_close(&column(&out, k), &column(parts.as_flattened(), k), what);
        }
        let f64_worst = (0..n)
            .map(|a| {
                let cr = [c[a] as f64 * r[a][0] as f64, c[a] as f64 * r[a][1] as f64];
                let f = moreau::problem::cone::natural_map(cr, [u[a][0] as f64, u[a][1] as f64], mu[a] as f64);
                f[0].hypot(f[1])
            })
            .fold(0.0f64, f64::max);
        let worst = parts.iter().fold(0.0f32, |m, p| m.max(p[0])) as f64;
        assert!(
            worst > 0.0 && (worst - f64_worst).abs() <= 1e-5 * f64_worst.max(1.0),
            "n = {n}: {worst} vs {f64_worst}"
        );
        let f64_size: f64 = r.iter().chain(u).map(|x| x[0].abs() as f64 + x[1].abs() as f64).sum();
        let size: f64 = parts.iter().map(|p| p[1] as f64).sum();
        assert!((size - f64_size).abs() <= 1e-5 * f64_size, "n = {n}: witness {size} vs {f64_size}");
        // A NaN in the last chunk: its witness is not finite, the others' are.
        r[n - 1][1] = f32::NAN;
        let out = run(&r, parts.len());
        let last = out.len() - 1;
        assert!(!out[last].is_finite(), "n = {n}: a NaN impulse left the witness {}", out[last]);
        assert!(out[..last].iter().all(|x| x.is_finite()), "n = {n}: a NaN reached another chunk");
    }
    // APGD stages.
    let s_thr: Vec<f32> = (0..nc).map(|_| rng.gen_range(0.0..0.5)).collect();
    let mut sc = [0.0f32; 8];
    sc[4] = 0.8;
    let out = stages::run_raw(
        &ctx,
        |k: &Kernels| &k.apgd_step,
        &[bytemuck::cast_slice(&sc), &b(&u), &b(&r), &b(&d), bytemuck::cast_slice(&s_thr), &b(&w0), &b(&w0)],
        &[],
        g,
        &[5, 6],
    )
    .unwrap();
    let (mut next, mut diff) = (w0.clone(), w0.clone());
    cpu::apgd_step::apgd_step(&sc, &u, &r, &d, &s_thr, &mut next, &mut diff);
    assert_close(&floats(&out[0]), next.as_flattened(), "apgd_step next");
    assert_close(&floats(&out[1]), diff.as_flattened(), "apgd_step diff");
    for (restart, theta) in [(0.3f32, 1.0f32), (-0.2, 0.6)] {
        let mut sc = [0.0f32; 8];
        (sc[0], sc[1]) = (restart, theta);
        let out =
            stages::run_raw(&ctx, |k: &Kernels| &k.apgd_scalars, &[bytemuck::cast_slice(&sc)], &[], 1, &[0]).unwrap();
        cpu::apgd_scalars::apgd_scalars(&mut sc);
        assert_close(&floats(&out[0]), &sc, "apgd_scalars");
    }
    for restart in [0.0f32, 1.0] {
        let mut sc = [0.0f32; 8];
        (sc[2], sc[3]) = (0.4, restart);
        let out = stages::run_raw(
            &ctx,
            |k: &Kernels| &k.apgd_momentum,
            &[bytemuck::cast_slice(&sc), &b(&u), &b(&d), &b(&r)],
            &[],
            g,
            &[2, 3],
        )
        .unwrap();
        let (mut gm, mut yy) = (d.clone(), r.clone());
        cpu::apgd_momentum::apgd_momentum(&sc, &u, &mut gm, &mut yy);
        assert_close(&floats(&out[0]), gm.as_flattened(), "apgd_momentum gamma");
        assert_close(&floats(&out[1]), yy.as_flattened(), "apgd_momentum y");
    }
    let out = stages::run_raw(
        &ctx,
        |k: &Kernels| &k.apgd_rebox,
        &[bytemuck::cast_slice(&mu), &b(&r), &b(&d), bytemuck::cast_slice(&s_thr), bytemuck::cast_slice(&[0.0f32; 8])],
        &[],
        g,
        &[1, 2, 3, 4],
    )
    .unwrap();
    let (mut gm, mut yy, mut ss, mut sc) = (r.clone(), d.clone(), s_thr.clone(), [0.0f32; 8]);
    cpu::apgd_rebox::apgd_rebox(&mu, &mut gm, &mut yy, &mut ss, &mut sc);
    assert_close(&floats(&out[0]), gm.as_flattened(), "apgd_rebox gamma");
    assert_close(&floats(&out[1]), yy.as_flattened(), "apgd_rebox y");
    assert_close(&floats(&out[2]), &ss, "apgd_rebox s");
    assert_close(&floats(&out[3]), &sc, "apgd_rebox scalars");
    for stage in 0..3u32 {
        let mut s = [0.0f32; 16];
        for (k, x) in s.iter_mut().enumerate().take(9) {
            *x = rng.gen_range(-1.0..1.0) + k as f32 * 0.0;
        }
        s[3] = if stage == 2 && rng.gen_bool(0.5) { 1.0 } else { 0.0 };
        let out = stages::run_raw(
            &ctx,
            |k: &Kernels| &k.cpg_scalars,
            &[bytemuck::cast_slice(&s)],
            &[bytemuck::cast_slice(&[stage, 0, 0, 0])],
            1,
            &[0],
        )
        .unwrap();
        let mut s_cpu = s;
        cpu::cpg_scalars::cpg_scalars(&mut s_cpu, stage);
        assert_close(&floats(&out[0]), &s_cpu, &format!("cpg_scalars stage {stage}"));
    }
}

/// Past 65,535 workgroups (4,194,240 contacts) a dispatch is a 2D grid; every contact is still
/// updated once, as the mirror does.
#[test]
fn a_dispatch_past_the_workgroup_limit_covers_every_contact() {
    assert_eq!(moreau::gpu::kernels::grid(65_535), [65_535, 1]);
    let [x, y] = moreau::gpu::kernels::grid(65_536);
    assert!(x <= 65_535 && x * y >= 65_536 && y == 2);
    let Some(ctx) = common::gpu_context() else { return };
    let nc = 65_535 * 64 + 1000;
    let u: Vec<[f32; 2]> = (0..nc).map(|a| [((a % 7) as f32) - 3.0, ((a % 5) as f32) - 2.0]).collect();
    let mu = vec![0.5f32; nc];
    let step = vec![0.25f32; nc];
    let r = vec![[0.0f32; 2]; nc];
    let gpu_r = stages::jacobi_update(&ctx, &u, &mu, &step, &r).unwrap();
    let mut cpu_r = r.clone();
    cpu::jacobi_update::jacobi_update(&u, &mu, &step, &mut cpu_r);
    assert_close(gpu_r.as_flattened(), cpu_r.as_flattened(), "jacobi_update on a 2D grid");
    assert!(gpu_r[nc - 1] != [0.0, 0.0] || cpu_r[nc - 1] == [0.0, 0.0], "the last contact was updated");
}

/// The three Anderson stages against their mirrors, after every "sweep" of a contraction
/// landed on the cones (3,000 contacts: three partials; a history of 3 slots, so the ring
/// wraps), with a kick at sweep 12 whose residual the mixer must refuse (a restart). Each
/// stage runs on the mirror's inputs, so differences cannot compound; the sequence of actions
/// must have recorded, mixed and restarted.
#[test]
fn anderson_stages_match_their_mirrors() {
    use moreau::gpu::cpu::anderson_dots::{anderson_dots, n_groups, n_sums};
    use moreau::gpu::cpu::anderson_fit::{anderson_fit, Mixer, MIX, RECORD, RESTART};
    use moreau::gpu::cpu::anderson_mix::{anderson_mix, MixerVectors};
    use moreau::gpu::kernels::Kernels;
    let Some(ctx) = common::gpu_context() else { return };
    let mut rng = rand::rngs::SmallRng::seed_from_u64(5);
    let (nc, depth) = (3000, 3);
    let mu: Vec<f32> = (0..nc).map(|_| rng.gen_range(0.0..0.8)).collect();
    let target: Vec<[f32; 2]> = (0..nc).map(|_| [rng.gen_range(-0.5..1.0), rng.gen_range(-0.5..0.5)]).collect();
    let b = |x: &[[f32; 2]]| bytemuck::cast_slice::<[f32; 2], u8>(x).to_vec();
    let pairs = |bytes: &[u8]| bytemuck::cast_slice::<u8, [f32; 2]>(bytes).to_vec();
    let mut x = MixerVectors {
        r: vec![[0.0; 2]; nc],
        before: vec![[0.0; 2]; nc],
        last_residual: vec![[0.0; 2]; nc],
        last_impulse: vec![[0.0; 2]; nc],
        d_residual: vec![[0.0; 2]; depth * nc],
        d_impulse: vec![[0.0; 2]; depth * nc],
    };
    let mut mixer = Mixer::new();
    let mut actions = Vec::new();
    for sweep in 0..24 {
        // The "sweep": r ← Π(0.9 r + 0.1 target), kicked once.
        let kick = if sweep == 12 { 50.0 } else { 1.0 };
        for a in 0..nc {
            let y = [0.9 * x.before[a][0] + 0.1 * kick * target[a][0], 0.9 * x.before[a][1] + 0.1 * target[a][1]];
            x.r[a] = cpu::single_contact::project_cone(y, mu[a]);
        }
        let (r, before, last) = (x.r.as_flattened(), x.before.as_flattened(), x.last_residual.as_flattened());
        let parts = anderson_dots(r, before, last, x.d_residual.as_flattened(), depth);
        let groups = n_groups(2 * nc);
        assert_eq!(parts.len(), groups * n_sums(depth));
        let shape = [2 * nc as u32, depth as u32, 0, 0];
        let out = stages::run_raw(
            &ctx,
            |k: &Kernels| &k.anderson_dots,
            &[&b(&x.r), &b(&x.before), &b(&x.last_residual), &b(&x.d_residual), &vec![0u8; 4 * parts.len()]],
            &[bytemuck::cast_slice(&shape)],
            groups as u32,
            &[4],
        )
        .unwrap();
        assert_close(&floats(&out[0]), &parts, &format!("anderson_dots, sweep {sweep}"));

        let before_fit = mixer;
        let job = [groups as u32, depth as u32, 7, 2];
        let args = anderson_fit(&parts, groups, depth, &mut mixer, [7, 2]);
        let out = stages::run_raw(
            &ctx,
            |k: &Kernels| &k.anderson_fit,
            &[bytemuck::cast_slice(&parts), bytemuck::bytes_of(&before_fit), &[0u8; 12]],
            &[bytemuck::cast_slice(&job)],
            1,
            &[1, 2],
        )
        .unwrap();
        let gpu: Mixer = bytemuck::pod_read_unaligned(&out[0]);
        let what = format!("anderson_fit, sweep {sweep}");
        let exact = |m: &Mixer| (m.count, m.has_last, m.mixed, m.restarts, m.action, m.slot, m.order);
        assert_eq!(exact(&gpu), exact(&mixer), "{what}");
        assert_eq!(bytemuck::cast_slice::<u8, u32>(&out[1]), args, "{what}: the rebuild's dispatch");
        // γ solves a small system in f32: its rounding, relative to the largest coefficient.
        let scale = mixer.gamma.iter().fold(1.0f32, |m, g| m.max(g.abs()));
        for (g, c) in gpu.gamma.iter().zip(&mixer.gamma) {
            assert!((g - c).abs() <= 1e-3 * scale, "{what}: γ {:?} vs {:?}", gpu.gamma, mixer.gamma);
        }
        assert_close(&gpu.gram, &mixer.gram, &what);
        assert_close(&[gpu.reference], &[mixer.reference], &what);
        actions.push(mixer.action);

        let before_mix = x.clone();
        anderson_mix(&mut x, &mu, &mixer);
        let out = stages::run_raw(
            &ctx,
            |k: &Kernels| &k.anderson_mix,
            &[
                &b(&before_mix.r),
                &b(&before_mix.before),
                &b(&before_mix.last_residual),
                &b(&before_mix.last_impulse),
                &b(&before_mix.d_residual),
                &b(&before_mix.d_impulse),
                bytemuck::cast_slice(&mu),
                bytemuck::bytes_of(&mixer),
            ],
            &[],
            moreau::gpu::kernels::groups(nc),
            &[0, 1, 2, 3, 4, 5],
        )
        .unwrap();
        let mirrors = [&x.r, &x.before, &x.last_residual, &x.last_impulse, &x.d_residual, &x.d_impulse];
        for (k, (gpu, cpu)) in out.iter().zip(mirrors).enumerate() {
            assert_close(pairs(gpu).as_flattened(), cpu.as_flattened(), &format!("anderson_mix {k}, sweep {sweep}"));
        }
    }
    eprintln!("actions: {actions:?}");
    for action in [RECORD, MIX, RESTART] {
        assert!(actions.contains(&action), "action {action} never taken: {actions:?}");
    }
}

/// The fit sums the partials of many workgroups (600, as for 300,000 contacts) in its fixed
/// order: the sums it keeps (the Gram matrix, the reference) are its mirror's to f32 rounding.
#[test]
fn anderson_fit_sums_many_groups_as_its_mirror() {
    use moreau::gpu::cpu::anderson_dots::n_sums;
    use moreau::gpu::cpu::anderson_fit::{anderson_fit, Mixer, PUSH};
    use moreau::gpu::kernels::Kernels;
    let Some(ctx) = common::gpu_context() else { return };
    let mut rng = rand::rngs::SmallRng::seed_from_u64(9);
    let (groups, depth) = (600, 4);
    // A mixer one record in, so this sweep's sums fill a Gram entry and set the reference.
    let mut mixer = Mixer { has_last: 1, reference: 1e3, ..Mixer::new() };
    let parts: Vec<f32> = (0..groups * n_sums(depth)).map(|_| rng.gen_range(0.0..1.0)).collect();
    let before = mixer;
    let job = [groups as u32, depth as u32, 3, 1];
    anderson_fit(&parts, groups, depth, &mut mixer, [3, 1]);
    let out = stages::run_raw(
        &ctx,
        |k: &Kernels| &k.anderson_fit,
        &[bytemuck::cast_slice(&parts), bytemuck::bytes_of(&before), &[0u8; 12]],
        &[bytemuck::cast_slice(&job)],
        1,
        &[1],
    )
    .unwrap();
    let gpu: Mixer = bytemuck::pod_read_unaligned(&out[0]);
    assert_eq!((gpu.action, gpu.count), (mixer.action, mixer.count));
    assert!(mixer.action != PUSH || mixer.count == 1, "{mixer:?}");
    // |f| over 600 groups of about 1/2 each: √300, not a lane's √(1/2).
    assert!(mixer.reference > 15.0, "{}", mixer.reference);
    assert_close(&gpu.gram, &mixer.gram, "the Gram matrix");
    assert_close(&[gpu.reference], &[mixer.reference], "the reference");
}

/// NLGS on the GPU mixes its sweeps when asked (`anderson = 5`), as the CPU does: on a
/// matrix-free pile step and on explicit `W`s (Siconos files) it reaches the tolerance in fewer
/// sweeps than the plain GPU sweeps, judged in f64, and says so; a history deeper than the
/// kernels keep is cut to theirs and said.
#[test]
fn the_gpu_mixes_its_sweeps_as_the_cpu_does() {
    let Some(ctx) = common::gpu_context() else { return };
    let mut cases: Vec<(String, ContactProblem)> = vec![
        ("pile step 60".into(), pile_problem(r#""gravity", "friction", "rotation""#)),
        ("lattice 30×15".into(), lattice_packing(30, 15, 0.5, 2)),
    ];
    if let Some(path) = common::shared_data("fc2d_granularflowonwall_02020_00213.dat") {
        cases.push(("Siconos 2020".into(), moreau::io::siconos::read_fc2d(&path).unwrap()));
    }
    for (name, p) in &cases {
        let run = |anderson| {
            let opts = SolverOptions { tol: 1e-5, max_iter: 50_000, anderson, ..SolverOptions::default() };
            moreau::gpu::solve(&ctx, p, SolverKind::Nlgs, &opts, None).unwrap()
        };
        let (plain, mixed) = (run(0), run(5));
        let cpu = solve(
            p,
            SolverKind::Nlgs,
            &SolverOptions { tol: 1e-5, max_iter: 50_000, anderson: 5, ..Default::default() },
            None,
        );
        eprintln!(
            "{name}: GPU plain {} sweeps, GPU Anderson {} ({:.2e}; {:?}), CPU Anderson {}",
            plain.iterations, mixed.iterations, mixed.error, mixed.notes, cpu.iterations
        );
        assert!(plain.converged, "{name}: plain {}", plain.stop_reason);
        assert!(mixed.converged && mixed.judged_error <= 1e-5, "{name}: mixed {}", mixed.stop_reason);
        common::check_solution(p, &mixed.r, 1e-4).unwrap_or_else(|e| panic!("{name}: {e}"));
        common::assert_mixing_paid(
            name,
            &mixed,
            plain.iterations,
            2,
            "Anderson acceleration over 5 sweeps (on the GPU)",
        );
    }
    let deep = SolverOptions { tol: 1e-5, max_iter: 50_000, anderson: 12, ..SolverOptions::default() };
    let said = moreau::backend::gpu_omits(SolverKind::Nlgs, &deep).expect("a history past 8 is cut");
    assert!(said.contains("at most 8") && said.contains("anderson = 12"), "{said}");
    let focused = SolverOptions { focus: 19, ..deep.clone() };
    let said = moreau::backend::gpu_omits(SolverKind::Nlgs, &focused).expect("focused sweeps are CPU sweeps");
    assert!(said.contains("anderson = 12") && said.contains("focus = 19"), "{said}");
    let r = moreau::gpu::solve(&ctx, &cases[1].1, SolverKind::Nlgs, &deep, None).unwrap();
    assert!(
        r.converged && r.notes.iter().any(|n| n.starts_with("Anderson acceleration over 8 sweeps")),
        "{:?}",
        r.notes
    );
}

/// Several buffers read back through one staging buffer and one wait come back as each read
/// alone does, whatever their lengths (odd counts: each part is padded to wgpu's 4 bytes).
#[test]
fn buffers_read_back_together_are_each_read_back_alone() {
    use moreau::gpu::kernels::{read_back, read_back_each, storage};
    let Some(ctx) = common::gpu_context() else { return };
    let a: Vec<u32> = (0..3).map(|k| 7 + k).collect();
    let b: Vec<u32> = (0..1025).map(|k| 3 * k + 1).collect();
    let (ga, gb) = (storage(&ctx, "a", &a), storage(&ctx, "b", &b));
    let [ra, rb] = read_back_each::<u32, 2>(&ctx, [(&ga, a.len()), (&gb, b.len())]).unwrap();
    assert_eq!((ra, rb), (a.clone(), b.clone()));
    assert_eq!(read_back::<u32>(&ctx, &gb, b.len()).unwrap(), b);
    let bytes: Vec<u8> = (0..8).collect();
    let [odd] = read_back_each::<u8, 1>(&ctx, [(&storage(&ctx, "bytes", &bytes), 5)]).unwrap();
    assert_eq!(odd, &bytes[..5]);
}

/// A read submitted with [`submit_and_read`] brings back the bytes as they were at its
/// submission, though work queued after it changes them before it is waited for.
#[test]
fn a_pending_read_sees_its_submission_not_the_work_queued_after_it() {
    use moreau::gpu::kernels::{encode_pass, read_back, storage, submit, submit_and_read};
    let Some(ctx) = common::gpu_context() else { return };
    let before: Vec<u32> = (0..513).collect();
    let after: Vec<u32> = before.iter().map(|k| 1000 + k).collect();
    let buffer = storage(&ctx, "changing", &before);
    let copy = storage(&ctx, "copy", &vec![0u32; before.len()]);
    let bytes = 4 * before.len();
    let mut encoder = encode_pass(&ctx, "read", |_| {});
    encoder.copy_buffer_to_buffer(&buffer, 0, &copy, 0, bytes as u64);
    let pending = submit_and_read(&ctx, encoder, &[(&buffer, bytes)]);
    ctx.queue.write_buffer(&buffer, 0, bytemuck::cast_slice(&after));
    submit(&ctx, "later", |_| {});
    let parts = pending.wait(&ctx).unwrap();
    assert_eq!(bytemuck::pod_collect_to_vec::<u8, u32>(&parts[0]), before, "the read came back as submitted");
    assert_eq!(read_back::<u32>(&ctx, &copy, before.len()).unwrap(), before, "the GPU-side copy too");
    assert_eq!(read_back::<u32>(&ctx, &buffer, after.len()).unwrap(), after, "the later work did run");
}

/// The GPU queues its next batch of sweeps before waiting for a check's numbers; a solve that
/// stops at a check returns that check's impulses, not those of the batch queued past it: the
/// same solve capped at its reported iterations (no batch queued past its last check) returns
/// the same bits.
#[test]
fn a_gpu_solve_returns_the_impulses_of_its_last_check_not_of_the_batch_queued_past_it() {
    let Some(ctx) = common::gpu_context() else { return };
    let p = lattice_packing(20, 10, 0.3, 3);
    let opts = SolverOptions { tol: 1e-5, max_iter: 20_000, ..SolverOptions::default() };
    let solved = moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &opts, None).unwrap();
    assert!(solved.converged, "{}", solved.stop_reason);
    assert!(solved.gpu_checks.discarded > 0, "a batch was queued past the converged check: {:?}", solved.gpu_checks);
    let said = format!("; {} iterations queued past the last check and not used", solved.gpu_checks.discarded);
    assert!(solved.notes.iter().any(|n| n.ends_with(&said)), "{:?}", solved.notes);
    let capped = SolverOptions { max_iter: solved.iterations, ..opts.clone() };
    let again = moreau::gpu::solve(&ctx, &p, SolverKind::Nlgs, &capped, None).unwrap();
    assert_eq!(again.iterations, solved.iterations);
    assert_eq!(again.gpu_checks.discarded, 0, "nothing is queued past max_iter");
    let differing = again.r.iter().zip(&solved.r).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 0, "the returned impulses are those judged at the last check");
    assert_eq!(solved.judged_error, again.judged_error);
}

/// A problem with no answer (a disk pressed from opposite sides at once) is not called solved on
/// the GPU either: its f32 sweeps grow the impulses until the relative error passes, and the
/// backend's check of the answer, the CPU's, refuses it.
#[test]
fn a_problem_with_no_answer_is_not_solved_on_the_gpu() {
    use moreau::backend::Backend;
    use moreau::problem::block_sparse::BlockSparse;
    let Some(ctx) = common::gpu_context() else { return };
    let (same, opposed) = ([1.0, 0.0, 0.0, 1.0], [-1.0, 0.0, 0.0, -1.0]);
    let w = BlockSparse::from_block_triplets(2, vec![(0, 0, same), (0, 1, opposed), (1, 0, opposed), (1, 1, same)]);
    let p = ContactProblem::new(Delassus::Sparse(w), vec![-1.0, 0.0, -1.0, 0.0], vec![0.5, 0.5]).unwrap();
    let opts = SolverOptions { tol: 1e-4, max_iter: 20_000, ..SolverOptions::default() };
    let backend = Backend::gpu(ctx);
    for kind in [SolverKind::Nlgs, SolverKind::Apgd] {
        let rep = backend.solve(&p, kind, &opts, None).unwrap();
        assert!(!rep.converged, "{kind}: converged with error {:e}, r = {:?}", rep.error, rep.r);
        assert!(rep.stop == moreau::solvers::StopReason::Unbounded, "{kind}: {}", rep.stop_reason);
    }
}
