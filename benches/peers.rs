//! moreau, rapier2d and Box2D v3 side by side on the same pile (README "What accuracy costs in time"):
//! moreau settles the deposited disks once, with the scene's own solver; every configuration of
//! every engine starts from that state (positions, velocities, and moreau's warm start), takes
//! 100 untimed steps so that its own warm start and overlaps develop (a loose setting lets the
//! pile sink step by step), then steps on while we time each step and measure, after it and outside the timer, the overlaps of the grains
//! (moreau's exact detection on each engine's positions, relative to the mean diameter).
//!
//! `cargo bench --bench peers` (scene `scenes/pile_10k.toml`; MOREAU_PEERS_SCENE, _WARMUP (the
//! settling steps), _LEAD (untimed steps of each configuration), _STEPS and _THREADS (moreau's
//! thread counts, `1,16`; default one and all cores) change it; MOREAU_PEERS_DEVICES=cpu,gpu adds
//! rows solved on a GPU, which take the last thread count for detection; MOREAU_PEERS_ONLY runs
//! only the rows it names, `;`-separated, as the table names their settings; MOREAU_PEERS_SETTLE=gpu
//! settles on a GPU, kept as settled_<scene>_<warmup>_<threads>_gpu.json).
//! The settled state is kept in target/peers/settled_<scene>_<warmup>_<threads>.json and read
//! back by the next run of the same scene file. Writes target/peers/peers.csv and peers.svg/.png (largest overlap against milliseconds per
//! step, one curve per engine). rapier2d is built without its `parallel` feature, so it runs on
//! one thread, and Box2D v3 steps with its default single worker; moreau's rows say their thread count, and under a velocity test the bound each
//! contact was held to: tol times the largest free velocity of the run's steps, or for the
//! "× g h" rows (the step-velocity test) tol times one step of gravity.

#[path = "peers/scene.rs"]
mod scene;

use std::path::{Path, PathBuf};
use std::time::Instant;

use moreau::backend::DeviceChoice;
use moreau::io::checkpoint::{read_checkpoint, scene_identity, write_checkpoint};
use moreau::io::plots::{write_chart, Chart, Series};
use moreau::solvers::{Ordering, SolverOptions, StopCriterion};
use moreau::stepping::{Checkpoint, Simulation};
use moreau::world::World;
use scene::{kinetic_energy, penetration, PEERS};

#[derive(serde::Serialize)]
struct Row {
    engine: &'static str,
    setting: String,
    threads: usize,
    ms_per_step: f64,
    mean_penetration: f64,
    max_penetration: f64,
    kinetic_energy: f64,
    contacts: usize,
    note: String,
}

/// Anderson depth of the accelerated rows when the scene has none.
const ANDERSON: usize = 5;

/// Focused sweeps of the focused rows (BENCHMARKS.md, "Focused sweeps").
const FOCUS: usize = 19;

/// Whether a row's setting is among MOREAU_PEERS_ONLY's (`;`-separated, e.g.
/// `4 iterations;tol 1e-4, focus 19`); every row without it.
fn chosen(setting: &str) -> bool {
    std::env::var("MOREAU_PEERS_ONLY").map_or(true, |only| only.split(';').any(|s| s.trim() == setting))
}

