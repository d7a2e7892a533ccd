//! Restarts: a run of 2N steps equals N steps, a restart from the checkpoint and N more, bit for
//! bit, for one thread, two threads (coloured Gauss–Seidel, whose colouring memory the
//! checkpoint carries) and the GPU; a checkpoint is refused for another scene or when tampered.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use moreau::io::checkpoint::{read_checkpoint, write_checkpoint};
use moreau::Simulation;

fn moreau() -> Command {
    Command::new(env!("CARGO_BIN_EXE_moreau"))
}

fn temp(name: &str) -> Scratch {
    Scratch::new(&format!("restart_{name}"))
}

/// `scenes/pile.toml` with a checkpoint every `every` steps, written into `dir`.
fn pile_with_checkpoints(dir: &Path, every: usize) -> PathBuf {
    let text = std::fs::read_to_string("scenes/pile.toml").unwrap();
    let path = dir.join("pile.toml");
    std::fs::write(&path, text.replace("[output]\n", &format!("[output]\ncheckpoint_every = {every}\n"))).unwrap();
    path
}

fn run(args: &[&str]) -> String {
    let out = moreau().args(args).args(["--quiet"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "moreau {args:?}: {err}");
    err
}

/// steps.csv without its three timing columns.
fn steps_without_timings(dir: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join("steps.csv")).unwrap();
    let mut lines = text.lines();
    let timing: Vec<bool> = lines.next().unwrap().split(',').map(|c| c.ends_with("seconds")).collect();
    assert!(timing.iter().any(|&t| t), "steps.csv has timing columns");
    lines
        .map(|l| l.split(',').zip(&timing).filter(|(_, &t)| !t).map(|(f, _)| f).collect::<Vec<_>>().join(","))
        .collect()
}

fn forty_equals_twenty_plus_twenty(device: &str, threads: &str) {
    let dir = temp(&format!("{device}_{threads}"));
    let scene = pile_with_checkpoints(&dir, 20);
    let (whole, second) = (dir.join("whole"), dir.join("second"));
    let common = ["--device", device, "--threads", threads];
    let s = scene.to_str().unwrap();
    run(&[&["run", s, "--steps", "40", "--out", whole.to_str().unwrap()][..], &common].concat());
    let checkpoint = whole.join("checkpoint_000020.json");
    let said = run(&[
        &["run", s, "--restart", checkpoint.to_str().unwrap(), "--out", second.to_str().unwrap()][..],
        &common,
        &["--steps", "20"],
    ]
    .concat());
    assert!(said.contains("restarting from step 20"), "{said}");
    let (a, b) = (steps_without_timings(&whole), steps_without_timings(&second));
    assert_eq!((a.len(), b.len()), (40, 20));
    assert_eq!(a[20..], b[..], "steps 21 to 40 differ ({device}, {threads} threads)");
    // The whole state after step 40, warm start and colours included, is the same bytes.
    let end = |d: &Path| std::fs::read(d.join("checkpoint_000040.json")).unwrap();
    assert!(end(&whole) == end(&second), "the states after step 40 differ ({device}, {threads} threads)");
}

#[test]
fn forty_steps_equal_twenty_a_restart_and_twenty_on_one_and_two_threads() {
    forty_equals_twenty_plus_twenty("cpu", "1");
    forty_equals_twenty_plus_twenty("cpu", "2");
}

#[test]
fn forty_steps_equal_twenty_a_restart_and_twenty_on_the_gpu() {
    if common::gpu_context().is_none() {
        return;
    }
    forty_equals_twenty_plus_twenty("gpu", "1");
}

