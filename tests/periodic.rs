//! Periodic boundaries along x (`[periodic] x = [x0, x1]`): what leaves at x1 comes back at x0,
//! grains touch through the boundary, and a pile needs no side walls.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

use std::path::Path;

use moreau::detection::Antagonist;
use moreau::scene;
use moreau::stepping::Simulation;

fn simulation(toml: &str) -> Simulation {
    let s = scene::parse(toml, Path::new("periodic.toml")).unwrap_or_else(|e| panic!("{e}"));
    Simulation::new(s.world, s.settings).unwrap()
}

/// Disks of radius 0.01 with no gravity in the cell [0, 0.1]: (x, y, vx) each.
fn disks(disks: &[(f64, f64, f64)], cell: &str) -> String {
    let mut s = format!(
        "effects = [\"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 100\n[solver]\ntol = 1e-12\nmax_iter = 10000\n\
         [contact]\nfriction = 0.3\n{cell}[[material]]\nname = \"g\"\ndensity = 1000.0\n"
    );
    for (x, y, vx) in disks {
        s.push_str(&format!("[[body]]\ndisk = {{ center = [{x}, {y}], radius = 0.01 }}\nvelocity = [{vx}, 0.0]\n"));
    }
    s
}

const CELL: &str = "[periodic]\nx = [0.0, 0.1]\n";

#[test]
fn a_free_disk_crossing_x1_reappears_at_x0() {
    let mut sim = simulation(&disks(&[(0.09, 0.5, 1.0)], CELL));
    for _ in 0..20 {
        sim.step().unwrap();
    }
    // 0.09 + 20 × 1e-3 × 1 = 0.11, that is 0.01 in the cell.
    assert!((sim.position(0).x - 0.01).abs() < 1e-12, "{}", sim.position(0));
    assert_eq!(sim.velocity(0).x, 1.0);
    // A scene may start with grains outside the cell: they are brought in.
    let sim = simulation(&disks(&[(-0.03, 0.5, 0.0)], CELL));
    assert!((sim.position(0).x - 0.07).abs() < 1e-12, "{}", sim.position(0));
}

#[test]
fn two_disks_collide_through_the_boundary_as_they_do_inside_the_cell() {
    // An oblique collision with friction: the left disk at 1 m/s meets the right one, at rest
    // and 5 mm higher, 5 mm later; both come out turning.
    let after = |a: f64, b: f64| {
        let mut sim = simulation(&disks(&[(a, 0.5, 1.0), (b, 0.505, 0.0)], CELL));
        let mut through = false;
        for _ in 0..15 {
            sim.step().unwrap();
            through |= sim.contacts().iter().any(|c| c.contact.image.x != 0.0 && c.impulse[0] > 0.0);
        }
        let state =
            [sim.velocity(0).x, sim.velocity(0).y, sim.spin(0), sim.velocity(1).x, sim.velocity(1).y, sim.spin(1)];
        (state, through)
    };
    let (inside, direct) = after(0.035, 0.06);
    let (across, through) = after(0.085, 0.01); // the same pair, its centres apart through x = 0.1
    assert!(!direct && through, "the second pair touches through the boundary");
    assert!(inside[2] != 0.0 && inside[5] != 0.0 && inside[4] > 0.0, "{inside:?}");
    for (v, w) in inside.iter().zip(&across) {
        assert!((v - w).abs() < 1e-12, "inside {inside:?}\nacross {across:?}");
    }
}

#[test]
fn a_periodic_pile_has_no_side_walls_yet_keeps_its_grains() {
    let scene = r#"
effects = ["gravity", "friction", "rotation"]
[time]
step = 2e-3
steps = 250
[solver]
tol = 1e-4
max_iter = 3000
[contact]
friction = 0.4
[periodic]
x = [0.0, 0.1]
[[material]]
name = "glass"
density = 2500.0
[[wall]]
segment = [[-0.01, 0.0], [0.11, 0.0]]
[[generate]]
kind = "grid"
count = 120
radius = [0.002, 0.003]
region = { min = [0.0, 0.0], max = [0.1, 0.2] }
velocity = [0.3, 0.0]
seed = 3
"#;
    let mut sim = simulation(scene);
    let start = sim.world.kinetic_energy();
    let mut through = 0;
    for _ in 0..250 {
        let report = sim.step().unwrap();
        assert!(report.max_penetration < 1e-3 * 0.005, "step {}: {}", report.step, report.max_penetration);
        through += sim
            .contacts()
            .iter()
            .filter(|c| matches!(c.contact.other, Antagonist::Body(_)) && c.contact.image.x != 0.0)
            .count();
    }
    assert!(through > 0, "no contact through the boundary");
    for k in 0..sim.body_count() {
        let p = sim.position(k);
        assert!((0.0..0.1).contains(&p.x) && p.y > 0.0 && p.y < 0.2, "grain {k} at {p}");
    }
    // The grains, thrown sideways at 0.3 m/s, settle; the cell measures the packing.
    assert!(sim.world.kinetic_energy() < 1e-3 * start, "{} of {start}", sim.world.kinetic_energy());
    let phi = sim.measures().packing_fraction;
    assert!(phi > 0.6 && phi < 0.92, "packing fraction {phi}");
}