fn env(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

/// Steps `step` for `lead` untimed steps, then times `steps` more; after each timed step the
/// overlaps at `state()` are measured. Returns (ms per step, mean and max overlap, contacts, KE).
fn measure(
    world: &moreau::world::World,
    lead: usize,
    steps: usize,
    mut step: impl FnMut() -> f64,
    state: impl Fn() -> (Vec<glam::DVec2>, Vec<glam::DVec2>),
) -> (f64, f64, f64, usize, f64) {
    for _ in 0..lead {
        step();
    }
    let (mut seconds, mut mean, mut max, mut contacts) = (0.0, 0.0f64, 0.0f64, 0);
    for _ in 0..steps {
        seconds += step();
        let (p, _) = state();
        let (m, x, n) = penetration(world, &p);
        (mean, max, contacts) = (mean.max(m), max.max(x), n);
    }
    let (_, v) = state();
    (1e3 * seconds / steps as f64, mean, max, contacts, kinetic_energy(world, &v))
}

fn main() {
    let path = PathBuf::from(std::env::var("MOREAU_PEERS_SCENE").unwrap_or_else(|_| "scenes/pile_10k.toml".into()));
    let (warmup, steps) = (env("MOREAU_PEERS_WARMUP", 20), env("MOREAU_PEERS_STEPS", 20));
    let lead = env("MOREAU_PEERS_LEAD", 100);
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let thread_counts: Vec<usize> = match std::env::var("MOREAU_PEERS_THREADS") {
        Ok(list) => {
            list.split(',').map(|t| t.trim().parse().expect("MOREAU_PEERS_THREADS: thread counts, `1,16`")).collect()
        }
        Err(_) => [1, cores].into_iter().collect::<std::collections::BTreeSet<_>>().into_iter().collect(),
    };
    let threads = *thread_counts.last().expect("a thread count");
    let devices: Vec<DeviceChoice> = std::env::var("MOREAU_PEERS_DEVICES")
        .unwrap_or_else(|_| "cpu".into())
        .split(',')
        .map(|d| DeviceChoice::from_name(d.trim()).unwrap_or_else(|e| panic!("MOREAU_PEERS_DEVICES: {e}")))
        .collect();
    let load = || moreau::scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let first = load();
    let h = first.settings.h;
    eprintln!(
        "{}: {} disks, h = {h:e}; {warmup} steps to settle, then per configuration {lead} untimed and {steps} timed",
        first.name,
        first.world.bodies.len()
    );
    let (settled, checkpoint) = settle(&path, load(), warmup, threads);
    let mut rows = Vec::new();

    for (engine, passes, build) in PEERS {
        for n in [4usize, 8, 16] {
            let setting = format!("{n} {passes}");
            if !chosen(&setting) {
                continue;
            }
            let pile = std::cell::RefCell::new(build(&settled, h, n).unwrap_or_else(|e| panic!("{e}")));
            let (ms, mean, max, contacts, ke) = measure(
                &first.world,
                lead,
                steps,
                || {
                    let t = Instant::now();
                    pile.borrow_mut().step();
                    t.elapsed().as_secs_f64()
                },
                || pile.borrow().state(),
            );
            eprintln!("{engine} {setting}: {ms:.1} ms/step, max overlap {max:.3e} d");
            rows.push(Row {
                engine,
                setting,
                threads: 1,
                ms_per_step: ms,
                mean_penetration: mean,
                max_penetration: max,
                kinetic_energy: ke,
                contacts,
                note: String::new(),
            });
        }
    }

    // (setting, tolerance, fixed sweep count, Anderson depth instead of the scene's, focused
    // sweeps, ordering instead of the scene's, criterion instead of the scene's): the scene's
    // solver at three tolerances of its criterion, full sweeps either side of Anderson
    // acceleration, focused sweeps, and, where the scene has not chosen them, NLGS on a work list
    // and the step-velocity test (every contact within tol × g h, whatever the fastest grain does).
    let scene_options = &first.settings.options;
    let (other, named) = match scene_options.anderson {
        0 => (ANDERSON, format!("Anderson {ANDERSON}")),
        _ => (0, "plain NLGS".to_string()),
    };
    // The step-velocity test's tol 1e-2 is 9.8e-5 m/s on every contact; below 3e-3 its steps crawl.
    let ladder = match scene_options.criterion {
        StopCriterion::StepVelocity => [1e-1, 1e-2, 3e-3],
        _ => [1e-2, 1e-3, 1e-4],
    };
    let (tight, full) = ([ladder[1], ladder[2]], Some(Ordering::Forward));
    let tolerances = ladder.map(|t| (format!("tol {t:.0e}"), Some(t), None, None, None, None, None));
    let mixed = tight.map(|t| (format!("tol {t:.0e}, {named}"), Some(t), None, Some(other), None, full, None));
    let focused =
        tight.map(|t| (format!("tol {t:.0e}, focus {FOCUS}"), Some(t), None, Some(0), Some(FOCUS), full, None));
    let list = Some(Ordering::Worklist);
    let listed: Vec<_> = match scene_options.ordering {
        Ordering::Worklist => vec![],
        _ => ladder.map(|t| (format!("tol {t:.0e}, work list"), Some(t), None, Some(0), None, list, None)).into(),
    };
    // Under the step-velocity test, tol 1e-4 in the other two readings as well: the velocity
    // test (each contact within 1e-4 of the largest free velocity) and the natural map.
    let held: Vec<_> = match scene_options.criterion {
        StopCriterion::StepVelocity => {
            [(StopCriterion::Velocity, "velocity test"), (StopCriterion::Natural, "natural map")]
                .map(|(c, name)| (format!("tol 1e-4, {name}"), Some(1e-4), None, None, None, None, Some(c)))
                .into()
        }
        _ => [1e-2, 3e-3]
            .map(|t| {
                let step_velocity = Some(StopCriterion::StepVelocity);
                (format!("tol {t:.0e} × g h, work list"), Some(t), None, Some(0), None, list, step_velocity)
            })
            .into(),
    };
    let sweeps = [4usize, 8, 16].map(|k| (format!("{k} sweeps"), None, Some(k), None, None, full, None));
    // The CPU at each thread count; a GPU once, its detection on the last count, without the
    // Anderson rows (the GPU's sweeps have none).
    let runs: Vec<(DeviceChoice, usize)> = devices
        .iter()
        .flat_map(|&d| match d {
            DeviceChoice::Cpu => thread_counts.iter().map(|&t| (d, t)).collect(),
            _ => vec![(d, threads)],
        })
        .collect();
    for &(device, t) in &runs {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().expect("a thread pool");
        let on_gpu = device != DeviceChoice::Cpu;
        let rows_of = tolerances.iter().chain(&mixed).chain(&focused).chain(&listed).chain(&held).chain(&sweeps);
        for (setting, tol, fixed, anderson, focus, ordering, criterion) in rows_of {
            let criterion = criterion.unwrap_or(first.settings.options.criterion);
            // The GPU's sweeps have no Anderson rows of their own, nor focused sweeps; its work
            // list (thresholded sweeps) needs a velocity test.
            let gpu_list = *ordering == Some(Ordering::Worklist) && criterion.is_velocity_test();
            if (on_gpu && anderson.is_some() && !gpu_list) || !chosen(setting) {
                continue;
            }
            let mut s = load();
            // The GPU's work list stops on a velocity test; under the natural map it sweeps
            // every contact, colour by colour, as a user of `--device gpu` would be told to.
            let ordering = match ordering.unwrap_or(s.settings.options.ordering) {
                Ordering::Worklist if on_gpu && !criterion.is_velocity_test() => Ordering::Forward,
                o => o,
            };
            let base = SolverOptions {
                anderson: anderson.unwrap_or(s.settings.options.anderson),
                focus: focus.unwrap_or(s.settings.options.focus),
                ordering,
                criterion,
                ..s.settings.options.clone()
            };
            s.settings.options = match (tol, fixed) {
                (Some(tol), _) => SolverOptions { tol: *tol, ..base },
                // A fixed sweep count: a tolerance no sweep reaches.
                (_, Some(k)) => SolverOptions { tol: 1e-300, max_iter: *k, ..base },
                _ => unreachable!(),
            };
            let world = s.world.clone();
            let ((ms, mean, max, contacts, ke), unconverged, scale) = pool.install(|| {
                let mut sim = Simulation::new(s.world, s.settings).expect("a valid scene");
                sim.restore(&checkpoint).expect("the settled state");
                if on_gpu {
                    let line = sim.choose_device(device).unwrap_or_else(|e| panic!("{e}"));
                    if setting == "tol 1e-2" {
                        eprintln!("{line}");
                    }
                }
                let sim = std::cell::RefCell::new(sim);
                let unconverged = std::cell::Cell::new(0usize);
                let scale = std::cell::Cell::new(0.0f64);
                let measured = measure(
                    &world,
                    lead,
                    steps,
                    || {
                        let r = sim.borrow_mut().step().unwrap_or_else(|e| panic!("{e}"));
                        if !r.converged && tol.is_some() {
                            unconverged.set(unconverged.get() + 1);
                        }
                        scale.set(scale.get().max(r.velocity_scale));
                        r.seconds
                    },
                    || {
                        let sim = sim.borrow();
                        (sim.world.bodies.position.clone(), sim.world.bodies.velocity.clone())
                    },
                );
                (measured, unconverged.get(), scale.get())
            });
            let mut notes = Vec::new();
            if unconverged > 0 {
                notes.push(format!("{unconverged} of {} steps missed tol", lead + steps));
            }
            // What a velocity test held each contact to: tol times its scale, the step's largest
            // free velocity (which a few fast grains set) or, under step-velocity, g h.
            if let (Some(tol), true) = (tol, criterion.is_velocity_test()) {
                notes.push(format!("each contact within {:.1e} m/s", tol * scale));
            }
            let note = notes.join("; ");
            let engine = if on_gpu { "moreau gpu" } else { "moreau" };
            eprintln!("{engine} {setting} ({t} threads): {ms:.1} ms/step, max overlap {max:.3e} d {note}");
            rows.push(Row {
                engine,
                setting: setting.clone(),
                threads: t,
                ms_per_step: ms,
                mean_penetration: mean,
                max_penetration: max,
                kinetic_energy: ke,
                contacts,
                note,
            });
        }
    }
    report(&rows, &first.name, first.world.bodies.len());
}

/// The scene (file `path`) stepped `warmup` times with its own settings on `threads` threads:
/// the settled world and the checkpoint every moreau configuration restarts from. Kept in
/// target/peers/ (checked against the scene file) so that a second run times without settling.
fn settle(path: &Path, scene: moreau::scene::Scene, warmup: usize, threads: usize) -> (World, Checkpoint) {
    // MOREAU_PEERS_SETTLE=gpu settles on a GPU: the 40,000-disk pile's 300 steps take half a
    // minute there and most of an hour on 16 cores. Its state is kept under its own name.
    let gpu = std::env::var("MOREAU_PEERS_SETTLE")
        .ok()
        .map(|d| DeviceChoice::from_name(d.trim()).unwrap_or_else(|e| panic!("MOREAU_PEERS_SETTLE: {e}")))
        .filter(|&d| d != DeviceChoice::Cpu);
    let on = if gpu.is_some() { "_gpu" } else { "" };
    let kept = Path::new("target/peers").join(format!("settled_{}_{warmup}_{threads}{on}.json", scene.name));
    let mut sim = Simulation::new(scene.world, scene.settings).expect("a valid scene");
    // A kept state of other grains (the generator changed since) is refused: settled again.
    match read_checkpoint(&kept, path).map(|c| sim.restore(&c).map(|()| c)) {
        Ok(Ok(c)) => {
            eprintln!("settled state read from {}", kept.display());
            return (sim.world.clone(), c);
        }
        Ok(Err(e)) => eprintln!("{} not used: {e}; settling again", kept.display()),
        Err(_) => {}
    }
    if let Some(device) = gpu {
        eprintln!("settling: {}", sim.choose_device(device).unwrap_or_else(|e| panic!("{e}")));
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a thread pool");
    pool.install(|| {
        let t = Instant::now();
        let mut missed = 0;
        for _ in 0..warmup {
            missed += usize::from(!sim.step().unwrap_or_else(|e| panic!("{e}")).converged);
        }
        let ke = sim.world.bodies.kinetic_energy();
        eprintln!(
            "settled in {:.1} s ({missed} of {warmup} steps missed tol), kinetic energy {ke:.3e} J",
            t.elapsed().as_secs_f64()
        );
        let mut c = sim.checkpoint();
        (c.scene, c.scene_fingerprint) = scene_identity(path).expect("the scene file");
        std::fs::create_dir_all("target/peers").expect("target/peers");
        write_checkpoint(&c, &kept).unwrap_or_else(|e| eprintln!("settled state not kept: {e}"));
        (sim.world.clone(), c)
    })
}

fn report(rows: &[Row], scene: &str, bodies: usize) {
    println!("{scene} ({bodies} disks): per configuration, overlaps relative to the mean diameter");
    println!("| engine | setting | threads | ms/step | mean overlap | max overlap | kinetic energy (J) | overlapping contacts | |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        println!(
            "| {} | {} | {} | {:.1} | {:.2e} | {:.2e} | {:.3e} | {} | {} |",
            r.engine,
            r.setting,
            r.threads,
            r.ms_per_step,
            r.mean_penetration,
            r.max_penetration,
            r.kinetic_energy,
            r.contacts,
            r.note
        );
    }
    let dir = Path::new("target/peers");
    std::fs::create_dir_all(dir).expect("target/peers");
    let mut csv = csv::Writer::from_path(dir.join("peers.csv")).expect("peers.csv");
    rows.iter().for_each(|r| csv.serialize(r).expect("a CSV row"));
    csv.flush().expect("peers.csv");
    // One curve per engine, thread count and family of settings (tolerances, sweep or
    // iteration counts), in order of time.
    fn family(r: &Row) -> &str {
        match r.setting.split_once(", ") {
            Some((_, variant)) => variant,
            None if r.setting.starts_with("tol") => "tolerance",
            None => "fixed sweeps",
        }
    }
    // The game engines first, so that they take the palette's first, strongest colours.
    let rank = |engine: &str| scene::PEERS.iter().position(|p| p.0 == engine).unwrap_or(scene::PEERS.len());
    let keys: std::collections::BTreeSet<_> =
        rows.iter().map(|r| (rank(r.engine), r.engine, r.threads, family(r))).collect();
    let mut series: Vec<Series> = Vec::new();
    for (_, engine, threads, fam) in keys {
        let mut points: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| (r.engine, r.threads, family(r)) == (engine, threads, fam) && r.max_penetration > 0.0)
            .map(|r| (r.ms_per_step, r.max_penetration))
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let label = match engine {
            "rapier2d" => format!("rapier2d, 4/8/16 iterations, {threads} thread"),
            "box2d" => format!("Box2D v3, 4/8/16 substeps, {threads} thread"),
            "moreau gpu" => format!("moreau on the GPU, {fam}"),
            _ => format!("moreau, {fam}, {threads} thread(s)"),
        };
        series.push((label, points));
    }
    let chart = Chart {
        title: &format!("{scene}: largest overlap vs time per step"),
        x_label: "ms per step",
        y_label: "largest overlap / mean diameter",
        log_x: true,
        log_y: true,
        series: &series,
    };
    match write_chart(&dir.join("peers"), &chart) {
        Ok(()) => eprintln!("wrote target/peers/peers.csv, peers.svg, peers.png"),
        Err(e) => eprintln!("wrote target/peers/peers.csv; no chart: {e}"),
    }
}