#[test]
fn a_threaded_pile_restarts_bit_for_bit_from_a_checkpoint_file() {
    // 20,000 contacts on 2 threads: the sweep runs by blocks of the contacts' order, which the
    // restarted run rebuilds alike; no contact colouring is needed, so the checkpoint carries
    // none (a GPU run's carries its colours: `forty_steps_equal_twenty_a_restart_and_twenty_on_the_gpu`).
    let dir = temp("colours");
    let scene = Path::new("scenes/pile_10k.toml");
    let mut first = Simulation::from_scene(scene).unwrap();
    first.set_threads(2).unwrap();
    for _ in 0..2 {
        first.step().unwrap();
    }
    let mut c = first.checkpoint();
    assert!(c.moving.is_none() && c.contacts.iter().all(|x| x.colour.is_none()), "the block sweep coloured nothing");
    c.scene_fingerprint = moreau::io::checkpoint::fingerprint(&std::fs::read(scene).unwrap());
    let file = dir.join("checkpoint.json");
    write_checkpoint(&c, &file).unwrap();
    let read = read_checkpoint(&file, scene).unwrap();
    assert_eq!(read, c, "a checkpoint reads back to the same bits");
    let mut second = Simulation::from_scene(scene).unwrap();
    second.set_threads(2).unwrap();
    second.restore(&read).unwrap();
    for _ in 0..2 {
        let (a, b) = (first.step().unwrap(), second.step().unwrap());
        assert_eq!((a.iterations, a.error.to_bits()), (b.iterations, b.error.to_bits()));
    }
    let bits = |s: &Simulation| s.positions().iter().flat_map(|p| [p.x.to_bits(), p.y.to_bits()]).collect::<Vec<_>>();
    assert!(bits(&first) == bits(&second));
}

