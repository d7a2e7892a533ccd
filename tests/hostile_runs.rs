//! Hostile scenes and flags on `moreau run` and its siblings: blow-ups stop the run with an
//! error naming the body and the step, keep the outputs and the last good state, and exit
//! non-zero; unintegrable scenes are refused up front; suspicious starts are warned about;
//! outputs never land outside their directory nor sit beside stale files; nothing is silently
//! accepted.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

mod common;

use std::path::Path;
use std::process::{Command, Output};

fn moreau() -> Command {
    Command::new(env!("CARGO_BIN_EXE_moreau"))
}

fn scratch(name: &str) -> Scratch {
    Scratch::new(&format!("hostile_{name}"))
}

/// Runs `moreau run` on `scene` (written to a scratch directory) with `args`; the output
/// directory is `<scratch>/out`.
fn run_scene(name: &str, scene: &str, args: &[&str]) -> (Output, Scratch) {
    let dir = scratch(name);
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, scene).unwrap();
    let out = dir.join("out");
    let output = moreau()
        .arg("run")
        .arg(&path)
        .args(["--quiet", "--device", "cpu", "--out"])
        .arg(&out)
        .args(args)
        .output()
        .unwrap();
    (output, dir)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The run failed with exit code 2 and a message holding every needle.
fn refused(o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "expected exit 2:\n{e}");
    assert!(!e.contains("panicked"), "{e}");
    for n in needles {
        assert!(e.contains(n), "message does not name {n:?}:\n{e}");
    }
}

fn disk_scene(h: &str, radius: &str, velocity: &str, gravity: &str, walls: bool) -> String {
    format!(
        "effects = [\"gravity\"]\ngravity = [0.0, {gravity}]\n[time]\nstep = {h}\nsteps = 3000\n\
         [[material]]\nname = \"g\"\ndensity = 2500.0\n{}[[body]]\ndisk = {{ center = [0.0, 0.5], radius = {radius} }}\n\
         velocity = [0.0, {velocity}]\n",
        if walls { "[[wall]]\nsegment = [[-1.0, 0.0], [1.0, 0.0]]\n" } else { "" }
    )
}

#[test]
fn scenes_that_cannot_be_integrated_are_refused_up_front() {
    let (o, _) = run_scene("huge_radius", &disk_scene("1e-3", "1e200", "0.0", "-9.81", true), &[]);
    refused(&o, &["body[0]", "mass", "beyond f64"]);
    let (o, _) = run_scene("huge_speed", &disk_scene("1e-3", "0.01", "-1e160", "-9.81", true), &[]);
    refused(&o, &["body 0", "kinetic energy overflows"]);
    let (o, _) = run_scene("huge_step", &disk_scene("1e6", "0.01", "0.0", "-9.81", true), &[]);
    refused(&o, &["body 0", "h = 1e6", "smaller time step"]);
    let (o, _) = run_scene(
        "far_away",
        &disk_scene("1e-3", "1e-9", "0.0", "-9.81", true).replace("[0.0, 0.5]", "[1e9, 0.5]"),
        &[],
    );
    refused(&o, &["coordinates reach", "smallest grain radius"]);
}

#[test]
fn a_run_that_blows_up_stops_at_the_step_and_keeps_its_outputs() {
    // Without walls a fast fall is allowed to start; with g = 1e4 m/s² the grain outruns 1e3
    // scene extents per step after about 2,000 steps.
    let (o, dir) = run_scene("runaway", &disk_scene("1e-3", "0.01", "0.0", "-1e4", false), &[]);
    let out = dir.join("out");
    refused(&o, &["body 0 ran away", "step ", "is kept"]);
    let e = stderr(&o);
    assert!(!e.contains("squeezed"), "nothing here moves by prescription: {e}");
    let step: usize = e.split("step ").nth(1).and_then(|s| s.split(':').next()).and_then(|s| s.parse().ok()).unwrap();
    assert!(step > 1000, "{e}");
    let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
    assert_eq!(csv.lines().count(), step, "steps.csv holds the {} steps before the failure", step - 1);
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("\"failure\"") && summary.contains("ran away"), "{summary}");
    let last_good = out.join(format!("grains_{:06}.vtu", step - 1));
    assert!(last_good.exists(), "the last good state is written as {}", last_good.display());
}

