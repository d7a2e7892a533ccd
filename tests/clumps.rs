//! Clumps (rigid grains of overlapping disks): what their shape changes in the physics, their
//! mass, their outputs, and the refusals that name a bad clump.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

use std::f64::consts::PI;
use std::path::Path;

use glam::DVec2;
use moreau::scene;
use moreau::stepping::Simulation;

mod common;
use common::disk_and_dimer_on_a_slope;

fn simulation(toml: &str) -> (Simulation, usize) {
    let s = scene::parse(toml, Path::new("test.toml")).unwrap_or_else(|e| panic!("{e}"));
    let steps = s.steps;
    (Simulation::new(s.world, s.settings).unwrap(), steps)
}

/// On a 20° slope with μ 0.5 (tan 20° = 0.36) a disk rolls without slipping, its centre
/// accelerating at ⅔ g sin θ, while a dimer lying on the slope rests on its two disks and stays
/// where it is: the shape, not the friction, decides. Tolerance: the disk's speed within 0.5 %
/// of the closed form, the dimer still to 1e-9 m/s.
#[test]
fn a_dimer_rests_on_a_slope_down_which_a_disk_rolls() {
    let (mut sim, steps) = simulation(&disk_and_dimer_on_a_slope(20.0));
    let start = sim.position(1);
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged, "step {} error {}", r.step, r.error);
    }
    let t = 20f64.to_radians();
    let dir = DVec2::new(t.cos(), -t.sin());
    let rolling = 2.0 / 3.0 * 9.81 * t.sin() * sim.time();
    let v = sim.velocity(0).dot(dir);
    assert!((v - rolling).abs() < 5e-3 * rolling, "disk {v} m/s, rolling {rolling} m/s");
    assert!(sim.velocity(1).length() < 1e-9 && sim.spin(1).abs() < 1e-8, "{} {}", sim.velocity(1), sim.spin(1));
    assert!(sim.position(1).distance(start) < 1e-9, "the dimer moved {}", sim.position(1).distance(start));
    // Both of its disks carry it: two contacts with the slope.
    assert_eq!(sim.contacts().iter().filter(|c| c.contact.i == 1 && c.impulse[0] > 0.0).count(), 2);
}

/// A dimer standing on its end, tilted by 0.05 rad, on a frictionless floor: no horizontal
/// force acts, so its centre of mass falls straight down (to 1e-9 m) while it topples, and it
/// ends lying on both disks (centre at one radius above the floor, to 1e-4 of it). Its mass is
/// the density times the union's area (the lens counted once, to 1e-12).
#[test]
fn a_standing_dimer_topples_with_its_centre_falling_straight_on_a_frictionless_floor() {
    let (r, d, tilt) = (0.1f64, 0.16, 0.05f64);
    let axis = DVec2::new(-tilt.sin(), tilt.cos());
    let (low, high) = (DVec2::new(0.0, r), DVec2::new(0.0, r) + d * axis);
    let text = format!(
        "effects = [\"gravity\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 2500\n[solver]\ntol = 1e-8\n\
         [[material]]\nname = \"m\"\ndensity = 1000.0\n[[wall]]\nsegment = [[-2.0, 0.0], [2.0, 0.0]]\n\
         [[body]]\nclump = {{ center = [0.0, 0.0], disks = [[{}, {}, {r}], [{}, {}, {r}]] }}\n",
        low.x, low.y, high.x, high.y
    );
    let (mut sim, steps) = simulation(&text);
    let lens = 2.0 * r * r * (d / (2.0 * r)).acos() - 0.5 * d * (4.0 * r * r - d * d).sqrt();
    let mass = 1000.0 * (2.0 * PI * r * r - lens);
    assert!((sim.world.bodies.mass[0] - mass).abs() < 1e-12 * mass, "{} vs {mass}", sim.world.bodies.mass[0]);
    let x0 = sim.position(0).x;
    assert!((x0 - (low.x + high.x) / 2.0).abs() < 1e-15);
    for _ in 0..steps {
        let s = sim.step().unwrap();
        assert!(s.converged, "step {} error {}", s.step, s.error);
        assert!(
            (sim.position(0).x - x0).abs() < 1e-9,
            "step {}: the centre moved sideways to {}",
            s.step,
            sim.position(0).x
        );
    }
    assert!((sim.position(0).y - r).abs() < 1e-4 * r, "ends at height {}", sim.position(0).y);
    assert_eq!(sim.contacts().iter().filter(|c| c.impulse[0] > 0.0).count(), 2, "lying on both disks");
}

