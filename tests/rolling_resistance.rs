//! Rolling resistance: a disk rolling on a floor stops after 3 v₀² / (4 η g); on an incline it
//! stays put while tan θ ≤ η and rolls with 2/3 g (sin θ − η cos θ) beyond; the rolling row is
//! judged by the error measure; threads, restarts and refusals.

use std::path::Path;

use glam::DVec2;
use moreau::backend::DeviceChoice;
use moreau::problem::residual::{error_of, natural_map_error, natural_map_error_rolling};
use moreau::scene;
use moreau::solvers::{self, SolverKind, SolverOptions};
use moreau::stepping::Simulation;

const G: f64 = 9.81;

fn simulation(toml: &str) -> (Simulation, usize) {
    let s = scene::parse(toml, Path::new("rolling.toml")).unwrap_or_else(|e| panic!("{e}"));
    let steps = s.steps;
    (Simulation::new(s.world, s.settings).unwrap(), steps)
}

/// A disk of radius 0.1 on a floor tilted by `deg` (down to the right), rolling down the slope
/// at `v0` without slipping.
fn incline(deg: f64, v0: f64, eta: f64, effects: &str, steps: usize) -> String {
    let t = deg.to_radians();
    let dir = DVec2::new(t.cos(), -t.sin());
    let n = DVec2::new(t.sin(), t.cos());
    let (a, b, c) = (-10.0 * dir, 40.0 * dir, 0.1 * n);
    let v = v0 * dir;
    format!(
        r#"
effects = [{effects}]
[time]
step = 1e-3
steps = {steps}
[solver]
name = "nlgs"
tol = 1e-10
max_iter = 10000
[contact]
friction = 0.5
rolling_resistance = {eta}
[[material]]
name = "m"
density = 1000.0
[[wall]]
segment = [[{ax}, {ay}], [{bx}, {by}]]
[[body]]
disk = {{ center = [{cx}, {cy}], radius = 0.1 }}
velocity = [{vx}, {vy}]
spin = {spin}
"#,
        ax = a.x,
        ay = a.y,
        bx = b.x,
        by = b.y,
        cx = c.x,
        cy = c.y,
        vx = v.x,
        vy = v.y,
        spin = -v0 / 0.1
    )
}

const ALL: &str = r#""gravity", "friction", "rotation", "rolling_resistance""#;

/// Runs every step (each must converge); returns the distance travelled along the slope and
/// the final speed and spin.
fn roll(text: &str) -> (f64, f64, f64) {
    let (mut sim, steps) = simulation(text);
    let start = sim.position(0);
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged, "step {} error {}", r.step, r.error);
    }
    ((sim.position(0) - start).length(), sim.velocity(0).length(), sim.spin(0))
}

#[test]
fn a_disk_rolling_on_a_floor_stops_after_three_v0_squared_over_four_eta_g() {
    for (v0, eta) in [(1.0, 0.05), (2.0, 0.2)] {
        let expected = 3.0 * v0 * v0 / (4.0 * eta * G);
        let stop_time = v0 / (2.0 / 3.0 * eta * G);
        let steps = (1.3 * stop_time / 1e-3) as usize;
        let (distance, speed, spin) = roll(&incline(0.0, v0, eta, ALL, steps));
        assert!((distance - expected).abs() <= 0.01 * expected, "v0 {v0}, η {eta}: {distance} m, expected {expected}");
        assert!(speed < 1e-9 && spin.abs() < 1e-8, "stopped for good: speed {speed}, spin {spin}");
    }
    // Not named, the effect is off and costs nothing: the disk rolls on at v0.
    let free = r#""gravity", "friction", "rotation""#;
    let (distance, speed, _) = roll(&incline(0.0, 1.0, 0.05, free, 500));
    assert!((distance - 0.5).abs() < 1e-9 && (speed - 1.0).abs() < 1e-9, "{distance} m at {speed} m/s");
}

/// Rolling without slipping, the disk loses its kinetic energy through its contact's rolling
/// row: what the steps report dissipated is all of it.
#[test]
fn a_disk_rolling_to_rest_dissipates_its_kinetic_energy_at_its_contact() {
    let (v0, eta) = (2.0, 0.2);
    let steps = (1.3 * v0 / (2.0 / 3.0 * eta * G) / 1e-3) as usize;
    let (mut sim, _) = simulation(&incline(0.0, v0, eta, ALL, steps));
    let k0 = sim.world.kinetic_energy();
    let mut dissipated = 0.0;
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged && r.dissipated_energy >= -1e-15 * k0 && r.boundary_work == 0.0, "{r:?}");
        dissipated += r.dissipated_energy;
    }
    assert!(sim.world.kinetic_energy() < 1e-12 * k0, "still moving");
    assert!((dissipated - k0).abs() <= 1e-9 * k0, "dissipated {dissipated} J of {k0} J");
}