/// A fixed box driven at 1 m/s pushes a disk into a wall: no impulse can hold the squeeze (the
/// box's face and the wall are exactly parallel, so the impulses grow and cancel, and the box
/// passes through the disk), and the run stops naming that cause, not only the time step.
#[test]
fn a_grain_squeezed_by_a_driven_fixed_body_stops_the_run_naming_the_squeeze() {
    let scene = "effects = [\"gravity\", \"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 600\n\
                 [solver]\nmax_iter = 500\n[contact]\nfriction = 0.3\n[[material]]\nname = \"m\"\ndensity = 1000.0\n\
                 [[wall]]\nsegment = [[-1.0, 0.0], [1.0, 0.0]]\n[[wall]]\nsegment = [[0.5, 0.0], [0.5, 1.0]]\n\
                 [[body]]\nregular = { center = [0.0, 0.1], radius = 0.1, sides = 4, angle = 0.7853981633974483 }\n\
                 fixed = true\nvelocity = [1.0, 0.0]\n[[body]]\ndisk = { center = [0.3, 0.05], radius = 0.05 }\n";
    let (o, _) = run_scene("squeeze", scene, &[]);
    refused(&o, &["body 0 and body 1 overlap by", "squeezed between walls or fixed bodies whose motion is prescribed"]);
}

#[test]
fn suspicious_starts_are_warned_about() {
    let scene = "effects = [\"gravity\"]\n[time]\nstep = 1e-3\nsteps = 2\n[[material]]\nname = \"g\"\ndensity = 1.0\n\
        [[wall]]\nbox = { min = [0.0, 0.0], max = [1.0, 0.2] }\n\
        [[wall]]\nbox = { min = [0.4, 0.0], max = [0.6, 0.2] }\n\
        [[body]]\ndisk = { center = [0.5, 0.1], radius = 0.05 }\n\
        [[body]]\ndisk = { center = [5.0, -5.0], radius = 0.05 }\n\
        [[body]]\ndisk = { center = [0.5, 0.5], radius = 0.05 }\n\
        [[body]]\ndisk = { center = [0.5, 0.5], radius = 0.05 }\n\
        [[body]]\ndisk = { center = [0.2, 0.249], radius = 0.05 }\n";
    let (o, _) = run_scene("suspicious", scene, &[]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    for needle in [
        "start outside the walls' bounds, below or beside them (first: body 1",
        // Body 0 lies in both boxes, body 4 2 % of its radius into the first's top: two grains.
        "2 grain(s) start overlapping a wall by more than 1 % of their radius (deepest: body 0",
        "same position (first: bodies 2 and 3",
    ] {
        assert!(e.contains(needle), "no warning {needle:?}:\n{e}");
    }
}

#[test]
fn moreau_check_reports_a_scenes_problems_without_running_it() {
    let dir = scratch("check");
    let check = |name: &str, scene: &str, strict: bool| {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, scene).unwrap();
        let mut cmd = moreau();
        cmd.arg("check").arg(&path);
        if strict {
            cmd.arg("--strict");
        }
        let o = cmd.output().unwrap();
        let text = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
        (o.status.success(), text)
    };
    let (ok, text) = check("clean", &disk_scene("1e-3", "0.05", "0.0", "-9.81", true), true);
    assert!(ok && text.contains("1 bodies, 1 walls") && text.contains("no warning"), "{text}");
    let overlapping =
        disk_scene("1e-3", "0.05", "0.0", "-9.81", true) + "[[body]]\ndisk = { center = [0.0, 0.5], radius = 0.05 }\n";
    let (ok, text) = check("overlap", &overlapping, false);
    assert!(ok && text.contains("same position (first: bodies 0 and 1") && text.contains("1 warning"), "{text}");
    let deep =
        disk_scene("1e-3", "0.05", "0.0", "-9.81", true) + "[[body]]\ndisk = { center = [0.0, 0.58], radius = 0.05 }\n";
    let (ok, text) = check("deep", &deep, false);
    assert!(ok && text.contains("1 pair(s) of bodies start overlapping") && text.contains("2.000e-2 m"), "{text}");
    let (ok, text) = check("overlap_strict", &overlapping, true);
    assert!(!ok && text.contains("--strict: 1 warning"), "{text}");
    let (ok, text) = check("fast", &disk_scene("1e6", "0.01", "0.0", "-9.81", true), false);
    assert!(!ok && text.contains("smaller time step"), "{text}");
    let (ok, text) = check("broken", "[time]\nstep = 1e-3\n", false);
    assert!(!ok && text.contains("steps"), "{text}");
    assert!(!dir.join("out").exists(), "check writes nothing");
}

