//! Physics of the simulation pipeline that can fail: Coulomb on an incline, rolling, energy,
//! resting stacks, penetration, settling.

mod common;

use std::path::Path;

use glam::DVec2;
use moreau::detection::Antagonist;
use moreau::scene;
use moreau::stepping::Simulation;

use common::{held_block, scene_header as header};

fn simulation(toml: &str) -> (Simulation, usize) {
    let s = scene::parse(toml, Path::new("test.toml")).unwrap_or_else(|e| panic!("{e}"));
    let steps = s.steps;
    (Simulation::new(s.world, s.settings).unwrap(), steps)
}

/// A disk of radius 0.1 touching an incline of angle `deg` (down to the right), at rest.
fn incline(deg: f64, mu: f64, effects: &str) -> String {
    let t = deg.to_radians();
    let dir = DVec2::new(t.cos(), -t.sin());
    let n = DVec2::new(t.sin(), t.cos());
    let c = 2.0 * dir + 0.1 * n;
    let b = 20.0 * dir;
    format!(
        "{}\n[[wall]]\nsegment = [[0.0, 0.0], [{}, {}]]\n[[body]]\ndisk = {{ center = [{}, {}], radius = 0.1 }}\n",
        header(effects, 500, mu, 1000.0),
        b.x,
        b.y,
        c.x,
        c.y
    )
}

/// Velocity along the slope after the scene's steps, and the expected one.
fn slide(deg: f64, mu: f64, effects: &str) -> (f64, f64, f64) {
    let (mut sim, steps) = simulation(&incline(deg, mu, effects));
    let start = sim.position(0);
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged, "step {} error {}", r.step, r.error);
    }
    let t = deg.to_radians();
    let dir = DVec2::new(t.cos(), -t.sin());
    (sim.velocity(0).dot(dir), sim.time(), (sim.position(0) - start).length())
}