#[test]
fn on_an_incline_a_disk_stays_while_tan_theta_is_below_eta_and_rolls_beyond() {
    let eta = 0.05;
    // tan 2° = 0.035 < η: held at rest.
    let (distance, speed, _) = roll(&incline(2.0, 0.0, eta, ALL, 500));
    assert!(distance < 1e-9 && speed < 1e-9, "held: moved {distance}, speed {speed}");
    // tan 6° = 0.105 > η: rolls with a = 2/3 g (sin θ − η cos θ).
    let t = 6.0f64.to_radians();
    let a = 2.0 / 3.0 * G * (t.sin() - eta * t.cos());
    let (_, speed, _) = roll(&incline(6.0, 0.0, eta, ALL, 500));
    let measured = speed / 0.5;
    assert!((measured - a).abs() <= 0.01 * a, "a = {measured}, expected {a}");
}

/// A pile of `count` disks under rolling resistance η (a deposition, ready to settle).
fn pile(count: usize, eta: f64, criterion: &str) -> String {
    format!(
        r#"
effects = ["gravity", "friction", "rotation", "rolling_resistance"]
[time]
step = 1e-3
steps = 5
[solver]
name = "nlgs"
tol = 1e-6
max_iter = 20000
criterion = "{criterion}"
[contact]
friction = 0.5
rolling_resistance = {eta}
[[material]]
name = "grain"
density = 2600.0
[[wall]]
container = {{ min = [0.0, 0.0], max = [60.0, 400.0] }}
[[generate]]
kind = "deposition"
count = {count}
radius = [0.4, 0.6]
region = {{ min = [0.0, 0.0], max = [60.0, 400.0] }}
seed = 3
"#
    )
}

#[test]
fn the_error_measure_judges_the_rolling_rows() {
    let (mut sim, _) = simulation(&pile(300, 0.1, "natural"));
    let (problem, r0) = sim.next_problem().unwrap().expect("a pile has contacts");
    let nc = problem.n_contacts();
    assert!(problem.has_rolling() && problem.unknowns() == 3 * nc && r0.len() == 3 * nc);
    let solved = solvers::solve(&problem, SolverKind::Nlgs, &SolverOptions { tol: 1e-9, ..Default::default() }, None);
    assert!(solved.converged && solved.error <= 1e-9, "{}", solved.error);
    let (error, u) = error_of(&problem, &solved.r);
    assert!(error <= 1e-9);
    // Rolling impulses act: some contact is at its bound or holding a spin back.
    let rolling = &solved.r[2 * nc..];
    assert!(rolling.iter().any(|x| x.abs() > 0.0), "no rolling impulse in a settling pile");
    // The (n, t) rows alone may look solved while a rolling row is not: pushing every rolling
    // impulse past its bound must show in the error, and only through the rolling rows.
    let mut bad = solved.r.clone();
    for a in 0..nc {
        bad[2 * nc + a] = 2.0 * problem.rolling[a] * bad[2 * a] + 1.0;
    }
    let u_bad = problem.velocity(&bad);
    let pairs_only = natural_map_error(&problem.q[..2 * nc], &problem.mu, &bad[..2 * nc], &u_bad[..2 * nc]);
    let with_rolling = natural_map_error_rolling(&problem.q, &problem.mu, &problem.rolling, &bad, &u_bad);
    assert!(with_rolling > 1e-3 && with_rolling > 10.0 * pairs_only, "{with_rolling} vs {pairs_only}");
    assert_eq!(natural_map_error_rolling(&problem.q, &problem.mu, &problem.rolling, &solved.r, &u), error);
}

