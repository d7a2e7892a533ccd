//! The structural half of the founding paper: the Signorini punch (plane-strain Q4 elements)
//! condensed on its contact dofs to the LCP `w = M z + q`, and solved by NLGS, CPG, LATIN and the
//! dual projected CG. Tolerances are stated per test.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::{Scratch, ScratchFile};

use std::path::Path;
use std::process::Command;

use moreau::scene::{self, AnyScene, SceneError};
use moreau::solvers::{self, LatinK, SolverKind, SolverOptions};
use moreau::structure::study::{latin_k_sweep, run, PunchProblems, StructuralSolver};
use moreau::structure::{Elastic, PunchGeometry, PunchModel};

const STEEL_LIKE: Elastic = Elastic { young: 2.0e11, poisson: 0.3 };

fn punch(cells: [usize; 2], radius: Option<f64>, displacement: f64) -> PunchModel {
    let geometry = PunchGeometry { half_width: 0.5, height: 1.0, radius, cells, grading: 1.5 };
    PunchModel::new(geometry, STEEL_LIKE, displacement).unwrap()
}

fn tight(max_iter: usize) -> SolverOptions {
    SolverOptions { tol: 1e-11, max_iter, ..SolverOptions::default() }
}

fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().map(|x| x.abs()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale
}

/// A linear displacement field is reproduced exactly by Q4 elements on the mapped (curved,
/// graded) mesh: the internal forces of every node not on the boundary vanish.
#[test]
fn patch_test_on_the_mapped_mesh() {
    let m = punch([12, 9], Some(2.0), 1e-3);
    let u: Vec<f64> =
        m.mesh.nodes.iter().flat_map(|p| [1e-3 * p[0] - 4e-4 * p[1], 2e-4 * p[0] + 7e-4 * p[1]]).collect();
    let f = m.internal_forces(&u);
    let on_boundary = |n: usize| {
        m.mesh.contact.contains(&n) || m.mesh.top.contains(&n) || m.mesh.axis.contains(&n) || {
            let x = m.mesh.nodes[n][0];
            (x - 0.5).abs() < 1e-12
        }
    };
    let scale = f.iter().map(|x| x.abs()).fold(0.0, f64::max);
    let worst = (0..m.mesh.nodes.len())
        .filter(|&n| !on_boundary(n))
        .map(|n| f[2 * n].abs().max(f[2 * n + 1].abs()))
        .fold(0.0, f64::max);
    assert!(scale > 0.0);
    assert!(worst <= 1e-10 * scale, "interior residual {worst:e} of {scale:e}");
}

/// The condensed stiffness (Schur complement through K_ii) and the flexibility (through K_ff,
/// an independent factorisation) are inverse to each other, and their loads agree: q_F = −F q.
#[test]
fn condensed_stiffness_and_flexibility_are_inverse() {
    let m = punch([30, 20], Some(2.0), 1e-3);
    let (stiff, flex) = (m.condense().unwrap(), m.flexibility().unwrap());
    let n = stiff.n;
    let mut worst: f64 = 0.0;
    for j in 0..n {
        let col: Vec<f64> = (0..n).map(|i| flex.entry(i, j)).collect();
        let mc = stiff.apply(&col);
        for (i, v) in mc.iter().enumerate() {
            worst = worst.max((v - if i == j { 1.0 } else { 0.0 }).abs());
        }
    }
    assert!(worst < 1e-8, "|M F − I| = {worst:e}");
    let fq: Vec<f64> = flex.apply(&stiff.q).iter().map(|x| -x).collect();
    assert!(max_rel_diff(&flex.q, &fq) < 1e-8, "q_F vs −F q: {:e}", max_rel_diff(&flex.q, &fq));
}

/// On a small mesh (11 contact nodes, 2,048 active sets) the exact LCP solution by enumeration is
/// the reference every solver must reach (relative 1e-8 on the gaps, 1e-6 on the forces).
#[test]
fn solvers_reach_the_enumerated_solution() {
    let m = punch([10, 6], Some(1.0), 2e-2);
    let problems = PunchProblems::new(&m).unwrap();
    let exact = problems.primal.solve_by_enumeration().expect("an SPD LCP has a solution");
    let closed = exact.iter().filter(|&&z| z == 0.0).count();
    assert!(closed >= 2 && closed < exact.len(), "a partial contact is wanted: {closed} of {} closed", exact.len());
    assert!(max_rel_diff(&problems.reference, &exact) < 1e-10, "active-set reference");
    let w_exact: Vec<f64> = problems.primal.complement(&exact).iter().map(|w| w * problems.force_scale).collect();
    for name in ["nlgs", "cpg", "pcpg", "latin", "dual_cg"] {
        let r = run(&problems, StructuralSolver::parse(name).unwrap(), &tight(100_000));
        assert!(r.converged, "{name}: {}", r.stop_reason);
        assert!(max_rel_diff(&r.z, &exact) < 1e-8, "{name}: gaps off by {:e}", max_rel_diff(&r.z, &exact));
        assert!(max_rel_diff(&r.w, &w_exact) < 1e-6, "{name}: forces off by {:e}", max_rel_diff(&r.w, &w_exact));
    }
}