#[test]
fn a_block_sticks_below_the_friction_angle_and_slides_above_it() {
    let g = 9.81;
    // Without rotation a disk behaves as a sliding block.
    let (v, _, moved) = slide(20.0, 0.5, r#""gravity", "friction""#);
    assert!(v.abs() < 1e-9 && moved < 1e-9, "tan 20° = 0.364 < 0.5 must stick: v = {v}, moved {moved}");
    for (deg, mu) in [(30.0f64, 0.3f64), (35.0, 0.6), (25.0, 0.0)] {
        let (v, t, _) = slide(deg, mu, r#""gravity", "friction""#);
        let a = g * (deg.to_radians().sin() - mu * deg.to_radians().cos());
        assert!(a > 0.0);
        let measured = v / t;
        assert!((measured - a).abs() <= 0.01 * a, "{deg}°, μ = {mu}: a = {measured}, expected {a}");
    }
}

#[test]
fn a_disk_that_can_rotate_rolls_with_two_thirds_of_g_sin_theta() {
    let deg: f64 = 30.0;
    // μ = 0.5 ≥ tan θ / 3: rolling without slipping.
    let (v, t, _) = slide(deg, 0.5, r#""gravity", "friction", "rotation""#);
    let a = 2.0 / 3.0 * 9.81 * deg.to_radians().sin();
    assert!((v / t - a).abs() <= 0.01 * a, "a = {}, expected {a}", v / t);
}

fn pile(count: usize, steps: usize, tol: f64, restitution: f64, effects: &str) -> String {
    pile_theta(count, steps, tol, restitution, effects, 0.5)
}

fn pile_theta(count: usize, steps: usize, tol: f64, restitution: f64, effects: &str, theta: f64) -> String {
    format!(
        r#"
effects = [{effects}]
[time]
step = 2e-3
steps = {steps}
theta = {theta}
[solver]
name = "nlgs"
tol = {tol}
max_iter = 5000
[contact]
friction = 0.4
restitution = {restitution}
[[material]]
name = "glass"
density = 2500.0
[[wall]]
container = {{ min = [0.0, 0.0], max = [0.06, 0.3] }}
[[generate]]
kind = "grid"
count = {count}
radius = [0.002, 0.003]
region = {{ min = [0.0, 0.0], max = [0.06, 0.3] }}
seed = 7
"#
    )
}

#[test]
fn without_restitution_total_energy_never_rises() {
    // θ = 1: every term of the energy balance, r·u⁺ and −½|Δv|²_M, is dissipative.
    // (θ = 1/2 is not strictly: a separating contact that recloses within a step gives back
    // ½ r_n u_n⁻ > 0; measured on this pile: rises up to 1.5e-6 of the potential energy.)
    let (mut sim, steps) = simulation(&pile_theta(120, 250, 1e-8, 0.0, r#""gravity", "friction", "rotation""#, 1.0));
    let mut last = sim.world.kinetic_energy() + sim.world.potential_energy();
    let scale = sim.world.potential_energy().abs();
    let mut worst = f64::NEG_INFINITY;
    for _ in 0..steps {
        let r = sim.step().unwrap();
        let e = r.kinetic_energy + r.potential_energy;
        worst = worst.max((e - last) / scale);
        last = e;
    }
    // Solved to 1e-8, the scheme may only lose energy (up to round-off of the potential energy).
    assert!(worst <= 1e-9, "energy rose by {worst:e} of the potential energy in one step");
}

#[test]
fn with_restitution_a_dropped_disk_bounces_back_to_e_squared_of_its_height() {
    let toml = r#"
effects = ["gravity", "restitution"]
[time]
step = 1e-4
steps = 6000
[contact]
restitution = 0.8
[[material]]
name = "m"
density = 1.0
[[wall]]
segment = [[-1.0, 0.0], [1.0, 0.0]]
[[body]]
disk = { center = [0.0, 0.6], radius = 0.1 }
"#;
    let (mut sim, steps) = simulation(toml);
    let mut top_after_bounce: f64 = 0.0;
    let mut bounced = false;
    for _ in 0..steps {
        sim.step().unwrap();
        if sim.velocity(0).y > 0.0 {
            bounced = true;
        }
        if bounced && sim.time() < 0.35 + 2.0 * 0.8 * 0.35 {
            top_after_bounce = top_after_bounce.max(sim.position(0).y - 0.1);
        }
    }
    // Dropped from 0.5 above the floor: the first rebound rises to e² · 0.5 = 0.32.
    assert!(bounced);
    assert!((top_after_bounce - 0.32).abs() < 0.01, "rebound height {top_after_bounce}");
}

#[test]
fn a_resting_column_of_disks_stays_at_rest_for_1000_steps() {
    let mut toml = String::from(
        r#"
effects = ["gravity", "friction", "rotation"]
[time]
step = 1e-3
steps = 1000
[solver]
tol = 1e-8
[contact]
friction = 0.5
[[material]]
name = "m"
density = 1.0
[[wall]]
segment = [[-2.0, 0.0], [2.0, 0.0]]
"#,
    );
    for k in 0..10 {
        toml.push_str(&format!("[[body]]\ndisk = {{ center = [0.0, {}], radius = 0.5 }}\n", 0.5 + k as f64));
    }
    let (mut sim, steps) = simulation(&toml);
    let start: Vec<DVec2> = (0..10).map(|k| sim.position(k)).collect();
    let mut max_ke: f64 = 0.0;
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged);
        max_ke = max_ke.max(r.kinetic_energy);
    }
    let drift = (0..10).map(|k| sim.position(k).distance(start[k])).fold(0.0, f64::max);
    let m = std::f64::consts::PI * 0.25;
    assert!(drift < 1e-9, "drift {drift:e} of a unit diameter");
    assert!(max_ke < 1e-12 * 10.0 * m * 9.81, "kinetic energy {max_ke:e}");
}

#[test]
fn a_stack_of_offset_boxes_does_not_creep() {
    let mut toml = String::from(
        r#"
effects = ["gravity", "friction", "rotation"]
[time]
step = 1e-2
steps = 1000
[solver]
tol = 1e-8
[contact]
friction = 0.3
[[material]]
name = "m"
density = 1.0
[[wall]]
segment = [[-5.0, 0.0], [5.0, 0.0]]
"#,
    );
    for k in 0..10 {
        let x = if k % 2 == 0 { 0.01 } else { -0.01 };
        toml.push_str(&format!(
            "[[body]]\npolygon = {{ center = [{x}, {}], vertices = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]] }}\n",
            0.5 + k as f64
        ));
    }
    let (mut sim, steps) = simulation(&toml);
    let top = sim.position(9);
    for _ in 0..steps {
        sim.step().unwrap();
    }
    let moved = sim.position(9) - top;
    assert!(moved.x.abs() < 0.01, "top box drifted sideways by {} (1 % of its size allowed)", moved.x);
    assert!(moved.y.abs() < 1e-3, "top box sank by {}", -moved.y);
}

#[test]
fn the_shipped_pile_settles_with_penetration_below_a_thousandth_of_a_diameter() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pile.toml");
    let scene = scene::load(&path).unwrap();
    let (steps, n) = (scene.steps, scene.world.bodies.len());
    let mut sim = Simulation::new(scene.world, scene.settings).unwrap();
    let d = sim.world.mean_diameter();
    let m = sim.world.bodies.mass.iter().sum::<f64>() / n as f64;
    let mut max_pen: f64 = 0.0;
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.error.is_finite());
        max_pen = max_pen.max(r.max_penetration);
    }
    assert!(max_pen < 1e-3 * d, "max penetration {:.2e} of the mean diameter", max_pen / d);
    let ke = sim.world.kinetic_energy();
    assert!(ke < 1e-6 * n as f64 * m * 9.81 * d, "kinetic energy {ke:e} after {steps} steps");
    assert!(sim.contacts().len() > n, "a settled pile of {n} grains has {} contacts", sim.contacts().len());
}