const SMALL: &str = "[time]\nstep = 1e-3\nsteps = 3\n[[material]]\nname = \"g\"\ndensity = 1.0\n\
    [[body]]\ndisk = { center = [0.0, 0.0], radius = 0.1 }\n";

#[test]
fn outputs_stay_in_their_directory_and_hold_no_stale_files() {
    for name in ["../../escape", "/tmp/absolute", "..", "a/b"] {
        let (o, _) = run_scene("bad_name", &format!("name = {name:?}\n{SMALL}"), &[]);
        refused(&o, &["name", "not a plain file name"]);
    }
    let (o, dir) = run_scene("stale", &format!("[output]\nvtk = true\nevery = 1\n{SMALL}"), &[]);
    let out = dir.join("out");
    assert!(o.status.success(), "{}", stderr(&o));
    for stale in ["grains_000999.vtu", "state_000999.png", "problem_000999.dat"] {
        std::fs::write(out.join(stale), "old").unwrap();
    }
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let scene = out.parent().unwrap().join("stale.toml");
    let again =
        moreau().arg("run").arg(&scene).args(["--quiet", "--device", "cpu", "--out"]).arg(&out).output().unwrap();
    assert!(again.status.success() && stderr(&again).contains("of an earlier run"), "{}", stderr(&again));
    assert!(!out.join("grains_000999.vtu").exists() && !out.join("state_000999.png").exists());
    assert!(out.join("notes.txt").exists(), "a file the run did not write is left alone");
    assert!(out.join("grains_000003.vtu").exists());
}

#[test]
fn the_time_step_is_set_from_the_command_line_and_refused_when_it_cannot_be() {
    let (o, dir) = run_scene("time_step", SMALL, &["--time-step", "5e-4"]);
    let out = dir.join("out");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("h = 5e-4"), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
    let last: f64 = csv.lines().last().unwrap().split(',').nth(1).unwrap().parse().unwrap();
    assert!((last - 3.0 * 5e-4).abs() < 1e-15, "3 steps of 5e-4 s end at {last}");
    for bad in ["0", "-1e-3", "nan", "inf"] {
        let (o, _) = run_scene("bad_time_step", SMALL, &[&format!("--time-step={bad}")]);
        refused(&o, &["--time-step", "must be finite and > 0"]);
    }
    let o = moreau().args(["run", "scenes/signorini_punch.toml", "--time-step", "1e-3"]).output().unwrap();
    refused(&o, &["--time-step", "punch scene"]);
}

#[test]
fn steps_that_never_come_and_zero_periods_are_refused() {
    let (o, _) = run_scene("late_dump", SMALL, &["--dump-problem", "7"]);
    refused(&o, &["--dump-problem 7", "steps 1 to 3"]);
    let (o, _) = run_scene("late_picture", SMALL, &["--picture-step", "9"]);
    refused(&o, &["--picture-step 9", "steps 1 to 3"]);
    let (o, _) = run_scene("zero_every", &format!("[output]\nvtk = true\nevery = 0\n{SMALL}"), &[]);
    refused(&o, &["output.every", ">= 1"]);
}

