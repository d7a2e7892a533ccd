//! Scene files: every shipped scene builds and steps; bad scenes get errors that name the line
//! and the field; effects that are off cost nothing; `moreau run` writes its outputs.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

use std::path::{Path, PathBuf};
use std::process::Command;

use moreau::scene::{self, SceneError};
use moreau::stepping::Simulation;

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

#[test]
fn every_shipped_scene_builds_and_runs_a_few_steps() {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(scenes_dir()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let mut s = match scene::load_any(&path).unwrap_or_else(|e| panic!("{e}")) {
                scene::AnyScene::Granular(s) => *s,
                // Structural scenes are tested in tests/structure.rs.
                scene::AnyScene::Punch(_) => continue,
            };
            assert!(s.warnings.is_empty(), "{}: {:?}", path.display(), s.warnings);
            // A few cheap steps: the big scenes are for benchmarks, not for tests.
            s.settings.options.max_iter = s.settings.options.max_iter.min(30);
            let tol = s.settings.options.tol;
            let n = s.world.bodies.len();
            let mut sim = Simulation::new(s.world, s.settings).unwrap();
            for _ in 0..2 {
                let r = sim.step().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert!(r.error.is_finite() && r.kinetic_energy.is_finite());
                // The step's error is the measure its test judged (the velocity one in the big
                // piles, whose natural-map error is ~1e-8 when they miss 1e-4).
                assert_eq!(r.converged, r.error <= tol, "{}: {:e} against {tol:e}", path.display(), r.error);
                assert!(r.max_penetration <= 0.05 * sim.world.mean_diameter(), "{}: {:?}", path.display(), r);
            }
            names.push((path.file_stem().unwrap().to_string_lossy().into_owned(), n, sim.contacts().len()));
        }
    }
    for required in [
        "pile",
        "box_compaction",
        "sandbox",
        "rotating_drum",
        "hopper",
        "column_collapse",
        "polygon_pile",
        "box_pyramid",
    ] {
        assert!(names.iter().any(|(n, ..)| n == required), "scenes/{required}.toml is missing");
    }
    let (_, n, contacts) = names.iter().find(|(n, ..)| n == "sandbox").unwrap();
    assert!(*n >= 40_000 && *contacts > 40_000, "sandbox: {n} grains, {contacts} contacts");
    let (_, n, _) = names.iter().find(|(n, ..)| n == "box_compaction").unwrap();
    assert!(*n >= 30_000);
}

const GOOD: &str = r#"
effects = ["gravity", "friction"]
[time]
step = 1e-3
steps = 10
[contact]
friction = 0.3
[[material]]
name = "m"
density = 1000.0
[[wall]]
segment = [[0.0, 0.0], [1.0, 0.0]]
[[body]]
disk = { center = [0.5, 0.1], radius = 0.1 }
"#;

fn error_of(text: &str) -> SceneError {
    match scene::parse(text, Path::new("bad.toml")) {
        Ok(_) => panic!("accepted a bad scene:\n{text}"),
        Err(e) => e,
    }
}

fn assert_scene_error(text: &str, line: usize, needles: &[&str]) {
    let e = error_of(text).to_string();
    assert!(e.starts_with(&format!("bad.toml: line {line}:")), "error '{e}' does not name line {line}");
    for n in needles {
        assert!(e.contains(n), "error '{e}' does not mention '{n}'");
    }
}