/// NLGS, CPG, LATIN and the dual CG agree on a finer mesh (81 contact nodes): energy-norm error
/// ≤ 1e-8 against the exact active-set solution at tolerance 1e-11.
#[test]
fn the_four_solvers_agree() {
    let m = punch([80, 40], Some(2.0), 1e-3);
    let problems = PunchProblems::new(&m).unwrap();
    for name in ["nlgs", "cpg", "latin", "dual_cg"] {
        let r = run(&problems, StructuralSolver::parse(name).unwrap(), &tight(200_000));
        assert!(r.converged, "{name}: {}", r.stop_reason);
        assert!(r.energy_error() <= 1e-8, "{name}: energy-norm error {:e}", r.energy_error());
    }
}

/// The headline of the punch (closed nodes, contact half-width) does not depend on the solver:
/// a projected gradient leaves force noise of the order of tol at open nodes, which must not
/// count as contact. Solves at tol 1e-6.
#[test]
fn the_contact_zone_is_the_same_for_every_solver() {
    let m = punch([80, 40], Some(2.0), 1e-3);
    let problems = PunchProblems::new(&m).unwrap();
    let opts = SolverOptions { tol: 1e-6, max_iter: 200_000, ..SolverOptions::default() };
    let zone = |name: &str| {
        let r = run(&problems, StructuralSolver::parse(name).unwrap(), &opts);
        assert!(r.converged, "{name}: {}", r.stop_reason);
        m.solution(&r.z, &r.w).unwrap().closed_nodes()
    };
    let reference = zone("nlgs");
    assert!(!reference.is_empty() && reference.len() < m.n_contacts(), "{} closed", reference.len());
    for name in ["pcpg", "cpg", "latin", "dual_cg"] {
        assert_eq!(zone(name), reference, "{name} closes other nodes than NLGS");
    }
}

/// LATIN's k changes the path, not the solution: k from 1/16 to 16 times the mean of diag M and
/// of diag M itself give the same gaps within 1e-8 (tol 1e-11).
#[test]
fn latin_does_not_depend_on_k() {
    let m = punch([40, 20], Some(2.0), 1e-3);
    let problems = PunchProblems::new(&m).unwrap();
    let rows = latin_k_sweep(&problems, &[1.0 / 16.0, 0.25, 1.0, 4.0, 16.0], 1e-11, 400_000);
    assert_eq!(rows.len(), 10);
    for r in &rows {
        assert!(r.converged, "k factor {} (diagonal {}): not converged", r.factor, r.per_contact_diagonal);
        assert!(r.energy_error <= 1e-8, "k factor {}: energy-norm error {:e}", r.factor, r.energy_error);
    }
    let its: Vec<usize> = rows.iter().map(|r| r.iterations).collect();
    assert!(its.iter().max() > its.iter().min(), "k must change the convergence rate: {its:?}");
}

/// LATIN's automatic search direction (√(λ_min λ_max) of the scaled M from Lanczos) lands near
/// the best factor of a sweep over powers of two: within 1.6× its iterations to 1e-8, and in at
/// most half the iterations of the fixed factor 1 it replaced. With friction (a lattice packing,
/// μ 0.3) the automatic factor is 1 and says why.
#[test]
fn latin_chooses_its_search_direction_near_the_best() {
    let m = punch([40, 20], Some(2.0), 1e-3);
    let problems = PunchProblems::new(&m).unwrap();
    let factors: Vec<f64> = (-6..=2).map(|e| 2f64.powi(e)).collect();
    let rows = latin_k_sweep(&problems, &factors, 1e-8, 20_000);
    let best = rows.iter().filter(|r| r.converged && r.per_contact_diagonal).map(|r| r.iterations).min().unwrap();
    let fixed = rows.iter().find(|r| r.factor == 1.0 && r.per_contact_diagonal).unwrap().iterations;
    let opts = SolverOptions { tol: 1e-8, max_iter: 20_000, ..SolverOptions::default() };
    assert_eq!(opts.latin_k, LatinK::Auto, "the automatic factor is the default");
    let auto = solvers::solve(&problems.primal.to_contact_problem(), SolverKind::Latin, &opts, None);
    assert!(auto.converged, "{}", auto.stop_reason);
    assert!(auto.notes.iter().any(|n| n.contains("√(λ_min λ_max)")), "{:?}", auto.notes);
    assert!(
        auto.iterations as f64 <= 1.6 * best as f64 && 2 * auto.iterations <= fixed,
        "automatic k: {} iterations; best factor {best}, factor 1 {fixed}",
        auto.iterations
    );

    let lattice = moreau::problem::generate::lattice_packing(12, 8, 0.3, 1);
    let auto = solvers::solve(&lattice, SolverKind::Latin, &opts, None);
    let one = SolverOptions { latin_k: LatinK::Factor(1.0), ..opts.clone() };
    let fixed = solvers::solve(&lattice, SolverKind::Latin, &one, None);
    assert_eq!((auto.iterations, auto.error), (fixed.iterations, fixed.error));
    assert!(auto.notes.iter().any(|n| n.contains("friction")), "{:?}", auto.notes);
}