#[test]
fn contacts_are_warm_started_from_the_previous_step() {
    let (mut sim, _) = simulation(&pile(100, 10, 1e-4, 0.0, r#""gravity", "friction", "rotation""#));
    sim.keep_problems(true);
    // The pile after 300 steps, at the first step from there that meets its tolerance (a settled
    // frictional pile has steps that need more than the 5,000-sweep cap).
    let mut last = None;
    for step in 1..=330 {
        let report = sim.step().unwrap();
        let done = step >= 300 && report.converged;
        last = Some(report);
        if done {
            break;
        }
    }
    let last = last.unwrap();
    assert!(
        last.converged,
        "no step of 300 to 330 converged: the last took {} its, error {:e}",
        last.iterations, last.error
    );
    // Every contact that existed last step is carried; only contacts new this step start from zero.
    assert!(
        last.contacts > 50 && last.warm_started * 100 >= 98 * last.contacts,
        "{} of {} warm-started",
        last.warm_started,
        last.contacts
    );
    // The same problem solved from zero takes several times more iterations: it has not
    // converged after three times the warm-started step's.
    let opts = moreau::solvers::SolverOptions { max_iter: 3 * last.iterations, ..sim.settings.options.clone() };
    let cold = moreau::solve(sim.last_problem().unwrap(), sim.settings.solver, &opts, None);
    assert!(
        !cold.converged,
        "warm {} vs cold {} iterations (error {:e})",
        last.iterations, cold.iterations, cold.error
    );
}

/// A square lattice of equal disks filling a box whose walls are frictionless, under a piston: a
/// plate as wide as the box (less 1 mm), its rotation locked, mass 2 kg, pushed down by `force`
/// newtons. (NLGS stalls near 2e-8 on the plate's five frictional contacts: tol 1e-7.)
fn piston_on_lattice(force: f64) -> String {
    let mut bodies = String::new();
    for row in 0..3 {
        for col in 0..5 {
            let (x, y) = (0.01 + 0.02 * col as f64, 0.01 + 0.02 * row as f64);
            bodies.push_str(&format!("[[body]]\ndisk = {{ center = [{x}, {y}], radius = 0.01 }}\n"));
        }
    }
    format!(
        r#"
effects = ["gravity", "friction", "rotation"]
[time]
step = 1e-3
steps = 200
[solver]
name = "nlgs"
tol = 1e-7
max_iter = 20000
[contact]
friction = 0.5
[[material]]
name = "glass"
density = 2500.0
[[material]]
name = "steel"
density = 7800.0
[[interaction]]
materials = ["steel", "steel"]
friction = 0.0
[[interaction]]
materials = ["glass", "steel"]
friction = 0.0
[[wall]]
container = {{ min = [0.0, 0.0], max = [0.1, 0.2] }}
material = "steel"
[[body]]
polygon = {{ center = [0.05, 0.0651], vertices = [[-0.0495, -0.005], [0.0495, -0.005], [0.0495, 0.005], [-0.0495, 0.005]] }}
material = "steel"
mass = 2.0
force = [0.0, {force:?}]
lock_rotation = true
{bodies}"#
    )
}

#[test]
fn a_piston_under_a_constant_force_settles_to_force_balance_with_the_pile() {
    let (mut sim, steps) = simulation(&piston_on_lattice(-500.0));
    for _ in 0..steps {
        let report = sim.step().unwrap();
        assert!(report.converged, "step {}: {}", report.step, report.stop_reason);
    }
    // At rest, the grains push back on the piston with the imposed force plus its weight.
    let load = sim.body_load(0);
    let expected = 500.0 + 2.0 * 9.81;
    assert!((load.force[1] - expected).abs() <= 1e-6 * expected, "grains on the piston: {:?}", load.force);
    assert!(load.force[0].abs() <= 1e-6 * expected, "{:?}", load.force);
    assert_eq!(sim.angle(0), 0.0, "the piston's rotation is locked");
    assert!(sim.velocity(0).length() < 1e-6, "at rest: {}", sim.velocity(0));
    // And the floor carries the piston's load and the grains' weight (frictionless side walls
    // carry nothing vertical).
    let grains: f64 = (1..sim.body_count()).map(|k| sim.world.bodies.mass[k]).sum();
    let floor = sim.wall_loads()[1].force[1];
    let total = expected + grains * 9.81;
    assert!((floor + total).abs() <= 1e-6 * total, "floor {floor} vs {total}");
}

#[test]
fn a_driven_body_in_free_flight_accelerates_by_force_over_mass_plus_gravity() {
    let (mut sim, _) =
        simulation(&piston_on_lattice(-500.0).replace("center = [0.05, 0.0651]", "center = [0.05, 0.15]"));
    for _ in 0..20 {
        sim.step().unwrap();
    }
    let expected = -(500.0 / 2.0 + 9.81) * 20.0 * 1e-3;
    assert!((sim.velocity(0).y - expected).abs() < 1e-12 * expected.abs(), "{} vs {expected}", sim.velocity(0).y);
}

#[test]
fn scenes_refuse_a_force_on_a_fixed_body_and_a_mass_that_is_not_positive() {
    for (change, named) in [
        ("lock_rotation = true", "lock_rotation = true\nfixed = true"),
        ("mass = 2.0", "mass = -2.0"),
        ("mass = 2.0", "mass = 0.0"),
        ("force = [0.0, -500.0]", "force = [0.0, nan]"),
        ("lock_rotation = true", "lock_rotation = true\nspin = 2.0"),
    ] {
        let text = piston_on_lattice(-500.0).replace(change, named);
        let e = scene::parse(&text, Path::new("piston.toml")).err().unwrap_or_else(|| panic!("{named} accepted"));
        let msg = e.to_string();
        assert!(msg.contains("body[0]") && msg.contains("piston.toml"), "{named}: {msg}");
    }
}

/// A disk of radius 0.1 resting on a fixed plate, the plate moving at 1 m/s to the right (a
/// conveyor belt: a kinematic body), μ = 0.2.
fn conveyor(effects: &str) -> String {
    format!(
        r#"{}
[[body]]
polygon = {{ center = [0.0, -0.05], vertices = [[-5.0, -0.05], [5.0, -0.05], [5.0, 0.05], [-5.0, 0.05]] }}
fixed = true
velocity = [1.0, 0.0]
[[body]]
disk = {{ center = [0.0, 0.1], radius = 0.1 }}
"#,
        header(effects, 1000, 0.2, 1000.0)
    )
}

#[test]
fn a_fixed_body_given_a_velocity_drags_a_grain_as_a_conveyor_belt_does() {
    // Without rotation the disk slides, accelerated by μ g, until it moves with the belt (within
    // 1e-5 m/s: the plate's f32 outline leaves the first step a gap of some 1e-8 m to close).
    let (mut sim, steps) = simulation(&conveyor(r#""gravity", "friction""#));
    for k in 1..=steps {
        let r = sim.step().unwrap();
        assert!(r.converged, "step {k}: error {}", r.error);
        let expected = (0.2 * 9.81 * k as f64 * 1e-3).min(1.0);
        assert!((sim.velocity(1).x - expected).abs() < 1e-5, "step {k}: {} vs {expected}", sim.velocity(1).x);
    }
    assert!((sim.position(0).x - 1.0).abs() < 1e-12 && sim.velocity(0) == DVec2::X, "the belt moves on, unpushed");
    assert!((sim.position(1).y - 0.1).abs() < 1e-6, "the disk stays on the belt: {}", sim.position(1).y);
    // A host stops the belt; the disk then slides on it and stops too.
    sim.set_velocity(0, DVec2::ZERO).unwrap();
    let stopped = sim.position(0);
    for _ in 0..600 {
        sim.step().unwrap();
    }
    assert!(sim.velocity(1).length() < 1e-8 && sim.position(0) == stopped, "{}", sim.velocity(1));
    // A disk that turns slides until its bottom point moves with the belt: v + ω r = 3 μ g t
    // reaches 1 m/s, and the disk then rolls on at a third of the belt's speed.
    let (mut sim, steps) = simulation(&conveyor(r#""gravity", "friction", "rotation""#));
    for _ in 0..steps {
        assert!(sim.step().unwrap().converged);
    }
    assert!((sim.velocity(1).x - 1.0 / 3.0).abs() < 1e-5, "{}", sim.velocity(1).x);
    assert!((sim.spin(1) - 2.0 / 3.0 / 0.1).abs() < 1e-4, "{}", sim.spin(1));
    // A fixed body turns at the spin it is given.
    let text = conveyor(r#""gravity", "friction", "rotation""#).replace("velocity = [1.0, 0.0]", "spin = 0.5");
    let (mut sim, _) = simulation(&text.replace("center = [0.0, 0.1]", "center = [0.0, 3.0]"));
    for _ in 0..200 {
        sim.step().unwrap();
    }
    assert!((sim.angle(0) - 0.1).abs() < 1e-12 && sim.spin(0) == 0.5, "{}", sim.angle(0));
}

/// Held along x, the block slides at exactly its velocity whatever friction does, while along y
/// it rests on the floor under gravity and its force: the floor pushes back with its weight plus
/// the force and drags on it with μ times that (a free block would stop in 0.34 s). Held along
/// y, a disk hovers under gravity and an impulse moves it along x only.
#[test]
fn a_body_held_along_one_axis_keeps_its_velocity_there_and_moves_freely_along_the_other() {
    let (mut sim, steps) = simulation(&held_block("force = [0.0, -400.0]"));
    let (mass, h) = (100.0, 1e-3);
    for k in 1..=steps {
        let report = sim.step().unwrap();
        assert!(report.converged, "step {k}: {}", report.error);
        assert_eq!(sim.velocity(1).x, 1.0, "step {k}");
        assert!((sim.position(1).y - 0.1).abs() < 1e-6, "step {k}: y {}", sim.position(1).y);
        let on_block = |c: &moreau::stepping::ContactState| if c.contact.i == 1 { c.force(h) } else { -c.force(h) };
        let force: DVec2 = sim.contacts().iter().map(on_block).sum();
        let load = mass * 9.81 + 400.0;
        assert!((force.y - load).abs() < 1e-6 * load, "step {k}: floor pushes {force} against {load}");
        assert!((force.x + 0.3 * load).abs() < 1e-6 * load, "step {k}: friction {} against {}", force.x, -0.3 * load);
    }
    assert!((sim.position(1).x - steps as f64 * h).abs() < 1e-12, "{}", sim.position(1).x);
    // Two disks held along x side by side, touching, falling together: along their shared
    // normal (x) neither can move, so no impulse acts there (it made W_nn = 0 and stopped the
    // run); both fall on at g.
    let disk = |x: f64| format!("[[body]]\ndisk = {{ center = [{x}, 1.0], radius = 0.1 }}\nhold_velocity = [\"x\"]\n");
    let (mut pair, _) =
        simulation(&format!("{}\n{}{}", header(r#""gravity", "friction""#, 1, 0.3, 1.0), disk(0.0), disk(0.2)));
    for k in 1..=50 {
        pair.step().unwrap_or_else(|e| panic!("step {k}: {e}"));
        assert!(pair.contacts().is_empty(), "step {k}: {} contacts between the held disks", pair.contacts().len());
        assert!((pair.velocity(1).y + 9.81 * k as f64 * h).abs() < 1e-12, "step {k}: {}", pair.velocity(1));
    }
    // The same block free along x slows at μ (g + 4) and stops.
    let (mut free, _) = simulation(&held_block("force = [0.0, -400.0]").replace("hold_velocity = [\"x\"]", ""));
    for _ in 0..100 {
        free.step().unwrap();
    }
    let expected = 1.0 - 0.3 * (9.81 + 4.0) * 0.1;
    assert!((free.velocity(1).x - expected).abs() < 1e-6, "{} vs {expected}", free.velocity(1).x);

    let hover = held_block("").replace("hold_velocity = [\"x\"]", "hold_velocity = [\"y\"]");
    let (mut sim, _) = simulation(&hover.replace("center = [0.0, 0.1]", "center = [0.0, 2.0]"));
    for _ in 0..100 {
        sim.step().unwrap();
    }
    assert!(sim.position(1).y == 2.0 && sim.velocity(1).y == 0.0, "{} {}", sim.position(1), sim.velocity(1));
    sim.apply_impulse(1, DVec2::new(50.0, 50.0), sim.position(1)).unwrap();
    // Half a metre a second more along x (the mass is 100 kg to f32's outline), nothing along y.
    let v = sim.velocity(1);
    assert!((v.x - 1.5).abs() < 1e-7 && v.y == 0.0, "{v}");
}

/// An axis that is not x or y, a fixed body that holds an axis, a force along a held axis are
/// refused by name; a grains file cannot carry a held axis; a checkpoint names them.
#[test]
fn held_axes_are_checked_saved_only_where_they_can_be_and_named_in_a_checkpoint() {
    for (change, named, words) in [
        ("hold_velocity = [\"x\"]", "hold_velocity = [\"z\"]", "unknown axis 'z'"),
        ("hold_velocity = [\"x\"]", "hold_velocity = [\"x\"]\nforce = [5.0, 0.0]", "force 5 along x"),
        ("velocity = [1.0, 0.0]", "velocity = [1.0, 0.0]\nfixed = true", "a fixed body holds its velocity"),
    ] {
        let text = held_block("").replace(change, named);
        let e = scene::parse(&text, Path::new("held.toml")).err().unwrap_or_else(|| panic!("{named} accepted"));
        let msg = e.to_string();
        assert!(msg.contains("body[1]") && msg.contains(words), "{named}: {msg}");
    }
    // A grains file has no column for a held axis: saving one is refused, naming the body.
    let disk = format!(
        "{}\n[[body]]\ndisk = {{ center = [0.0, 1.0], radius = 0.1 }}\nhold_velocity = [\"y\"]\n",
        header(r#""gravity""#, 1, 0.0, 1.0)
    );
    let (sim, _) = simulation(&disk);
    let why = moreau::io::grains::unsavable(&sim.world).expect("a held disk is not saved as a free one");
    assert!(why.contains("body 0 holds its velocity"), "{why}");
    // A checkpoint names the held axes among the shapes: one is not taken up by a scene that
    // holds other axes, or none.
    let prints: Vec<String> = ["[\"x\"]", "[\"y\"]", "[]"]
        .iter()
        .map(|axes| simulation(&held_block("").replace("[\"x\"]", axes)).0.world.shapes_fingerprint())
        .collect();
    assert!(prints[0] != prints[1] && prints[1] != prints[2] && prints[0] != prints[2], "{prints:?}");
}

/// Materials that pass through each other (`[[interaction]] pass_through = true`, LMGC90's
/// visibility table): a grain falls through a ghost wall and a ghost floor at exactly g while a
/// ghost disk rests on the same floor and a grain on a grain's; without the setting the grain
/// rests on the ghost floor too.
#[test]
fn materials_that_pass_through_each_other_never_touch() {
    let scene = |through: &str| {
        format!(
            r#"{}
[[material]]
name = "ghost"
density = 1000.0
[[interaction]]
materials = ["m", "ghost"]
{through}
[[wall]]
segment = [[-1.0, 0.05], [0.5, 0.05]]
material = "ghost"
[[body]]
polygon = {{ center = [0.0, -0.05], vertices = [[-5.0, -0.05], [5.0, -0.05], [5.0, 0.05], [-5.0, 0.05]] }}
material = "ghost"
fixed = true
[[body]]
disk = {{ center = [0.0, 0.1], radius = 0.1 }}
material = "m"
[[body]]
disk = {{ center = [1.0, 0.1], radius = 0.1 }}
material = "ghost"
[[body]]
polygon = {{ center = [3.0, -0.05], vertices = [[-0.5, -0.05], [0.5, -0.05], [0.5, 0.05], [-0.5, 0.05]] }}
material = "m"
fixed = true
[[body]]
disk = {{ center = [3.0, 0.1], radius = 0.1 }}
material = "m"
"#,
            header(r#""gravity", "friction""#, 100, 0.3, 1000.0)
        )
    };
    let (mut sim, steps) = simulation(&scene("pass_through = true"));
    for k in 1..=steps {
        let report = sim.step().unwrap();
        assert!(report.converged, "step {k}: {}", report.error);
        let t = k as f64 * 1e-3;
        assert!((sim.velocity(1).y + 9.81 * t).abs() < 1e-12, "step {k}: the grain at {}", sim.velocity(1));
        for rests in [2, 4] {
            assert!(sim.velocity(rests).length() < 1e-9, "step {k}: body {rests} at {}", sim.velocity(rests));
        }
        let grain = |c: &moreau::stepping::ContactState| c.contact.i == 1 || c.contact.other == Antagonist::Body(1);
        assert!(!sim.contacts().iter().any(grain), "step {k}: a contact on the grain");
    }
    // Through the wall it started across and into the floor: half a radius deep after 0.1 s.
    let fallen = 0.1 - 0.5 * 9.81 * 0.1f64.powi(2);
    assert!((sim.position(1).y - fallen).abs() < 1e-9, "the grain at {}, not {fallen}", sim.position(1));
    let (mut touching, _) = simulation(&scene(""));
    for _ in 0..steps {
        touching.step().unwrap();
    }
    assert!(touching.velocity(1).length() < 1e-9, "without pass_through the grain rests: {}", touching.velocity(1));
    let e = scene::parse(&scene("pass_through = 1"), Path::new("ghost.toml")).expect_err("a number for a bool");
    let line = scene("pass_through = 1").lines().position(|l| l == "pass_through = 1").unwrap() + 1;
    assert!(e.to_string().contains(&format!("line {line}: invalid type: integer `1`, expected a boolean")), "{e}");
}

/// A grain that starts 2 % of its radius into the floor (a settled pile saved and read back)
/// keeps that overlap and still slides: a block's Coulomb deceleration, exactly, as if it touched.
#[test]
fn a_grain_started_into_the_floor_keeps_its_overlap_and_slides() {
    let (mu, g, y0) = (0.3, 9.81, 0.098);
    let toml = format!(
        "{}\n[[wall]]\nsegment = [[-5.0, 0.0], [5.0, 0.0]]\n[[body]]\ndisk = {{ center = [0.0, {y0}], radius = 0.1 }}\n\
         velocity = [1.0, 0.0]\n",
        header(r#""gravity", "friction""#, 100, mu, 1000.0)
    );
    let (mut sim, steps) = simulation(&toml);
    let warned = sim.check().unwrap().to_vec();
    assert!(warned.iter().any(|w| w.contains("overlapping a wall") && w.contains("the overlaps stay")), "{warned:?}");
    for _ in 0..steps {
        assert!(sim.step().unwrap().converged);
    }
    let v = 1.0 - mu * g * sim.time();
    assert!((sim.velocity(0).x - v).abs() < 1e-9, "slides at {}, not {v}", sim.velocity(0));
    assert!((sim.position(0).y - y0).abs() < 1e-12, "the overlap changed: y = {}", sim.position(0).y);
}

/// A disk sliding to rest on a fixed floor (no rotation) loses its kinetic energy through its
/// contact: each step dissipates μ m g h v̄, and in all ½ m v₀².
#[test]
fn a_disk_sliding_to_rest_dissipates_its_kinetic_energy_by_friction() {
    let (mu, g, h, v0) = (0.3, 9.81, 1e-3, 1.0);
    let toml = format!(
        "{}\n[[wall]]\nsegment = [[-5.0, 0.0], [5.0, 0.0]]\n[[body]]\ndisk = {{ center = [0.0, 0.1], radius = 0.1 }}\n\
         velocity = [{v0:?}, 0.0]\n",
        header(r#""gravity", "friction""#, 500, mu, 1000.0)
    );
    let (mut sim, steps) = simulation(&toml);
    let (k0, mass) = (sim.world.kinetic_energy(), sim.world.bodies.mass[0]);
    let mut dissipated = 0.0;
    for _ in 0..steps {
        let before = sim.velocity(0).x;
        let r = sim.step().unwrap();
        assert!(r.converged && r.boundary_work == 0.0, "step {}: {r:?}", r.step);
        let after = sim.velocity(0).x;
        if after >= mu * g * h {
            let expected = mu * mass * g * h * 0.5 * (before + after);
            assert!((r.dissipated_energy - expected).abs() <= 1e-9 * expected, "step {}: {r:?}", r.step);
        }
        dissipated += r.dissipated_energy;
    }
    assert!(sim.velocity(0).length() < 1e-12 && (k0 - 0.5 * mass * v0 * v0).abs() < 1e-12 * k0);
    assert!((dissipated - k0).abs() <= 1e-9 * k0, "dissipated {dissipated} J of {k0} J");
}

/// With θ = ½ a step's change of kinetic and potential energy is the work of its impulses at the
/// mean velocity: the pile loses what its contacts dissipate, and gains what the wall pushing it
/// does, step by step, in every step the position projection leaves alone.
#[test]
fn a_pushed_pile_changes_its_energy_by_the_walls_work_less_what_its_contacts_dissipate() {
    let scene = pile(120, 150, 1e-6, 0.0, r#""gravity", "friction", "rotation", "moving_walls""#).replace(
        "container = { min = [0.0, 0.0], max = [0.06, 0.3] }",
        "segment = [[-0.1, 0.0], [0.2, 0.0]]\n[[wall]]\nsegment = [[0.0, 0.3], [0.0, 0.0]]\n\
         [[wall]]\nsegment = [[0.06, 0.0], [0.06, 0.3]]\nvelocity = [-0.02, 0.0]",
    );
    let (mut sim, steps) = simulation(&scene);
    let scale = sim.world.potential_energy().abs();
    let mut energy = sim.world.kinetic_energy() + sim.world.potential_energy();
    let (mut dissipated, mut work, mut checked) = (0.0, 0.0, 0);
    for _ in 0..steps {
        let r = sim.step().unwrap();
        let now = r.kinetic_energy + r.potential_energy;
        if r.projected == 0 {
            let imbalance = now - energy + r.dissipated_energy - r.boundary_work;
            assert!(imbalance.abs() <= 1e-12 * scale, "step {}: {imbalance:e} J of {scale} J: {r:?}", r.step);
            checked += 1;
        }
        (energy, dissipated, work) = (now, dissipated + r.dissipated_energy, work + r.boundary_work);
    }
    assert!(checked >= steps * 9 / 10, "{checked} of {steps} steps checked");
    assert!(dissipated > 0.1 * scale && work > 0.0, "dissipated {dissipated} J, the wall's work {work} J");
}

/// A belt brings a grain resting on it to its speed V by friction: it does m V² of work, half of
/// it the grain's kinetic energy and half dissipated at the contact — for a belt that is a fixed
/// body given a velocity and for one that is a moving wall.
#[test]
fn a_belt_gives_a_grain_its_speed_and_dissipates_as_much_as_it_gives() {
    let wall_belt = format!(
        "{}\n[[wall]]\nsegment = [[-5.0, 0.0], [5.0, 0.0]]\nvelocity = [1.0, 0.0]\n[[body]]\n\
         disk = {{ center = [0.0, 0.1], radius = 0.1 }}\n",
        header(r#""gravity", "friction", "moving_walls""#, 1000, 0.2, 1000.0)
    );
    for (name, text, grain) in [("fixed body", conveyor(r#""gravity", "friction""#), 1), ("wall", wall_belt, 0)] {
        let (mut sim, steps) = simulation(&text);
        let mass = sim.world.bodies.mass[grain];
        let (mut dissipated, mut work) = (0.0, 0.0);
        for _ in 0..steps {
            let r = sim.step().unwrap();
            let round_off = -1e-12 * mass;
            assert!(r.converged && r.dissipated_energy >= round_off && r.boundary_work >= round_off, "{name}: {r:?}");
            (dissipated, work) = (dissipated + r.dissipated_energy, work + r.boundary_work);
        }
        let v = sim.velocity(grain).x;
        assert!((v - 1.0).abs() < 1e-5, "{name}: the grain moves at {v}");
        assert!((work - mass).abs() < 1e-4 * mass, "{name}: the belt's work {work} J, m V² = {mass} J");
        assert!((dissipated - 0.5 * mass).abs() < 1e-4 * mass, "{name}: dissipated {dissipated} J of {} J", 0.5 * mass);
    }
}