#[test]
fn bad_scenes_get_errors_naming_line_and_field() {
    assert!(scene::parse(GOOD, Path::new("good.toml")).is_ok());
    // Line numbers count from the leading newline of GOOD (line 1 is empty). A value that is
    // wrong is reported at the header of its table (`[[material]]`, `[[body]]`…) with its field path.
    assert_scene_error(&GOOD.replace("radius = 0.1 }", "radus = 0.1 }"), 14, &["radus"]);
    assert_scene_error(&GOOD.replace("density = 1000.0", "density = -3.0"), 8, &["material[0].density", "-3"]);
    assert_scene_error(&GOOD.replace("density = 1000.0", "density = nan"), 8, &["density", "NaN"]);
    assert_scene_error(&GOOD.replace("radius = 0.1 }", "radius = 0.0 }"), 13, &["body[0]", "radius"]);
    assert_scene_error(&GOOD.replace("step = 1e-3", "step = -1e-3"), 3, &["time step"]);
    assert_scene_error(&GOOD.replace("steps = 10", "steps = 0"), 3, &["time.steps"]);
    assert_scene_error(
        &GOOD.replace("[1.0, 0.0]]", "[1.0, 0.0]]\nvelocity = [1.0, 0.0]"),
        11,
        &["wall[0].velocity", "moving_walls"],
    );
    assert_scene_error(
        &GOOD.replace("\"friction\"]", "\"friction\", \"rolling_resistance\"]"),
        2,
        &["rolling_resistance", "needs the effect `rotation`"],
    );
    assert_scene_error(&GOOD.replace("\"friction\"]", "\"frction\"]"), 2, &["frction"]);
    assert_scene_error(
        &GOOD.replace(
            "disk = { center = [0.5, 0.1], radius = 0.1 }",
            "polygon = { center = [0.5, 0.1], vertices = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]] }",
        ),
        13,
        &["body[0]", "degenerate polygon"],
    );
    assert_scene_error(
        &GOOD.replace("[[body]]\n", "[[body]]\nmaterial = \"steel\"\n"),
        13,
        &["body[0].material", "steel"],
    );
    assert_scene_error(&format!("{GOOD}[solver]\nname = \"magic\"\n"), 15, &["solver.name", "magic", "nlgs"]);
    assert_scene_error(&format!("{GOOD}[solver]\ncriterion = \"loose\"\n"), 15, &["solver.criterion", "loose", "maxm"]);
    assert_scene_error(&GOOD.replace("[time]", "[time"), 3, &[]);
    // Generators that cannot fit say so.
    let crowded = format!(
        "{GOOD}[[generate]]\nkind = \"grid\"\ncount = 1000\nradius = [0.1, 0.1]\nregion = {{ min = [0.0, 0.0], max = [1.0, 1.0] }}\n"
    );
    assert_scene_error(&crowded, 15, &["generate[0].count", "holds 16"]);
    // Requests no file may make: billions of grains, a huge pyramid or drum.
    let huge = format!(
        "{GOOD}[[generate]]\nkind = \"deposition\"\ncount = 4000000000\nradius = [0.1, 0.1]\nregion = {{ min = [0.0, 0.0], max = [1.0, 1.0] }}\n"
    );
    assert_scene_error(&huge, 15, &["generate[0].count", "more than"]);
    let pyramid = format!("{GOOD}[[generate]]\nkind = \"pyramid\"\nbase = 9000000000\nradius = [0.1, 0.1]\nregion = {{ min = [0.0, 0.0], max = [1.0, 1.0] }}\n");
    assert_scene_error(&pyramid, 15, &["generate[0].base", "more than"]);
    let drum = GOOD.replace(
        "segment = [[0.0, 0.0], [1.0, 0.0]]",
        "drum = { center = [0.0, 0.0], radius = 1.0, sides = 1000000000 }",
    );
    assert_scene_error(&drum, 11, &["wall[0].drum", "sides"]);
    // Hostile input: a truncated file, binary junk, an empty file.
    let _ = error_of(&GOOD[..GOOD.len() / 2]);
    let _ = error_of("\u{0}\u{1}\u{2}garbage = [[[");
    assert!(error_of("").to_string().contains("time"));
}

#[test]
fn effects_that_are_off_allocate_nothing_and_add_no_rows() {
    let with =
        scene::parse(&GOOD.replace("\"friction\"]", "\"friction\", \"rotation\"]"), Path::new("a.toml")).unwrap();
    let without = scene::parse(GOOD, Path::new("b.toml")).unwrap();
    assert!(with.world.bodies.angle.len() == 1 && with.world.bodies.inertia.len() == 1);
    assert!(
        without.world.bodies.angle.is_empty()
            && without.world.bodies.spin.is_empty()
            && without.world.bodies.inertia.is_empty()
    );
    assert!(without.world.bodies.memory_bytes() < with.world.bodies.memory_bytes());
    // A frictionless scene: tangential impulses stay exactly zero, the operator has no lever arms.
    let frictionless =
        scene::parse(&GOOD.replace("\"gravity\", \"friction\"", "\"gravity\""), Path::new("c.toml")).unwrap();
    let mut sim = Simulation::new(frictionless.world, frictionless.settings).unwrap();
    sim.keep_problems(true);
    for _ in 0..120 {
        sim.step().unwrap();
    }
    assert!(!sim.contacts().is_empty());
    assert!(sim.contacts().iter().all(|c| c.impulse[1] == 0.0 && c.impulse[0] > 0.0));
    let p = sim.last_problem().unwrap();
    assert!(p.mu.iter().all(|&m| m == 0.0));
    let moreau::problem::Delassus::MatrixFree(op) = &p.w else { panic!("simulation problems are matrix-free") };
    assert_eq!(op.dofs(), moreau::problem::matrix_free::Dofs { rotation: false, friction: false });
}

