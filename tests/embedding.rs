//! The Rust API a host code uses (issue: embedding): step settings from the world, a scene loaded
//! into a simulation, per-body accessors, impulses and forces, and typed errors that name the
//! problem instead of panicking.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

use std::path::Path;

#[path = "common/said_scene.rs"]
mod said_scene;

use moreau::world::Interaction;
use moreau::{BodyError, BodySpec, DVec2, Effects, Materials, Simulation, StepSettings, Wall, World};

/// One disk (radius 0.1, density 1000) on a floor, friction μ, with or without gravity/rotation.
fn disk_on_floor(mu: f64, gravity: bool, rotation: bool) -> Simulation {
    let law = Interaction { friction: mu, ..Interaction::default() };
    let effects = Effects {
        gravity: gravity.then_some(DVec2::new(0.0, -9.81)),
        friction: mu > 0.0,
        rotation,
        ..Effects::default()
    };
    let mut world = World::new(effects, Materials::new(vec!["steel".into()], vec![1000.0], law));
    world.walls.push(Wall::segment(DVec2::new(-5.0, 0.0), DVec2::new(5.0, 0.0), 0));
    world.bodies.add(&BodySpec::disk(DVec2::new(0.0, 0.1), 0.1, 0), 1000.0).unwrap();
    let settings = StepSettings::for_world(&world, 1e-3);
    Simulation::new(world, settings).unwrap()
}

#[test]
fn a_scene_file_loads_into_the_simulation_the_command_line_steps() {
    let path = Path::new("scenes/pile.toml");
    let mut from_scene = Simulation::from_scene(path).unwrap();
    let s = moreau::scene::load(path).unwrap();
    let mut by_hand = Simulation::new(s.world, s.settings).unwrap();
    for _ in 0..5 {
        from_scene.step().unwrap();
        by_hand.step().unwrap();
    }
    let bits =
        |sim: &Simulation| sim.positions().iter().flat_map(|p| [p.x.to_bits(), p.y.to_bits()]).collect::<Vec<_>>();
    assert_eq!(bits(&from_scene), bits(&by_hand));
    let Err(e) = Simulation::from_scene(Path::new("scenes/no_such_scene.toml")) else {
        panic!("a missing file loaded")
    };
    let e = e.to_string();
    assert!(e.contains("no_such_scene.toml"), "{e}");
}