#[test]
fn a_threaded_sweep_solves_rolling_rows_the_same_on_every_run() {
    // Over 4096 contacts: two threads sweep colour by colour.
    let (mut sim, _) = simulation(&pile(3000, 0.1, "velocity"));
    let (problem, _) = sim.next_problem().unwrap().unwrap();
    assert!(problem.n_contacts() >= 4096, "{} contacts", problem.n_contacts());
    let opts = SolverOptions { tol: 1e-5, max_iter: 20000, ..Default::default() };
    let on = |threads: usize| {
        moreau::parallel::with_threads(threads, || solvers::solve(&problem, SolverKind::Nlgs, &opts, None)).unwrap()
    };
    // Products with rolling rows: each body sums its own contacts on threads, the same bits.
    let r: Vec<f64> = (0..problem.unknowns()).map(|k| (k as f64 * 0.37).sin().abs()).collect();
    let velocity = |threads: usize| moreau::parallel::with_threads(threads, || problem.velocity(&r)).unwrap();
    assert_eq!(velocity(1), velocity(2));
    for threads in [1, 2] {
        let (a, b) = (on(threads), on(threads));
        assert!(a.converged, "{threads} thread(s): error {}", a.error);
        assert_eq!(a.r, b.r, "{threads} thread(s): two runs differ");
        let (error, _) = error_of(&problem, &a.r);
        assert!(error < 1.0 && a.r[2 * problem.n_contacts()..].iter().any(|x| *x != 0.0));
    }
}

#[test]
fn a_work_list_solves_rolling_rows() {
    let (mut sim, _) = simulation(&pile(300, 0.1, "velocity"));
    let (problem, _) = sim.next_problem().unwrap().unwrap();
    let opts = SolverOptions {
        tol: 1e-6,
        max_iter: 20000,
        criterion: solvers::StopCriterion::Velocity,
        ordering: solvers::Ordering::Worklist,
        ..Default::default()
    };
    let solved = solvers::solve(&problem, SolverKind::Nlgs, &opts, None);
    assert!(solved.converged && solved.judged_error <= 1e-6, "{:.2e} {}", solved.judged_error, solved.stop_reason);
    let nc = problem.n_contacts();
    let u = problem.velocity(&solved.r);
    let diag = problem.w.diag_blocks();
    let velocity = moreau::problem::residual::velocity_error_rolling(
        &diag,
        &problem.q,
        &problem.mu,
        &problem.rolling,
        &problem.gap_rate,
        &solved.r,
        &u,
    );
    assert!(velocity <= 1e-6, "{velocity:.2e}");
    assert!(solved.r[2 * nc..].iter().any(|x| *x != 0.0), "no rolling impulse");
}

#[test]
fn a_restart_carries_the_rolling_impulses_bit_for_bit() {
    let text = pile(200, 0.2, "natural");
    let (mut whole, _) = simulation(&text);
    let (mut first, _) = simulation(&text);
    for _ in 0..10 {
        whole.step().unwrap();
    }
    for _ in 0..5 {
        first.step().unwrap();
    }
    let c = first.checkpoint();
    assert!(c.contacts.iter().any(|x| x.rolling != 0.0), "the checkpoint carries rolling impulses");
    let json = serde_json::to_string(&c).unwrap();
    let (mut second, _) = simulation(&text);
    second.restore(&serde_json::from_str(&json).unwrap()).unwrap();
    for _ in 0..5 {
        second.step().unwrap();
    }
    assert_eq!(whole.positions(), second.positions());
    assert_eq!(whole.velocities(), second.velocities());
}

#[test]
fn rolling_resistance_is_refused_where_it_cannot_be_solved() {
    let refused = |text: String, words: &str| {
        let Err(e) = scene::parse(&text, Path::new("rolling.toml")) else { panic!("accepted: {text}") };
        let e = e.to_string();
        assert!(e.contains(words), "{e}");
    };
    let base = pile(10, 0.1, "natural");
    refused(base.replace("name = \"nlgs\"", "name = \"cpg\""), "rolling resistance is solved by nlgs only");
    refused(base.replace("\"natural\"", "\"quad\""), "natural or velocity criterion");
    refused(base.replace("\"rotation\", ", ""), "needs the effect `rotation`");
    refused(base.replace("rolling_resistance = 0.1", "rolling_resistance = -1.0"), "rolling_resistance -1");
    // `gpu` is refused before any adapter is opened; `auto` takes the CPU and says why.
    let (mut sim, _) = simulation(&base);
    let e = sim.choose_device(DeviceChoice::Gpu).unwrap_err().to_string();
    assert!(e.contains("CPU only"), "{e}");
    let line = sim.choose_device(DeviceChoice::Auto).unwrap();
    assert!(line.starts_with("cpu") && line.contains("rolling resistance"), "{line}");
}