#[test]
fn cohesion_holds_a_disk_under_a_ceiling_until_its_weight_exceeds_it() {
    // A disk of mass m = ρπr² hangs under a ceiling segment: cohesion c per step holds it when
    // c ≥ m g h (the impulse of its weight over one step).
    let hanging = |cohesion: f64| {
        let text = format!(
            r#"
effects = ["gravity", "cohesion"]
[time]
step = 1e-3
steps = 200
[solver]
tol = 1e-10
[contact]
cohesion = {cohesion}
[[material]]
name = "m"
density = 1000.0
[[wall]]
segment = [[-1.0, 0.1], [1.0, 0.1]]
[[body]]
disk = {{ center = [0.0, 0.0], radius = 0.1 }}
"#
        );
        let s = scene::parse(&text, Path::new("cohesion.toml")).unwrap();
        let mut sim = Simulation::new(s.world, s.settings).unwrap();
        for _ in 0..200 {
            sim.step().unwrap();
        }
        sim.position(0).y
    };
    let weight_impulse = 1000.0 * std::f64::consts::PI * 0.01 * 9.81 * 1e-3;
    assert!(hanging(1.2 * weight_impulse).abs() < 1e-9, "held by cohesion");
    assert!(hanging(0.8 * weight_impulse) < -0.1, "too weak a bond lets it fall");
}