/// A host loading a scene gets what `moreau check` prints: the file's warnings first in
/// `check()`'s, then the start's, and its notes.
#[test]
fn a_loaded_scene_keeps_its_files_warnings_and_notes_for_the_host() {
    let dir = Scratch::new("embedding_said");
    let scene = said_scene::write_said_scene(&dir);
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let notes = sim.notes().to_vec();
    let warnings = sim.check().unwrap().to_vec();
    assert!(notes.len() == 1 && notes[0].contains("800 grains") && notes[0].contains("numbered in rows"), "{notes:?}");
    assert!(warnings.len() == 2, "{warnings:?}");
    assert!(warnings[0].contains("spins") && warnings[1].contains("overlapping a wall"), "{warnings:?}");
    // A simulation built from the scene's world by hand has the start's warning alone.
    let s = moreau::scene::load(&scene).unwrap();
    let mut by_hand = Simulation::new(s.world, s.settings).unwrap();
    assert_eq!(by_hand.check().unwrap(), &warnings[1..]);
    assert!(by_hand.notes().is_empty());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn default_step_settings_take_the_alert_distance_from_the_grains() {
    let sim = disk_on_floor(0.3, true, false);
    assert_eq!(sim.settings.alert, moreau::stepping::DEFAULT_ALERT_FRACTION * 0.1);
    assert_eq!((sim.settings.theta, sim.settings.options.tol), (0.5, 1e-4));
}

#[test]
fn a_force_acts_for_one_step_and_the_contacts_answer_it() {
    // Free flight: one step of force F changes the velocity by h F / m, the next step nothing.
    let mut sim = disk_on_floor(0.0, false, false);
    sim.set_velocity(0, DVec2::new(0.0, 1.0)).unwrap();
    let m = 1000.0 * std::f64::consts::PI * 0.01;
    sim.apply_force(0, DVec2::new(2.0, 0.0), 0.0).unwrap();
    sim.apply_force(0, DVec2::new(1.0, 0.0), 0.0).unwrap();
    sim.step().unwrap();
    assert!((sim.velocity(0).x - 1e-3 * 3.0 / m).abs() < 1e-12, "{}", sim.velocity(0).x);
    let v = sim.velocity(0);
    sim.step().unwrap();
    assert_eq!(sim.velocity(0), v, "the force lasted more than one step");
    // On the floor with μ = 0.5, a push below μ m g is held by friction within the step, one
    // above it slides the disk at (F − μ m g) / m.
    for (push, expected) in [(0.4, 0.0), (0.8, (0.8 - 0.5) * 9.81)] {
        let mut sim = disk_on_floor(0.5, true, false);
        for _ in 0..20 {
            sim.step().unwrap();
        }
        let v0 = sim.velocity(0).x;
        for _ in 0..100 {
            sim.apply_force(0, DVec2::new(push * m * 9.81, 0.0), 0.0).unwrap();
            let r = sim.step().unwrap();
            assert!(r.converged, "{}", r.stop_reason);
        }
        let a = (sim.velocity(0).x - v0) / 0.1;
        assert!((a - expected).abs() <= 1e-2 * 9.81, "push {push} m g: a = {a}, expected {expected}");
    }
}

#[test]
fn an_impulse_off_centre_spins_the_body() {
    let mut sim = disk_on_floor(0.0, false, true);
    let (m, inertia) = (1000.0 * std::f64::consts::PI * 0.01, 0.5 * 1000.0 * std::f64::consts::PI * 0.01 * 0.01);
    // 1 N·s along x at the top of the disk: v = 1/m, ω = (0.1 ŷ × x̂) / I = −0.1 / I.
    sim.apply_impulse(0, DVec2::new(1.0, 0.0), DVec2::new(0.0, 0.2)).unwrap();
    assert!((sim.velocity(0).x - 1.0 / m).abs() < 1e-12);
    assert!((sim.spin(0) + 0.1 / inertia).abs() < 1e-9, "spin {}", sim.spin(0));
    sim.set_spin(0, 2.0).unwrap();
    sim.step().unwrap();
    assert!((sim.angle(0) - 2e-3).abs() < 1e-12, "angle {}", sim.angle(0));
}

#[test]
fn bad_requests_are_named_errors_never_panics() {
    let mut sim = disk_on_floor(0.3, true, false);
    assert_eq!(sim.set_velocity(7, DVec2::ZERO), Err(BodyError::NoBody { body: 7, count: 1 }));
    assert!(matches!(sim.set_velocity(0, DVec2::new(f64::NAN, 0.0)), Err(BodyError::NotFinite { body: 0, .. })));
    assert!(matches!(sim.apply_force(0, DVec2::new(0.0, f64::INFINITY), 0.0), Err(BodyError::NotFinite { .. })));
    assert_eq!(sim.set_spin(0, 1.0), Err(BodyError::NoRotation(0)));
    assert_eq!(sim.material("glass"), Err(BodyError::NoMaterialNamed("glass".into())));
    assert_eq!(sim.add_body(&BodySpec::disk(DVec2::ZERO, 0.1, 3)), Err(BodyError::NoMaterial(3)));
    let e = sim.add_body(&BodySpec::disk(DVec2::new(0.0, 1.0), -0.1, 0)).unwrap_err();
    assert!(e.to_string().contains("radius"), "{e}");
    let fixed = BodySpec { fixed: true, ..BodySpec::disk(DVec2::new(1.0, 1.0), 0.1, 0) };
    let k = sim.add_body(&fixed).unwrap();
    assert_eq!(sim.apply_impulse(k, DVec2::X, DVec2::ZERO), Err(BodyError::Fixed(k)));
    let moving = Wall { velocity: DVec2::X, ..Wall::segment(DVec2::ZERO, DVec2::X, 0) };
    let e = sim.add_wall(moving).unwrap_err();
    assert!(matches!(e, BodyError::World(moreau::world::WorldError::Wall { index: 1, .. })), "{e:?}");
    assert!(e.to_string().contains("needs the effect moving_walls"), "{e}");
    let e = sim.add_wall(Wall::segment(DVec2::X, DVec2::X, 0)).unwrap_err();
    assert!(e.to_string().contains("segment endpoints must be finite and distinct"), "{e}");
    assert_eq!(sim.world.walls.len(), 1, "a refused wall is not added");
    assert_eq!(sim.set_wall_motion(1, DVec2::X, 0.0), Err(BodyError::NoWall { wall: 1, count: 1 }));
    let e = sim.set_wall_motion(0, DVec2::ZERO, 1.0).unwrap_err();
    assert!(e.to_string().contains("wall 0: a wall with a velocity or a spin needs the effect moving_walls"), "{e}");
    assert!(!sim.world.walls[0].is_moving(), "a refused motion is not set");
    let e: moreau::Error = BodyError::Fixed(k).into();
    assert!(e.to_string().contains("is fixed"), "{e}");
}

#[test]
fn a_solver_set_on_a_loaded_scene_is_checked_as_a_new_simulations_and_refused_ones_change_nothing() {
    use moreau::solvers::{Ordering, StopCriterion};
    use moreau::SolverKind;
    let mut sim = Simulation::from_scene(Path::new("scenes/column_collapse_rolling.toml")).unwrap();
    let before = format!("{:?}", sim.settings);
    let cpg = sim.set_solver(SolverKind::Cpg, sim.settings.options.clone()).unwrap_err();
    assert!(cpg.to_string().contains("rolling resistance is solved by nlgs only, not cpg"), "{cpg}");
    let zero = moreau::SolverOptions { max_iter: 0, ..sim.settings.options.clone() };
    let e = sim.set_solver(SolverKind::Nlgs, zero).unwrap_err();
    assert!(e.to_string().contains("max_iter 0"), "{e}");
    assert_eq!(format!("{:?}", sim.settings), before);
    // The scene's own work list and velocity test, replaced by forward sweeps and the natural map.
    let scene = (sim.settings.options.ordering, sim.settings.options.criterion);
    assert_eq!(scene, (Ordering::Worklist, StopCriterion::Velocity));
    let sweeps = moreau::SolverOptions {
        ordering: Ordering::Forward,
        criterion: StopCriterion::Natural,
        ..sim.settings.options.clone()
    };
    sim.set_solver(SolverKind::Nlgs, sweeps).unwrap();
    assert_eq!(
        (sim.settings.options.ordering, sim.settings.options.criterion),
        (Ordering::Forward, StopCriterion::Natural)
    );
}

#[test]
fn removing_a_body_renumbers_the_rest_and_keeps_their_warm_start() {
    // A column of three disks at rest on the floor; the middle one is taken out.
    let mut sim = disk_on_floor(0.3, true, true);
    for k in 1..3 {
        sim.add_body(&BodySpec::disk(DVec2::new(0.0, 0.1 + 0.2 * k as f64), 0.1, 0)).unwrap();
    }
    for _ in 0..200 {
        assert!(sim.step().unwrap().converged);
    }
    assert_eq!(sim.contacts().len(), 3);
    sim.apply_force(2, DVec2::new(0.0, -1.0), 0.0).unwrap();
    sim.remove_body(1).unwrap();
    assert_eq!(sim.body_count(), 2);
    assert!((sim.position(1).y - 0.5).abs() < 1e-3, "the top disk is now body 1");
    // The floor contact of body 0 is kept with its impulse; the two involving body 1 are gone.
    let kept = sim.contacts();
    assert_eq!(kept.len(), 1);
    assert!(matches!(kept[0].contact.other, moreau::detection::Antagonist::Wall(0)) && kept[0].contact.i == 0);
    let report = sim.step().unwrap();
    assert_eq!(report.warm_started, 1, "the floor contact carries its impulse");
    // The top disk falls the gap of one diameter and comes to rest on the bottom one.
    for _ in 0..600 {
        assert!(sim.step().unwrap().converged);
    }
    assert!((sim.position(1).y - 0.3).abs() < 1e-3 && sim.velocity(1).length() < 1e-2, "{}", sim.position(1));
    assert_eq!(sim.remove_body(2), Err(BodyError::NoBody { body: 2, count: 2 }));
}

/// Two disks between walls on the floor and one on top, no friction: the top disk rests on the two
/// lower ones along ±60°, the lower ones are pushed apart and lean on the walls, so the contacts
/// between grains that carry a force are the two at ±60°: F = diag(1/4, 3/4), anisotropy 1.
#[test]
fn a_frictionless_pyramid_has_the_fabric_of_its_two_sixty_degree_contacts() {
    let r = 0.1;
    let mut sim = disk_on_floor(0.0, true, false);
    sim.world.bodies.position[0].x = -r;
    for (a, b) in [((-2.0 * r, 0.0), (-2.0 * r, 1.0)), ((2.0 * r, 0.0), (2.0 * r, 1.0))] {
        sim.add_wall(Wall::segment(DVec2::new(a.0, a.1), DVec2::new(b.0, b.1), 0)).unwrap();
    }
    sim.add_body(&BodySpec::disk(DVec2::new(r, r), r, 0)).unwrap();
    sim.add_body(&BodySpec::disk(DVec2::new(0.0, r + 3f64.sqrt() * r), r, 0)).unwrap();
    sim.settings.options.tol = 1e-10;
    for _ in 0..50 {
        assert!(sim.step().unwrap().converged);
    }
    let m = sim.measures();
    let close = |x: f64, y: f64| (x - y).abs() < 1e-6;
    assert!(close(m.fabric_xx, 0.25) && close(m.fabric_yy, 0.75) && close(m.fabric_xy, 0.0), "{m:?}");
    assert!(close(m.anisotropy, 1.0), "{m:?}");
    // Without contacts between grains (one grain left) the fabric is zero, not undefined.
    sim.remove_body(2).unwrap();
    sim.remove_body(1).unwrap();
    sim.step().unwrap();
    assert_eq!((sim.measures().fabric_xx, sim.measures().anisotropy), (0.0, 0.0));
}

#[test]
fn a_resting_column_has_the_packing_coordination_and_stress_of_statics() {
    // k disks (radius r, mass m) stacked in a box of width W on a floor at y = 0: the floor
    // carries k m g, the contact above disk i (k − i) m g; Σ ℓ ⊗ f gives σyy A = m g r k²
    // with A = W · 2 r k, so σyy = k m g / (2 W); φ = k π r² / (2 r k W) = π r / (2 W).
    let (k, r, width) = (3usize, 0.1, 1.0);
    let mut sim = disk_on_floor(0.0, true, false);
    sim.add_wall(Wall::segment(DVec2::new(-0.5, 0.0), DVec2::new(-0.5, 1.0), 0)).unwrap();
    sim.add_wall(Wall::segment(DVec2::new(0.5, 0.0), DVec2::new(0.5, 1.0), 0)).unwrap();
    sim.world.walls[0] = Wall::segment(DVec2::new(-0.5, 0.0), DVec2::new(0.5, 0.0), 0);
    for i in 1..k {
        sim.add_body(&BodySpec::disk(DVec2::new(0.0, r + 2.0 * r * i as f64), r, 0)).unwrap();
    }
    sim.settings.options.tol = 1e-10;
    for _ in 0..50 {
        assert!(sim.step().unwrap().converged);
    }
    let m = sim.measures();
    let mass = 1000.0 * std::f64::consts::PI * r * r;
    let sigma = k as f64 * mass * 9.81 / (2.0 * width);
    assert!((m.stress_yy - sigma).abs() < 1e-6 * sigma, "σyy {} vs {sigma}", m.stress_yy);
    assert!(m.stress_xx.abs() < 1e-9 * sigma && m.stress_xy.abs() < 1e-9 * sigma, "{m:?}");
    let phi = std::f64::consts::PI * r / (2.0 * width);
    assert!((m.packing_fraction - phi).abs() < 1e-6, "φ {} vs {phi}", m.packing_fraction);
    // Bottom and middle disks carry two contacts each; the top one, one: a rattler.
    assert_eq!((m.coordination, m.neighbours, m.rattlers), (2.0, 2.0, 1), "{m:?}");
    // The grains touch along the vertical only: one direction, the largest anisotropy.
    assert_eq!((m.fabric_xx, m.fabric_yy, m.fabric_xy, m.anisotropy), (0.0, 1.0, 0.0, 2.0), "{m:?}");
    // The floor carries the column's weight; the side walls nothing.
    let loads = sim.wall_loads();
    let weight = k as f64 * mass * 9.81;
    assert!((loads[0].force[1] + weight).abs() < 1e-6 * weight && loads[0].force[0].abs() < 1e-9 * weight, "{loads:?}");
    assert!(loads[0].moment.abs() < 1e-9 * weight && loads[1..].iter().all(|l| l.force == [0.0, 0.0]), "{loads:?}");
}

#[test]
fn the_next_steps_problem_is_the_one_the_step_then_solves() {
    let mut sim = Simulation::from_scene(Path::new("scenes/pile.toml")).unwrap();
    sim.keep_problems(true);
    for _ in 0..30 {
        sim.step().unwrap();
    }
    let positions = sim.positions().to_vec();
    let (problem, r0) = sim.next_problem().unwrap().expect("the pile has contacts");
    assert_eq!(sim.positions(), positions.as_slice(), "assembling moves nothing");
    assert_eq!(sim.steps_done(), 30);
    // Solved by the host with the step's solver and warm start: the step's own answer.
    let options = sim.settings.options.clone();
    let mine = moreau::solve(&problem, sim.settings.solver, &options, Some(&r0));
    let report = sim.step().unwrap();
    let stepped = sim.last_problem().unwrap();
    let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&problem.q), bits(&stepped.q));
    assert_eq!(bits(&problem.mu), bits(&stepped.mu));
    assert_eq!((mine.iterations, mine.error.to_bits()), (report.iterations, report.error.to_bits()));
    let impulses: Vec<f64> = sim.contacts().iter().flat_map(|c| c.impulse).collect();
    assert_eq!(bits(&mine.r), bits(&impulses));
}