#[test]
fn a_checkpoint_is_refused_for_another_scene_or_when_it_was_tampered_with() {
    let dir = temp("refusals");
    let scene = pile_with_checkpoints(&dir, 10);
    let s = scene.to_str().unwrap();
    let out = dir.join("out");
    run(&["run", s, "--steps", "10", "--out", out.to_str().unwrap(), "--threads", "1", "--device", "cpu"]);
    let checkpoint = out.join("checkpoint_000010.json");
    let refusal = |scene: &Path, checkpoint: &Path, extra: &[&str]| {
        let o = moreau()
            .args(["run", scene.to_str().unwrap(), "--restart", checkpoint.to_str().unwrap(), "--quiet"])
            .args(["--out", dir.join("again").to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap();
        assert!(!o.status.success(), "a bad restart ran");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    // Another scene file (here: one changed by a character).
    let other = dir.join("other.toml");
    std::fs::write(&other, std::fs::read_to_string(&scene).unwrap().replace("friction = 0.4", "friction = 0.5"))
        .unwrap();
    let e = refusal(&other, &checkpoint, &[]);
    assert!(e.contains("the scene file changed") && e.contains("other.toml"), "{e}");
    // Tampered contents, each refused with what is wrong.
    let original = std::fs::read_to_string(&checkpoint).unwrap();
    let c: serde_json::Value = serde_json::from_str(&original).unwrap();
    let tamper = |edit: &dyn Fn(&mut serde_json::Value), message: &str| {
        let mut bad = c.clone();
        edit(&mut bad);
        let path = dir.join("bad.json");
        std::fs::write(&path, bad.to_string()).unwrap();
        let e = refusal(&scene, &path, &["--steps", "5"]);
        assert!(e.contains(message), "{e} should say {message:?}");
    };
    tamper(&|c| c["position"].as_array_mut().unwrap().truncate(3), "position has 3 entries, the scene 400");
    tamper(&|c| c["velocity"][0][0] = serde_json::Value::Null, "not a moreau checkpoint");
    tamper(&|c| c["contacts"][0]["body"] = 9999.into(), "which the scene lacks");
    tamper(&|c| c["contacts"][0]["other_wall"] = 0.into(), "exactly one of other_body, other_wall");
    tamper(&|c| c["format"] = 7.into(), "format 7 is not 1");
    tamper(&|c| c["time"] = (-1.0).into(), "time -1 is negative");
    tamper(&|c| c["contacts"].as_array_mut().unwrap().reverse(), "not sorted");
    tamper(&|c| c["shapes"] = "fnv1a64:0000000000000000".into(), "other shapes");
    // A checkpoint at the scene's last step needs --steps to go on.
    std::fs::write(
        dir.join("short.toml"),
        std::fs::read_to_string(&scene).unwrap().replace("steps = 300", "steps = 10"),
    )
    .unwrap();
    let short_checkpoint = dir.join("short_ck.json");
    let mut at_end = c.clone();
    at_end["scene_fingerprint"] =
        moreau::io::checkpoint::fingerprint(&std::fs::read(dir.join("short.toml")).unwrap()).into();
    std::fs::write(&short_checkpoint, at_end.to_string()).unwrap();
    let e = refusal(&dir.join("short.toml"), &short_checkpoint, &[]);
    assert!(e.contains("the scene's last: give --steps"), "{e}");
}

#[test]
fn a_checkpoint_is_refused_for_bodies_of_other_shapes() {
    // What a generator that now draws other grains would give: the same scene file, other bodies.
    let scene = Path::new("scenes/pile.toml");
    let mut sim = Simulation::from_scene(scene).unwrap();
    sim.step().unwrap();
    let c = sim.checkpoint();
    assert!(Simulation::from_scene(scene).unwrap().restore(&c).is_ok(), "the same scene's bodies");
    type Change = fn(&mut moreau::World);
    let changes: [(&str, Change); 3] = [
        ("a radius", |w| w.bodies.shape[7] = moreau::world::BodyShape::Disk { radius: 0.123 }),
        ("a material", |w| w.bodies.material[7] += 1),
        ("a fixing", |w| w.bodies.inv_mass[7] = 0.0),
    ];
    for (what, change) in changes {
        let mut other = Simulation::from_scene(scene).unwrap();
        change(&mut other.world);
        let e = other.restore(&c).unwrap_err().to_string();
        assert!(e.contains("other shapes") && e.contains("generator"), "{what}: {e}");
        assert_eq!(other.steps_done(), 0, "{what}: a refused checkpoint changed the simulation");
    }
    // Files written before the fingerprint carry none and are not checked.
    let mut other = Simulation::from_scene(scene).unwrap();
    other.world.bodies.material[7] += 1;
    assert!(other.restore(&moreau::stepping::Checkpoint { shapes: None, ..c }).is_ok());
}

#[test]
fn a_restart_at_another_time_step_starts_from_the_impulses_scaled_to_it() {
    let scene = Path::new("scenes/pile.toml");
    let mut first = Simulation::from_scene(scene).unwrap();
    first.set_threads(1).unwrap();
    for _ in 0..60 {
        first.step().unwrap();
    }
    let c = first.checkpoint();
    assert_eq!(c.time_step, Some(first.settings.h));
    let half = first.settings.h / 2.0;
    let step_at_half = |c: &moreau::stepping::Checkpoint| {
        let mut sim = Simulation::from_scene(scene).unwrap();
        sim.set_threads(1).unwrap();
        sim.restore(c).unwrap();
        sim.set_time_step(half).unwrap();
        let r = sim.step().unwrap();
        assert!(r.converged);
        (r.iterations, r.error.to_bits(), sim.contacts().iter().map(|x| x.impulse[0].to_bits()).collect::<Vec<_>>())
    };
    first.set_time_step(half).unwrap();
    let r = first.step().unwrap();
    let went_on = (r.iterations, r.error.to_bits(), first.contacts().iter().map(|x| x.impulse[0].to_bits()).collect());
    assert_eq!(step_at_half(&c), went_on, "a restart at another step goes on as the run would have");
    let unscaled = step_at_half(&moreau::stepping::Checkpoint { time_step: None, ..c.clone() });
    assert_ne!(unscaled, went_on, "without the step it was taken over, the impulses are not scaled");
    assert!(unscaled.0 > went_on.0, "scaled impulses start nearer: {} against {} sweeps", went_on.0, unscaled.0);
    let mut sim = Simulation::from_scene(scene).unwrap();
    let e = sim.restore(&moreau::stepping::Checkpoint { time_step: Some(-1.0), ..c }).unwrap_err();
    assert!(e.to_string().contains("time_step -1 must be finite and > 0"), "{e}");
    assert!(sim.set_time_step(f64::NAN).is_err() && sim.settings.h > 0.0);
}

#[test]
fn improper_colours_in_a_checkpoint_are_refused() {
    let scene = Path::new("scenes/pile_10k.toml");
    let mut sim = Simulation::from_scene(scene).unwrap();
    sim.set_threads(2).unwrap();
    sim.step().unwrap();
    let mut c = sim.checkpoint();
    // Colours as a colouring solve leaves them (the block sweep colours nothing): one each.
    c.moving = Some(vec![true; c.position.len()]);
    c.contacts.iter_mut().enumerate().for_each(|(k, x)| x.colour = Some(k as u32));
    let fresh = Simulation::from_scene(scene).unwrap();
    let mut proper = Simulation::from_scene(scene).unwrap();
    assert!(proper.restore(&c).is_ok(), "distinct colours are a proper colouring");
    // Two contacts of body 0's neighbourhood given one colour: not a proper colouring.
    let (a, b) = (0, 1);
    assert_eq!(c.contacts[a].body, c.contacts[b].body);
    c.contacts[b].colour = c.contacts[a].colour;
    let mut target = fresh;
    let e = target.restore(&c).unwrap_err().to_string();
    assert!(e.contains("the colouring is not proper"), "{e}");
    c.contacts[b].colour = Some(u32::MAX);
    let e = target.restore(&c).unwrap_err().to_string();
    assert!(e.contains("is not below the number of contacts"), "{e}");
}

#[test]
fn saved_grains_start_a_scene_where_the_run_left_them() {
    let dir = temp("grains");
    let saved = dir.join("settled.csv");
    let out = dir.join("run");
    let said = run(&[
        "run",
        "scenes/pile.toml",
        "--steps",
        "10",
        "--device",
        "cpu",
        "--out",
        out.to_str().unwrap(),
        "--save-grains",
        saved.to_str().unwrap(),
    ]);
    assert!(said.contains("grains of step 10 in"), "{said}");
    // The same scene taking its grains from the file instead of generating them.
    let text = std::fs::read_to_string("scenes/pile.toml").unwrap();
    let generated = text.find("[[generate]]").unwrap();
    let scene = dir.join("from_file.toml");
    std::fs::write(&scene, format!("{}[[grains]]\nfile = \"settled.csv\"\n", &text[..generated])).unwrap();
    let loaded = moreau::scene::load(&scene).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::from_scene(Path::new("scenes/pile.toml")).unwrap();
    for _ in 0..10 {
        sim.step().unwrap();
    }
    let (a, b) = (&loaded.world.bodies, &sim.world.bodies);
    assert_eq!(a.len(), b.len());
    assert!(a.position == b.position && a.velocity == b.velocity && a.spin == b.spin, "not the run's last state");
    assert_eq!(a.mass, b.mass);

    // A world a grains file cannot hold is refused before the run, naming the body.
    let bad = moreau()
        .args(["run", "scenes/polygon_pile.toml", "--steps", "1", "--quiet", "--save-grains"])
        .arg(dir.join("no.csv"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("is a polygon; a grains file holds disks"), "{err}");
    assert!(!dir.join("no.csv").exists());
}

/// `--until-rest V` ends a run at the first step whose grains' rms speed is at most V m/s, with
/// that step's picture and saved grains; a run that never gets there says so; a speed that is no
/// speed is refused.
#[test]
fn a_run_until_rest_stops_at_the_first_step_at_rest() {
    let dir = temp("until_rest");
    let (out, saved) = (dir.join("run"), dir.join("rest.csv"));
    let args = ["run", "scenes/pile.toml", "--device", "cpu", "--vtk-every", "0", "--until-rest", "1e-2", "--out"];
    let said = run(&[&args[..], &[out.to_str().unwrap(), "--save-grains", saved.to_str().unwrap()]].concat());
    let at = said.find("at rest after step ").map(|i| &said[i + 19..]).unwrap_or_else(|| panic!("{said}"));
    let step: usize = at[..at.find(':').unwrap()].parse().unwrap();
    assert!(step > 1 && step < 300, "{said}");
    assert!(said.contains(&format!("grains of step {step} in")), "{said}");
    assert!(out.join(format!("state_{step:06}.png")).exists(), "the picture of the step at rest");
    let rows = std::fs::read_to_string(out.join("steps.csv")).unwrap().lines().count() - 1;
    assert_eq!(rows, step);
    // The speed it judged, recomputed from the same run in the library: above 1e-2 the step
    // before, at most 1e-2 at the step it stopped at, and √(2 E / M) for these free disks.
    let mut sim = Simulation::from_scene(Path::new("scenes/pile.toml")).unwrap();
    let speeds: Vec<f64> = (0..step)
        .map(|_| {
            sim.step().unwrap();
            sim.world.bodies.rms_speed()
        })
        .collect();
    assert!(speeds[step - 2] > 1e-2 && speeds[step - 1] <= 1e-2, "{speeds:?}");
    let mass: f64 = sim.world.bodies.mass.iter().sum();
    let from_energy = (2.0 * sim.world.kinetic_energy() / mass).sqrt();
    assert!((from_energy - speeds[step - 1]).abs() <= 1e-12 * from_energy.max(1e-30), "{from_energy} {speeds:?}");

    let short =
        run(&["run", "scenes/pile.toml", "--steps", "3", "--until-rest", "1e-9", "--out", out.to_str().unwrap()]);
    assert!(short.contains("warning: not at rest after step 3"), "{short}");
    for bad in ["0", "-1", "nan", "inf"] {
        let o = moreau().args(["run", "scenes/pile.toml", "--quiet", &format!("--until-rest={bad}")]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains("--until-rest ") && err.contains("finite and > 0"), "{bad}: {err}");
    }
    // A punch is static: no step to be at rest after.
    let o = moreau().args(["run", "scenes/signorini_punch.toml", "--quiet", "--until-rest", "1e-2"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--until-rest: scenes/signorini_punch.toml is a punch scene"), "{err}");
}

/// A paused GPU mixing (solves left plain, the pause's length) goes into a checkpoint and back,
/// follows the simulation to another backend, and a checkpoint without it (an older file) reads
/// as no pause; an impossible one is refused by name.
#[test]
fn a_checkpoint_carries_the_paused_gpu_mixing() {
    let load = || {
        let s = moreau::scene::load(Path::new("scenes/pile.toml")).unwrap();
        Simulation::new(s.world, s.settings).unwrap()
    };
    let mut sim = load();
    sim.step().unwrap();
    sim.backend().set_mixing_pause([3, 8]).unwrap();
    let refused = sim.backend().set_mixing_pause([3, 65]).unwrap_err();
    assert!(refused.contains("mixing_pause [3, 65]"), "{refused}");
    assert_eq!(sim.backend().mixing_pause(), [3, 8], "a refused pause changes nothing");
    let c = sim.checkpoint();
    assert_eq!(c.mixing_pause, [3, 8]);
    let mut other = load();
    other.restore(&c).unwrap();
    assert_eq!(other.backend().mixing_pause(), [3, 8]);
    other.set_backend(moreau::backend::Backend::cpu()).unwrap();
    assert_eq!(other.backend().mixing_pause(), [3, 8], "a new backend of the same simulation keeps the pause");
    // A file from before the field: no pause.
    let mut json: serde_json::Value = serde_json::to_value(&c).unwrap();
    json.as_object_mut().unwrap().remove("mixing_pause");
    let old: moreau::stepping::Checkpoint = serde_json::from_value(json).unwrap();
    assert_eq!(old.mixing_pause, [0, 0]);
    let bad = moreau::stepping::Checkpoint { mixing_pause: [9, 8], ..c.clone() };
    let err = load().restore(&bad).unwrap_err().to_string();
    assert!(err.contains("mixing_pause [9, 8]"), "{err}");
}
