//! Fast impacts at every phase of a step: a grain that meets an obstacle anywhere within one
//! step's travel never ends a step below its surface by more than 1e-3 of its size, at θ = 1/2
//! and θ = 1, at 50 and 500 m/s, against a segment, a solid box, a resting disk and a moving
//! wall, for a disk and for a square. The penetration is measured on the exact geometry of the
//! state after each step, not on the solver's linearised gaps.

use std::path::Path;

use moreau::stepping::Simulation;

const RADIUS: f64 = 0.005;
const H: f64 = 2e-3;
const FLOOR_SPEED: f64 = 2.0;

#[derive(Clone, Copy, Debug)]
enum Obstacle {
    Segment,
    SolidBox,
    RestingDisk,
    MovingWall,
}

#[derive(Clone, Copy, Debug)]
enum Grain {
    Disk,
    Square,
}

fn scene(obstacle: Obstacle, grain: Grain, theta: f64, speed: f64, phase: f64) -> String {
    let moving = matches!(obstacle, Obstacle::MovingWall);
    let mut s = format!(
        "effects = [\"gravity\", \"friction\", \"rotation\"{}]\n[time]\nstep = {H}\nsteps = 25\ntheta = {theta}\n\
         [solver]\ntol = 1e-8\nmax_iter = 2000\n[contact]\nfriction = 0.3\n\
         [[material]]\nname = \"g\"\ndensity = 2500.0\n",
        if moving { ", \"moving_walls\"" } else { "" }
    );
    s.push_str(match obstacle {
        Obstacle::Segment | Obstacle::RestingDisk => "[[wall]]\nsegment = [[-1.0, 0.0], [1.0, 0.0]]\n",
        Obstacle::SolidBox => "[[wall]]\nbox = { min = [-1.0, -0.5], max = [1.0, 0.0] }\n",
        Obstacle::MovingWall => "[[wall]]\nsegment = [[-1.0, 0.0], [1.0, 0.0]]\nvelocity = [0.0, 2.0]\n",
    });
    // The grain's lowest point starts `phase` of one step's closing travel above the surface.
    let closing = speed + if moving { FLOOR_SPEED } else { 0.0 };
    let mut surface = 0.0;
    if matches!(obstacle, Obstacle::RestingDisk) {
        s.push_str(&format!("[[body]]\ndisk = {{ center = [0.0, {RADIUS}] , radius = {RADIUS} }}\n"));
        surface = 2.0 * RADIUS;
    }
    let bottom = surface + phase * closing * H;
    match grain {
        Grain::Disk => {
            s.push_str(&format!("[[body]]\ndisk = {{ center = [0.0, {}], radius = {RADIUS} }}\n", bottom + RADIUS))
        }
        Grain::Square => s.push_str(&format!(
            "[[body]]\nregular = {{ center = [0.0, {}], radius = {RADIUS}, sides = 4, angle = 0.7853981633974483 }}\n",
            bottom + RADIUS / 2f64.sqrt()
        )),
    }
    s.push_str(&format!("velocity = [0.0, {}]\n", -speed));
    s
}

/// Depth of the last body below whatever it falls on, from the exact geometry.
fn penetration(sim: &Simulation, obstacle: Obstacle) -> f64 {
    let b = &sim.world.bodies;
    let last = b.len() - 1;
    let lowest = |k: usize| match b.world_vertices(k).iter().map(|v| v.y).reduce(f64::min) {
        Some(y) => y,
        None => b.position[k].y - b.radius_of(k),
    };
    let floor_y = if matches!(obstacle, Obstacle::MovingWall) { FLOOR_SPEED * sim.time() } else { 0.0 };
    let mut depth = (floor_y - lowest(last)).max(0.0);
    if matches!(obstacle, Obstacle::RestingDisk) {
        depth = depth.max(floor_y - lowest(0));
        if b.world_vertices(last).is_empty() {
            depth = depth.max(2.0 * RADIUS - b.position[0].distance(b.position[last]));
        }
    }
    depth
}

fn worst_penetration(obstacle: Obstacle, grain: Grain, theta: f64, speed: f64, phase: f64) -> f64 {
    let text = scene(obstacle, grain, theta, speed, phase);
    let s = moreau::scene::parse(&text, Path::new("impact")).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let steps = s.steps;
    let mut sim = Simulation::new(s.world, s.settings).unwrap();
    let mut worst = 0.0f64;
    for _ in 0..steps {
        let report = sim.step().unwrap_or_else(|e| panic!("{obstacle:?} {grain:?} θ {theta} {speed} m/s: {e}"));
        // A square landing flat is hyperstatic: NLGS may cycle near tol, which the report says.
        assert!(report.error.is_finite() && report.kinetic_energy.is_finite(), "{obstacle:?} {grain:?}: {report:?}");
        worst = worst.max(penetration(&sim, obstacle));
    }
    // The grain stays on the obstacle's side: it never passes through.
    let b = &sim.world.bodies;
    assert!(
        b.position[b.len() - 1].y > 0.0,
        "{obstacle:?} {grain:?} θ {theta} {speed} m/s phase {phase}: went through"
    );
    worst
}

const PHASES: [f64; 9] = [0.02, 0.1, 0.3, 0.49, 0.51, 0.7, 0.9, 0.99, 1.4];

fn check(obstacle: Obstacle, grain: Grain) {
    let mut failures = Vec::new();
    for theta in [0.5, 1.0] {
        for speed in [50.0, 500.0] {
            for phase in PHASES {
                let depth = worst_penetration(obstacle, grain, theta, speed, phase);
                if depth > 1e-3 * 2.0 * RADIUS {
                    failures.push(format!(
                        "θ {theta} {speed} m/s phase {phase}: {:.2e} of a diameter",
                        depth / (2.0 * RADIUS)
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{obstacle:?} {grain:?} ends below the surface:\n{}", failures.join("\n"));
}

#[test]
fn a_fast_disk_never_ends_a_step_inside_a_segment() {
    check(Obstacle::Segment, Grain::Disk);
}

#[test]
fn a_fast_disk_never_ends_a_step_inside_a_solid_box() {
    check(Obstacle::SolidBox, Grain::Disk);
}

#[test]
fn a_fast_disk_never_ends_a_step_inside_a_resting_disk() {
    check(Obstacle::RestingDisk, Grain::Disk);
}

#[test]
fn a_fast_disk_never_ends_a_step_inside_a_wall_moving_towards_it() {
    check(Obstacle::MovingWall, Grain::Disk);
}

#[test]
fn a_fast_square_never_ends_a_step_inside_a_segment_or_a_box() {
    check(Obstacle::Segment, Grain::Square);
    check(Obstacle::SolidBox, Grain::Square);
}