#[test]
fn run_writes_steps_summary_vtk_picture_and_dumped_problems() {
    let out = Scratch::new("run");
    let status = Command::new(env!("CARGO_BIN_EXE_moreau"))
        .args([
            "run",
            "scenes/pile.toml",
            "--device",
            "cpu",
            "--steps",
            "40",
            "--vtk-every",
            "20",
            "--dump-problem",
            "30",
            "--quiet",
            "--out",
        ])
        .arg(&out)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let stdout = String::from_utf8_lossy(&status.stdout);
    assert!(stdout.contains("pile: 40 steps"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
    let mut lines = csv.lines();
    let header = lines.next().unwrap();
    for col in [
        "step",
        "time",
        "contacts",
        "iterations",
        "gpu_iterations",
        "error",
        "converged",
        "max_penetration",
        "kinetic_energy",
        "seconds",
    ] {
        assert!(header.split(',').any(|c| c == col), "steps.csv lacks {col}: {header}");
    }
    assert_eq!(lines.count(), 40);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["steps"], 40);
    assert_eq!(summary["device"], "cpu");
    // The pile's grains rest on a floor: the velocity scale is at least a step of gravity.
    assert_eq!(summary["criterion"], "natural");
    assert!(summary["max_velocity_scale"].as_f64().unwrap() >= 9.81 * 1e-3 * 0.999, "{summary}");
    for f in [
        "grains.pvd",
        "contacts.pvd",
        "walls.pvd",
        "grains_000000.vtu",
        "grains_000020.vtu",
        "contacts_000040.vtu",
        "state_000040.png",
        "problem_000030.dat",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let pvd = std::fs::read_to_string(out.join("grains.pvd")).unwrap();
    assert!(
        pvd.contains("grains_000000.vtu") && pvd.contains("grains_000020.vtu") && pvd.contains("grains_000040.vtu")
    );
    let vtu = std::fs::read_to_string(out.join("contacts_000040.vtu")).unwrap();
    assert!(vtu.contains("normal_impulse") && vtu.contains(moreau::io::vtk::STATUS_LEGEND));
    assert!(std::fs::read_to_string(out.join("grains_000040.vtu")).unwrap().contains("orientation"));
    // Each contact's force vector is its impulse over the step, in the (normal, tangent) frame.
    let cells = contact_cells(&out.join("contacts_000040.vtu"));
    let (rn, rt, normal, force) =
        (&cells["normal_impulse"], &cells["tangential_impulse"], &cells["normal"], &cells["force"]);
    assert!(!rn.is_empty() && force.len() == 3 * rn.len() && cells["contact_point"].len() == 3 * rn.len());
    for a in 0..rn.len() {
        let (nx, ny) = (normal[3 * a], normal[3 * a + 1]);
        let expected = [(rn[a] * nx - rt[a] * ny) / 2e-3, (rn[a] * ny + rt[a] * nx) / 2e-3];
        for (got, want) in [force[3 * a], force[3 * a + 1]].iter().zip(expected) {
            assert!((got - want).abs() <= 1e-12 * want.abs().max(1e-9), "contact {a}: force {got} vs {want}");
        }
    }
    assert!(cells["body"].iter().zip(&cells["other_is_wall"]).all(|(b, w)| *b >= 0.0 && (*w == 0.0 || *w == 1.0)));
    // `moreau stats` turns the contacts file into the density of normal forces over their mean.
    let stats = Command::new(env!("CARGO_BIN_EXE_moreau"))
        .args(["stats", out.join("contacts_000040.vtu").to_str().unwrap(), "--bins", "10"])
        .output()
        .unwrap();
    assert!(stats.status.success(), "{}", String::from_utf8_lossy(&stats.stderr));
    let pdf = std::fs::read_to_string(out.join("force_pdf_000040.csv")).unwrap();
    let rows: Vec<(f64, f64)> = pdf
        .lines()
        .skip(1)
        .map(|l| {
            let (x, d) = l.split_once(',').unwrap();
            (x.parse().unwrap(), d.parse().unwrap())
        })
        .collect();
    let width = 2.0 * rows[0].0;
    assert_eq!(rows.len(), 10);
    assert!((rows.iter().map(|r| r.1 * width).sum::<f64>() - 1.0).abs() < 1e-9, "{pdf}");
    let bad = Command::new(env!("CARGO_BIN_EXE_moreau"))
        .args(["stats", out.join("steps.csv").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("steps.csv"));
    // A missing file and a folder are worded as such, not as XML errors.
    for (path, says) in
        [(out.join("contacts_999999.vtu"), "No such file"), (out.to_path_buf(), "a folder, not a .vtu file")]
    {
        let o = Command::new(env!("CARGO_BIN_EXE_moreau")).arg("stats").arg(&path).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(says) && !err.contains("XML"), "{err}");
    }
    // `moreau picture` redraws a saved step coloured by pressure, and the run as an animation.
    let picture = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_moreau")).arg("picture").arg(&out).args(args).output().unwrap()
    };
    let o = picture(&["--step", "20", "--color", "pressure"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("state_000020.png").exists());
    let o = picture(&["--animate", "--width", "400"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut gif = gif::DecodeOptions::new().read_info(std::fs::File::open(out.join("run.gif")).unwrap()).unwrap();
    assert_eq!(gif.width(), 400);
    let mut frames = 0;
    while gif.read_next_frame().unwrap().is_some() {
        frames += 1;
    }
    assert_eq!(frames, 3, "steps 0, 20 and 40 were saved");
    let o = picture(&["--step", "7"]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--step 7: ")
            && String::from_utf8_lossy(&o.stderr).contains("steps 0, 20, 40")
    );
    let o = picture(&["--color", "temperature"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("temperature"));
    // What a picture reads back from the VTK files is the simulation's state.
    let mut sim = Simulation::from_scene(&scenes_dir().join("pile.toml")).unwrap();
    for _ in 0..10 {
        sim.step().unwrap();
    }
    moreau::io::vtk::write_step(&sim, &out, 10).unwrap();
    let (live, saved) = (moreau::io::picture::Frame::of(&sim), moreau::io::picture::Frame::read(&out, 10).unwrap());
    assert_eq!(live.grains.len(), saved.grains.len());
    assert_eq!(live.chains.len(), saved.chains.len());
    for (a, b) in live.grains.iter().zip(&saved.grains) {
        assert!(a.position == b.position && a.radius == b.radius && a.velocity == b.velocity && a.tag == b.tag);
    }
    for (a, b) in live.chains.iter().zip(&saved.chains) {
        assert!(
            (a.body, a.other, a.from, a.to, a.force, a.normal) == (b.body, b.other, b.from, b.to, b.force, b.normal)
        );
    }
    assert_eq!(live.pressures(), saved.pressures());
    assert_eq!(live.walls, saved.walls);
    // The dumped problem is a valid Siconos file that `moreau solve` solves.
    let problem = moreau::io::siconos::read_fc2d(&out.join("problem_000030.dat")).unwrap();
    assert!(problem.n_contacts() > 0);
    let report = moreau::solve(
        &problem,
        moreau::SolverKind::Nlgs,
        &moreau::SolverOptions { tol: 1e-6, ..Default::default() },
        None,
    );
    assert!(report.converged, "{}", report.stop_reason);
    // A bad scene gives exit code 2 and names the file.
    let bad = out.join("bad.toml");
    std::fs::write(&bad, "effects = [\"gravity\"]\n[time]\nstep = 1.0\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_moreau")).args(["run", "--quiet"]).arg(&bad).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("bad.toml"));
    let _ = std::fs::remove_dir_all(&out);
}

/// The GPU path stops on the natural-map error or a velocity test only: with an LMGC90 criterion
/// `--device auto` picks the CPU and says why, and `--device gpu` is refused by name before any
/// adapter is sought.
#[test]
fn a_criterion_the_gpu_lacks_keeps_the_run_on_the_cpu() {
    let out = Scratch::new("criterion");
    let run = |device: &str, criterion: &str| {
        Command::new(env!("CARGO_BIN_EXE_moreau"))
            .args(["run", scenes_dir().join("pile.toml").to_str().unwrap(), "--steps", "1", "--quiet"])
            .args(["--device", device, "--criterion", criterion, "--out"])
            .arg(&out)
            .output()
            .unwrap()
    };
    let auto = run("auto", "qm16");
    let stderr = String::from_utf8_lossy(&auto.stderr);
    assert!(auto.status.success(), "{stderr}");
    assert!(
        stderr.contains(
            "device: cpu (the GPU path stops on the natural-map error or a velocity test only, not on the qm16 criterion)"
        ),
        "{stderr}"
    );
    let gpu = run("gpu", "maxm");
    let stderr = String::from_utf8_lossy(&gpu.stderr);
    assert!(!gpu.status.success());
    assert!(stderr.contains("not on the maxm criterion"), "{stderr}");
}

/// The cell arrays of a contacts `.vtu`, by name, as f64.
fn contact_cells(path: &std::path::Path) -> std::collections::HashMap<String, Vec<f64>> {
    use vtkio::model::{Attribute, DataSet, Piece};
    let vtk = vtkio::Vtk::import(path).unwrap();
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else { panic!("not an unstructured grid") };
    let Piece::Inline(piece) = &pieces[0] else { panic!("not inline") };
    piece
        .data
        .cell
        .iter()
        .filter_map(|a| match a {
            Attribute::DataArray(d) => Some((d.name.clone(), d.data.clone().cast_into::<f64>().unwrap())),
            _ => None,
        })
        .collect()
}

#[test]
fn walls_csv_holds_each_walls_position_and_load_when_asked_for() {
    let dir = Scratch::new("walls");
    let scene = dir.join("pile.toml");
    let text = std::fs::read_to_string("scenes/pile.toml").unwrap();
    std::fs::write(&scene, text.replace("[output]\n", "[output]\nwall_forces = true\n")).unwrap();
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_moreau"))
        .args(["run", scene.to_str().unwrap(), "--steps", "300", "--device", "cpu", "--quiet", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("walls.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("step,time,wall,x,y,angle,fx,fy,moment"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
    let walls = rows.iter().filter(|r| r[0] == 1.0).count();
    assert!(walls >= 1 && rows.len() == 300 * walls, "{} rows for {walls} walls", rows.len());
    // At rest (step 300) the walls carry the pile's weight: 400 disks of glass, radius 2–3 mm.
    let last: Vec<&Vec<f64>> = rows.iter().filter(|r| r[0] == 300.0).collect();
    let fy: f64 = last.iter().map(|r| r[7]).sum();
    let weight = 2500.0 * 9.81 * 400.0 * std::f64::consts::PI * 0.0025f64.powi(2);
    assert!(fy < 0.0 && (fy.abs() - weight).abs() < 0.15 * weight, "Σ fy {fy} vs weight about {weight}");
}