/// The contact forces balance the load the platen applies (equilibrium of the whole body, to
/// round-off), and on a fine mesh the contact half-width and peak pressure follow Hertz's line
/// contact (a² = 4PR/(πE*), p₀ = 2P/(πa)) within 5 %.
#[test]
fn contact_pressure_integrates_to_the_load() {
    let m = punch([120, 80], Some(2.0), 1e-4);
    let problems = PunchProblems::new(&m).unwrap();
    let r = run(&problems, StructuralSolver::Primal(SolverKind::Pcpg), &tight(100_000));
    assert!(r.converged, "{}", r.stop_reason);
    let sol = m.solution(&r.z, &r.w).unwrap();
    let load = -sol.platen_force;
    assert!(load > 0.0, "the platen pushes down");
    assert!((sol.contact_force() - load).abs() <= 1e-9 * load, "Σw = {:e}, load {load:e}", sol.contact_force());
    // Both halves for Hertz (symmetry at x = 0).
    let p = 2.0 * load;
    let e_star = STEEL_LIKE.young / (1.0 - STEEL_LIKE.poisson.powi(2));
    let a_hertz = (4.0 * p * 2.0 / (std::f64::consts::PI * e_star)).sqrt();
    let max_w = sol.w.iter().copied().fold(0.0, f64::max);
    let a = (0..m.n_contacts())
        .filter(|&k| sol.w[k] > 1e-6 * max_w)
        .map(|k| m.mesh.nodes[m.mesh.contact[k]][0])
        .fold(0.0, f64::max);
    let spacing = 0.5 / 120.0;
    assert!((a - a_hertz).abs() <= 0.05 * a_hertz + spacing, "half-width {a:e} vs Hertz {a_hertz:e}");
    let p0 = 2.0 * p / (std::f64::consts::PI * a_hertz);
    let peak = sol.pressure.iter().copied().fold(0.0, f64::max);
    assert!((peak - p0).abs() <= 0.05 * p0, "peak pressure {peak:e} vs Hertz {p0:e}");
}

/// A flat punch pushed down is in full contact; pulled up, it lifts off everywhere (w = 0).
#[test]
fn flat_punch_in_full_contact_or_lifted() {
    let m = punch([20, 10], None, 1e-3);
    let problems = PunchProblems::new(&m).unwrap();
    let r = run(&problems, StructuralSolver::Primal(SolverKind::Nlgs), &tight(100_000));
    assert!(r.converged && r.z.iter().all(|&z| z == 0.0) && r.w.iter().all(|&w| w > 0.0));
    let up = punch([20, 10], None, -1e-3);
    let problems = PunchProblems::new(&up).unwrap();
    let r = run(&problems, StructuralSolver::DualCg, &tight(100_000));
    assert!(r.converged && r.w.iter().all(|&w| w == 0.0), "forces {:?}", r.w);
    assert!(r.z.iter().all(|&z| (z - 1e-3).abs() < 1e-12), "a free body translates rigidly: {:?}", &r.z[..3]);
}

fn parse_err(text: &str) -> String {
    match scene::load_any(&write_temp(text)) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted:\n{text}"),
    }
}

fn write_temp(text: &str) -> ScratchFile {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let file = ScratchFile::new(&format!("structure_{}", N.fetch_add(1, Ordering::Relaxed)), "punch.toml");
    std::fs::write(&*file, text).unwrap();
    file
}

const GOOD: &str = "name = \"p\"\n[punch]\nhalf_width = 0.5\nheight = 1.0\nradius = 2.0\ncells = [10, 6]\nyoung = 1e7\npoisson = 0.3\ndisplacement = 1e-3\n";