/// Two dimers stacked on a floor segment, and a third on a fixed polygon plate, come to rest:
/// the upper dimer on the lower by two contacts between their disks, the floor carrying both
/// weights (to 1e-6), the plate's dimer at one disk radius above it (to 1e-6 m), each pair of
/// grains one neighbour however many contacts it has, every step
/// solved to 1e-8 (with parry2d's f32 normals the plate's two supports disagreed by 1e-7 rad and
/// NLGS cycled at 3e-8).
#[test]
fn stacked_dimers_and_a_dimer_on_a_polygon_rest_on_every_pair_of_disks() {
    let dimer = |x: f64, y: f64| {
        format!("[[body]]\nclump = {{ center = [{x}, {y}], disks = [[-0.08, 0.0, 0.1], [0.08, 0.0, 0.1]] }}\n")
    };
    let text = format!(
        "effects = [\"gravity\", \"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 600\n[solver]\ntol = 1e-8\n\
         max_iter = 20000\n[contact]\nfriction = 0.5\n[[material]]\nname = \"m\"\ndensity = 1000.0\n\
         [[wall]]\nsegment = [[-1.0, 0.0], [1.0, 0.0]]\n{}{}\
         [[body]]\npolygon = {{ center = [3.0, -0.05], vertices = [[-0.5, -0.05], [0.5, -0.05], [0.5, 0.05], [-0.5, 0.05]] }}\n\
         fixed = true\n{}",
        dimer(0.0, 0.1005),
        dimer(0.0, 0.302),
        dimer(3.0, 0.101)
    );
    let (mut sim, steps) = simulation(&text);
    for _ in 0..steps {
        let r = sim.step().unwrap();
        assert!(r.converged, "step {} error {}", r.step, r.error);
    }
    let weight = 9.81 * (sim.world.bodies.mass[0] + sim.world.bodies.mass[1]);
    let floor = sim.wall_loads()[0].force;
    assert!(floor[0].abs() < 1e-6 * weight && (floor[1] + weight).abs() < 1e-6 * weight, "{floor:?} vs {weight}");
    let pairs = sim.contacts().iter().filter(|c| {
        c.contact.i == 0 && c.impulse[0] > 0.0 && c.contact.other == moreau::detection::Antagonist::Body(1)
    });
    assert_eq!(pairs.count(), 2, "the upper dimer rests on both disks of the lower");
    assert!((sim.position(1).y - 0.3).abs() < 1e-6 && sim.velocity(1).length() < 1e-9, "{}", sim.position(1));
    assert!((sim.position(3).y - 0.1).abs() < 1e-6 && sim.velocity(3).length() < 1e-9, "{}", sim.position(3));
    // Contacts a grain: 4 for the lower dimer (floor and upper dimer, two each), 2 for each other;
    // neighbours: 2 for the lower dimer, 1 for each other (double contacts count once).
    let m = sim.measures();
    assert_eq!((m.coordination, m.neighbours, m.rattlers), (8.0 / 3.0, 4.0 / 3.0, 0), "{m:?}");
}