#[test]
fn nothing_is_silently_accepted() {
    let polygon =
        |vertices: &str| format!("{SMALL}[[body]]\npolygon = {{ center = [1.0, 0.0], vertices = {vertices} }}\n");
    let (o, _) = run_scene("concave", &polygon("[[0.0, 0.0], [1.0, 0.0], [0.2, 0.2], [0.0, 1.0]]"), &[]);
    assert!(o.status.success(), "a concave outline is accepted: {}", stderr(&o));
    let star = "[[0.0, 1.0], [0.588, -0.809], [-0.951, 0.309], [0.951, 0.309], [-0.588, -0.809]]";
    let (o, _) = run_scene("star", &polygon(star), &[]);
    refused(&o, &["polygon", "cross or touch", "vertex 0", "vertex 2"]);
    let (o, _) = run_scene("spike", &polygon("[[0.0, 0.0], [1.0, 0.0], [0.5, 0.0], [0.5, 0.5]]"), &[]);
    refused(&o, &["folds back", "vertex 1"]);
    // A vertex beyond what the f32 hull can take (parry2d panicked on it), on a body and a wall.
    let (o, _) = run_scene("far_vertex", &polygon("[[0.0, 0.0], [1.0, 0.0], [0.0, 1e308]]"), &[]);
    refused(&o, &["vertex 2", "beyond 1e18 m"]);
    let wall = format!("{SMALL}[[wall]]\npolygon = [[2.0, 1e308], [0.7, 0.5], [2.0, -1.0]]\n");
    let (o, _) = run_scene("far_wall_vertex", &wall, &[]);
    refused(&o, &["wall[", "vertex 0", "beyond 1e18 m"]);
    let (o, _) = run_scene("clockwise", &polygon("[[0.0, 0.0], [0.0, 0.1], [0.1, 0.1], [0.1, 0.0]]"), &[]);
    assert!(o.status.success(), "a clockwise convex polygon is accepted: {}", stderr(&o));
    let (o, _) = run_scene("gravity3", &format!("effects = [\"gravity\"]\ngravity = [0.0, -9.81, 0.0]\n{SMALL}"), &[]);
    refused(&o, &["line 2", "exactly 2 values"]);
    let (o, _) = run_scene("point3", &SMALL.replace("[0.0, 0.0]", "[0.0, 0.0, 1.0]"), &[]);
    refused(&o, &["exactly 2 values"]);
    let dir = scratch("flags");
    let o = moreau().args(["generate", "lattice", "--n", "0", "--out"]).arg(dir.join("p.dat")).output().unwrap();
    refused(&o, &["--n 0", "at least 1"]);
    let o = moreau().args(["bench", "--sizes", "100", "--solve-to=-1"]).output().unwrap();
    refused(&o, &["--solve-to -1", "> 0"]);
    // A thread count nobody means: refused at once, not minutes spent making the threads.
    let (o, _) = run_scene("threads", SMALL, &["--threads", "100000"]);
    refused(&o, &["--threads 100000", "1..=1024"]);
    let o = moreau().args(["solve", "tests/data/none.dat", "--threads", "5000"]).output().unwrap();
    refused(&o, &["--threads 5000"]);
    // A lone disk in the air: no step has a problem to time sweeps on.
    std::fs::write(dir.join("lone.toml"), SMALL).unwrap();
    let o = moreau()
        .args(["bench", "--steps", "1", "--threads-list", "1", "--scene"])
        .arg(dir.join("lone.toml"))
        .output()
        .unwrap();
    refused(&o, &["lone.toml", "no contacts"]);
    // Rolling rows: three unknowns a contact on the CPU, and no GPU rows (the GPU has none).
    let o = moreau()
        .args(["bench", "--steps", "1", "--sweeps", "2", "--threads-list", "1", "--scene"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/column_collapse_rolling.toml"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("no GPU rows: rolling resistance"), "{out}");
    // Its full check of the error is timed beside the sweep, and given in sweeps too.
    let row = out.lines().find(|l| l.starts_with("| 1 |")).expect("the one-thread row");
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let sweep: f64 = cells[8].parse().unwrap();
    let (check, in_sweeps) = cells[9].split_once(" (").expect("a check and its share of a sweep");
    let (check, in_sweeps): (f64, f64) = (check.parse().unwrap(), in_sweeps.trim_end_matches(')').parse().unwrap());
    assert!(check > 0.0 && check.is_finite() && (in_sweeps - check / sweep).abs() <= 0.01 + 0.01 * in_sweeps, "{row}");
    let o = moreau()
        .args([
            "sweep",
            "scenes/pile.toml",
            "--solvers",
            "nlgs",
            "--tols",
            "1e-2,1e-3",
            "--profile-tol",
            "1e-6",
            "--out",
        ])
        .arg(dir.join("sweep"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    refused(&o, &["--profile-tol", "finest of --tols"]);
}

#[test]
fn messages_say_things_once_and_cite_nothing_missing() {
    let dir = scratch("dir_as_file");
    for command in ["run", "solve"] {
        let o = moreau().arg(command).arg(&dir).output().unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert_eq!(e.matches("os error").count(), 1, "the OS error once: {e}");
    }
    for command in ["run", "solve", "bench", "sweep", "friction-study", "generate"] {
        let help = moreau().args([command, "--help"]).output().unwrap();
        let text = String::from_utf8_lossy(&help.stdout);
        assert!(help.status.success());
        assert!(!text.contains('§') && !text.contains("[`") && !text.contains("crate::"), "{command} --help:\n{text}");
    }
    let readme = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    assert!(!readme.contains("notes §"), "README cites notes that are not in the repository");
}

/// Under the velocity test a run says when its bound was far looser than a step of gravity: a
/// grain sliding down a wall at 3 m/s beside a resting stack sets the scale of every contact.
#[test]
fn a_run_warns_when_a_fast_grain_loosens_the_velocity_tests_bound() {
    let scene = |sliding: bool| common::stack_scene(sliding, 2, "tol = 1e-6\ncriterion = \"velocity\"\n");
    let (resting, _) = run_scene("velocity_scale_resting", &scene(false), &[]);
    assert!(resting.status.success(), "{}", stderr(&resting));
    assert!(!stderr(&resting).contains("a step of gravity"), "{}", stderr(&resting));
    let (sliding, dir) = run_scene("velocity_scale_sliding", &scene(true), &[]);
    let out = dir.join("out");
    let e = stderr(&sliding);
    assert!(sliding.status.success(), "{e}");
    // 3 m/s and two steps of gravity: about 300 steps of gravity.
    assert!(e.contains("tol × up to 3.0") && e.contains("308× a step of gravity"), "{e}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["criterion"], "velocity");
}

/// Extreme punches: one so soft that its stresses underflow f32 (Young's modulus 1e-300 Pa,
/// stresses about 1e-303) still draws its stress picture (the colour scale once divided 0 by 0
/// in f32, and plotters' colour map panicked on the NaN); a modulus whose stiffness overflows
/// f64, and a punch pushed further than its block is high (whose load overflowed and panicked
/// in the condensation), are refused naming the value.
#[test]
fn extreme_punches_run_or_are_refused_naming_the_value() {
    let scene =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/signorini_punch.toml")).unwrap();
    assert!(scene.contains("young = 1.0e7") && scene.contains("displacement = 0.01"), "the shipped punch moved");
    let (o, dir) = run_scene("soft_punch", &scene.replace("young = 1.0e7", "young = 1e-300"), &[]);
    assert!(o.status.success() && !stderr(&o).contains("panicked"), "{}", stderr(&o));
    assert!(dir.join("out").join("sigma_yy.png").is_file());
    let (o, _) = run_scene("stiff_punch", &scene.replace("young = 1.0e7", "young = 1e308"), &[]);
    refused(&o, &["young = 1e308", "overflow"]);
    let (o, _) = run_scene("deep_punch", &scene.replace("displacement = 0.01", "displacement = -1e308"), &[]);
    refused(&o, &["displacement = -1e308", "height"]);
}