#[test]
fn bad_punch_scenes_are_named_errors() {
    assert!(matches!(scene::load_any(&write_temp(GOOD)), Ok(AnyScene::Punch(_))));
    for (from, to, expected) in [
        ("young = 1e7", "young = -1e7", "young = -10000000 must be > 0"),
        ("poisson = 0.3", "poisson = 0.5", "poisson = 0.5 must lie in (-1, 0.5)"),
        ("radius = 2.0", "radius = 0.4", "must be larger than half_width"),
        ("cells = [10, 6]", "cells = [0, 6]", "at least one element"),
        ("cells = [10, 6]", "cells = [1000, 1000]", "100,000 in all"),
        ("displacement = 1e-3", "displacement = nan", "not finite"),
        ("height = 1.0", "height = 1.0\nheight_typo = 2", "unknown field `height_typo`"),
    ] {
        let e = parse_err(&GOOD.replace(from, to));
        assert!(e.contains(expected), "{to}: {e}");
        assert!(e.contains("line "), "{to}: no line in {e}");
    }
    let e = parse_err(&format!("{GOOD}[solver]\nname = \"dual\"\n"));
    assert!(e.contains("solver.name") && e.contains("dual_cg"), "{e}");
    for k in ["\"fast\"", "0.0", "-2"] {
        let e = parse_err(&format!("{GOOD}[solver]\nlatin_k = {k}\n"));
        assert!(e.contains("solver.latin_k") && e.contains("auto"), "{k}: {e}");
    }
    match scene::load_any(&write_temp(&format!("{GOOD}[solver]\nlatin_k = \"auto\"\n"))) {
        Ok(AnyScene::Punch(p)) => assert_eq!(p.options.latin_k, LatinK::Auto),
        Ok(_) => panic!("not a punch scene"),
        Err(e) => panic!("{e}"),
    }
    // A granular loader names the structural scene instead of a missing field.
    match scene::load(&write_temp(GOOD)) {
        Err(SceneError::Invalid { field, message, .. }) => {
            assert_eq!(field, "punch");
            assert!(message.contains("structural scene"), "{message}");
        }
        other => panic!("{other:?}"),
    }
}

/// `moreau run` and `moreau sweep` on the shipped scene write what they promise.
#[test]
fn run_and_sweep_write_their_outputs() {
    let out = Scratch::new("punch_out");
    let exe = env!("CARGO_BIN_EXE_moreau");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/signorini_punch.toml");
    let status = Command::new(exe).arg("run").arg(&scene).arg("--out").arg(out.join("run")).status().unwrap();
    assert!(status.success());
    for f in ["summary.json", "contact.csv", "punch.vtu", "sigma_yy.png"] {
        assert!(out.join("run").join(f).is_file(), "{f} missing");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("run/summary.json")).unwrap()).unwrap();
    assert_eq!(summary["converged"], true);
    let (load, force) = (summary["load"].as_f64().unwrap(), summary["contact_force"].as_f64().unwrap());
    assert!((load - force).abs() <= 1e-6 * load, "load {load} vs contact force {force}");
    let vtu = std::fs::read_to_string(out.join("run/punch.vtu")).unwrap();
    assert!(vtu.contains("sigma_yy") && vtu.contains("displacement"));

    let status = Command::new(exe)
        .args(["sweep"])
        .arg(&scene)
        .args([
            "--solvers",
            "nlgs,cpg,latin,dual_cg",
            "--devices",
            "cpu",
            "--tols",
            "1e-6",
            "--latin-k-factors",
            "0.125,1,8",
        ])
        .arg("--out")
        .arg(out.join("sweep"))
        .status()
        .unwrap();
    assert!(status.success());
    let wp = std::fs::read_to_string(out.join("sweep/work_precision.csv")).unwrap();
    for solver in ["nlgs", "cpg", "latin", "dual_cg"] {
        let row = wp.lines().find(|l| l.split(',').nth(2) == Some(solver)).unwrap_or_else(|| panic!("{solver} row"));
        assert_eq!(row.split(',').nth(5), Some("true"), "{solver} did not converge: {row}");
    }
    let energy = std::fs::read_to_string(out.join("sweep/energy_convergence.csv")).unwrap();
    assert!(energy.starts_with("problem,solver,iteration,seconds,w_products,error,energy_error"));
    let k = std::fs::read_to_string(out.join("sweep/latin_k.csv")).unwrap();
    assert_eq!(k.lines().count(), 1 + 6, "3 factors × 2 forms of k");
    // A granular-only solver list on a structural scene is fine; dual_cg on a granular target is not.
    let bad = Command::new(exe)
        .args(["sweep"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pile.toml"))
        .args(["--solvers", "dual_cg", "--out"])
        .arg(out.join("bad"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("dual_cg solves the dual of a structural problem"));
}