/// A deposition of trimers: each grain is the shape scaled to its drawn radius (bounding radius
/// within [r_min, r_max]), turned at random, and the deposit, loose at first, settles into a
/// pile whose grains touch by several disks.
#[test]
fn a_deposition_of_trimers_settles() {
    let text = "effects = [\"gravity\", \"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 600\n[solver]\ntol = 1e-4\n\
                max_iter = 2000\n[contact]\nfriction = 0.4\n[[material]]\nname = \"m\"\ndensity = 1000.0\n\
                [[wall]]\ncontainer = { min = [0.0, 0.0], max = [0.3, 0.5] }\n[[generate]]\nkind = \"deposition\"\ncount = 150\n\
                radius = [0.008, 0.012]\nregion = { min = [0.0, 0.0], max = [0.3, 0.5] }\n\
                clump = [[0.0, 0.4619, 0.5], [-0.4, -0.2309, 0.5], [0.4, -0.2309, 0.5]]\n";
    let (mut sim, steps) = simulation(text);
    let b = &sim.world.bodies;
    assert_eq!(b.clumps.len(), 150);
    for k in 0..b.len() {
        assert!((0.008 - 1e-12..=0.012 + 1e-12).contains(&b.bounding_radius[k]), "{}", b.bounding_radius[k]);
    }
    let angles: Vec<f64> = (0..b.len()).map(|k| sim.angle(k)).collect();
    assert!(angles.iter().any(|a| (a - angles[0]).abs() > 0.1), "turned at random");
    for _ in 0..steps {
        sim.step().unwrap();
    }
    let per_grain = sim.contacts().iter().filter(|c| c.impulse[0] > 0.0).count() as f64 / 150.0;
    assert!(
        per_grain > 1.5 && sim.world.kinetic_energy() < 1e-3,
        "{per_grain} contacts a grain, {} J",
        sim.world.kinetic_energy()
    );
}

/// A clump is written as a polygon cell over its outline, and `moreau picture` reads it back:
/// the outline's area is the union's (to 2 %, its sampling).
#[test]
fn a_clump_is_drawn_by_its_outline() {
    let (sim, _) = simulation(&disk_and_dimer_on_a_slope(20.0));
    let dir = Scratch::new("clump");
    moreau::io::vtk::write_step(&sim, &dir, 0).unwrap();
    let frame = moreau::io::picture::Frame::read(&dir, 0).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let area = sim.world.bodies.mass[1] / 1000.0;
    let outline = frame.grains[1].outline.as_ref().expect("the clump has an outline");
    assert!(outline.len() > 20 && (frame.grains[1].area() - area).abs() < 0.02 * area, "{}", frame.grains[1].area());
    assert!(frame.grains[0].outline.is_none(), "a disk stays a disk");
}

fn parse_error(text: &str) -> String {
    match scene::parse(text, Path::new("bad.toml")) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

/// A clump whose disks do not make one grain, a disk given as [x, y], or a template asked for
/// with polygon sides: each refused, naming what is wrong and where.
#[test]
fn bad_clumps_are_refused_by_name() {
    let head = "[time]\nstep = 1e-3\nsteps = 1\n[[material]]\nname = \"m\"\ndensity = 1.0\n";
    let e = parse_error(&format!(
        "{head}[[body]]\nclump = {{ center = [0.0, 0.0], disks = [[0.0, 0.0, 1.0], [1.5, 0.0, 1.0], [5.0, 0.0, 1.0]] }}\n"
    ));
    assert!(e.contains("body[0]") && e.contains("clump disk 2") && e.contains("one grain"), "{e}");
    let e = parse_error(&format!("{head}[[body]]\nclump = {{ center = [0.0, 0.0], disks = [[0.0, 0.0]] }}\n"));
    assert!(e.contains("exactly 3 values") && e.contains("[x, y, r]"), "{e}");
    let e = parse_error(&format!(
        "{head}[[generate]]\nkind = \"grid\"\ncount = 4\nradius = [0.1, 0.1]\nregion = {{ min = [0.0, 0.0], max = [1.0, 1.0] }}\n\
         sides = 5\nclump = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]]\n"
    ));
    assert!(e.contains("generate[0].clump") && e.contains("only one of sides, clump and polygon"), "{e}");
    let e = parse_error(&format!(
        "{head}[[generate]]\nkind = \"grid\"\ncount = 4\nradius = [0.1, 0.1]\nregion = {{ min = [0.0, 0.0], max = [1.0, 1.0] }}\n\
         clump = [[0.0, 0.0, -1.0]]\n"
    ));
    assert!(e.contains("generate[0].clump") && e.contains("radius > 0"), "{e}");
}