#[test]
fn a_fixed_body_is_driven_by_its_velocity_and_spin_and_a_locked_one_has_no_spin_to_set() {
    let mut sim = disk_on_floor(0.3, true, true);
    let paddle = BodySpec { fixed: true, ..BodySpec::disk(DVec2::new(1.0, 1.0), 0.1, 0) };
    let paddle = sim.add_body(&paddle).unwrap();
    let piston = BodySpec { lock_rotation: true, ..BodySpec::disk(DVec2::new(-1.0, 1.0), 0.1, 0) };
    let piston = sim.add_body(&piston).unwrap();
    sim.set_velocity(paddle, DVec2::new(0.0, 2.0)).unwrap();
    sim.set_spin(paddle, 3.0).unwrap();
    let e = sim.set_spin(piston, 1.0).unwrap_err();
    assert!(e.to_string().contains("keeps its angle (lock_rotation)"), "{e}");
    assert_eq!(sim.apply_force(paddle, DVec2::X, 0.0), Err(BodyError::Fixed(paddle)));
    for _ in 0..100 {
        sim.step().unwrap();
    }
    let h = sim.settings.h;
    assert!((sim.position(paddle).y - (1.0 + 200.0 * h)).abs() < 1e-12, "{}", sim.position(paddle));
    assert!((sim.angle(paddle) - 300.0 * h).abs() < 1e-12 && sim.angle(piston) == 0.0);
}