#[test]
fn a_cell_too_short_for_its_grains_is_refused() {
    let text = disks(&[(0.05, 0.5, 0.0)], "[periodic]\nx = [0.0, 0.07]\n");
    let Err(e) = scene::parse(&text, Path::new("periodic.toml")) else { panic!("accepted") };
    assert!(e.to_string().contains("periodic.x") && e.to_string().contains("at least 4"), "{e}");
    let text = disks(&[(0.05, 0.5, 0.0)], "[periodic]\nx = [0.1, 0.0]\n");
    let Err(e) = scene::parse(&text, Path::new("periodic.toml")) else { panic!("accepted") };
    assert!(e.to_string().contains("periodic.x"), "{e}");
}

/// `[output] profile = true`: `moreau run` writes the moving grains by height every `every` steps
/// and at the last, one mean diameter a layer.
#[test]
fn a_run_writes_the_height_profile_of_its_grains() {
    // Two rows of five disks sliding at 1 and 2 m/s, untouched (no gravity, 1 mm apart).
    let rows: Vec<(f64, f64, f64)> =
        (0..10).map(|k| (0.01 + 0.02 * (k % 5) as f64, 0.01 + 0.021 * (k / 5) as f64, 1.0 + (k / 5) as f64)).collect();
    let dir = Scratch::new("profile");
    let scene = dir.join("rows.toml");
    std::fs::write(&scene, disks(&rows, CELL) + "[output]\nevery = 2\nprofile = true\n").unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_moreau"))
        .args(["run", scene.to_str().unwrap(), "--steps", "5", "--device", "cpu", "--quiet", "--out"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(dir.join("out/profile.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("step,time,y_low,y_high,grains,solid_fraction,vx,vy,spin,velocity_fluctuation"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
    // Steps 2, 4 and 5 (the last), three layers 2 cm high each: a row's centres in each of the
    // two lower ones; the upper row's disks reach 1 mm into the third.
    assert_eq!(rows.iter().map(|r| r[0]).collect::<Vec<_>>(), [2.0, 2.0, 2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 5.0]);
    // Five caps of height h cut from disks of radius r: r² acos((r − h)/r) − (r − h) √(2rh − h²).
    let r = 0.01f64;
    let area = |h: f64| 5.0 * (r * r * ((r - h) / r).acos() - (r - h) * (2.0 * r * h - h * h).sqrt());
    let (cut, full) = (area(0.001) / (0.1 * 0.02), 5.0 * std::f64::consts::PI * 1e-4 / (0.1 * 0.02));
    for (n, r) in rows.iter().enumerate() {
        let (grains, vx, fraction) = [(5.0, 1.0, full), (5.0, 2.0, full - cut), (0.0, 0.0, cut)][n % 3];
        assert_eq!(r[4], grains, "{r:?}");
        assert!((r[6] - vx).abs() < 1e-12 && r[9].abs() < 1e-12, "{r:?}");
        assert!((r[5] - fraction).abs() < 1e-9, "{r:?} against {fraction}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `scenes/inclined_flow.toml`: a bed of fixed grains tagged 1 (`[[generate]] fixed`, `tag`)
/// under a flowing layer tagged 0, all in the cell; a few steps start it down the slope.
#[test]
fn the_inclined_flow_runs_down_a_bed_of_fixed_grains_tagged_apart() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/inclined_flow.toml");
    let s = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let b = &s.world.bodies;
    let bed: Vec<usize> = (0..b.len()).filter(|&k| b.inv_mass[k] == 0.0).collect();
    assert_eq!(bed.len(), 39);
    assert!(bed.iter().all(|&k| b.tag[k] == 1 && b.position[k].y < 0.006));
    assert!((0..b.len()).filter(|k| !bed.contains(k)).all(|k| b.tag[k] == 0 && b.position[k].y > 0.006));
    let mut sim = Simulation::new(s.world, s.settings).unwrap();
    for _ in 0..100 {
        assert!(sim.step().unwrap().error.is_finite());
    }
    let bed_still = bed.iter().all(|&k| sim.velocity(k) == glam::DVec2::ZERO);
    let moving: Vec<usize> = (0..sim.world.bodies.len()).filter(|k| !bed.contains(k)).collect();
    let mean_vx = moving.iter().map(|&k| sim.velocity(k).x).sum::<f64>() / moving.len() as f64;
    assert!(bed_still && mean_vx > 0.0, "mean vx {mean_vx}");
}
