//! Driving moreau from a host code, step by step: build a world, add bodies and walls, step,
//! read positions and contact impulses, change the world between steps.
//!
//! Run with `cargo run --release --example embed`.

use glam::DVec2;
use moreau::solvers::{SolverKind, SolverOptions};
use moreau::stepping::{Simulation, StepSettings, DEFAULT_PROJECTION_SLACK};
use moreau::world::{BodySpec, Effects, Interaction, Materials, Wall, World};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Effects are off unless switched on: here gravity, friction and rotation.
    let effects =
        Effects { gravity: Some(DVec2::new(0.0, -9.81)), friction: true, rotation: true, ..Effects::default() };
    // One material (density 2500) whose pairs all have μ = 0.5.
    let materials =
        Materials::new(vec!["grain".into()], vec![2500.0], Interaction { friction: 0.5, ..Interaction::default() });
    let settings = StepSettings {
        h: 1e-3,
        theta: 0.5,
        alert: 1e-4,
        projection_slack: DEFAULT_PROJECTION_SLACK,
        solver: SolverKind::Nlgs,
        options: SolverOptions { tol: 1e-6, max_iter: 5000, ..SolverOptions::default() },
    };
    let mut sim = Simulation::new(World::new(effects, materials), settings)?;
    sim.add_wall(Wall::segment(DVec2::new(-0.1, 0.0), DVec2::new(0.1, 0.0), 0))?;
    // Three disks in a column.
    for k in 0..3 {
        sim.add_body(&BodySpec::disk(DVec2::new(0.0, 0.01 + 0.02 * k as f64), 0.01, 0))?;
    }
    for step in 1..=500 {
        let report = sim.step()?;
        if !report.converged {
            eprintln!("step {step}: not converged ({})", report.stop_reason);
        }
        // The host may add a body between steps: a square dropped on the column at step 200.
        if step == 200 {
            let square = vec![
                DVec2::new(-0.01, -0.01),
                DVec2::new(0.01, -0.01),
                DVec2::new(0.01, 0.01),
                DVec2::new(-0.01, 0.01),
            ];
            sim.add_body(&BodySpec::polygon(DVec2::new(0.0, 0.1), square, 0))?;
        }
    }
    for k in 0..sim.world.bodies.len() {
        println!("body {k}: position {:?}, velocity {:?}", sim.position(k).to_array(), sim.velocity(k).to_array());
    }
    for c in sim.contacts() {
        println!(
            "contact {} – {:?}: gap {:+.2e}, impulse (n, t) = ({:.3e}, {:.3e}), {:?}",
            c.contact.i, c.contact.other, c.contact.gap, c.impulse[0], c.impulse[1], c.status
        );
    }
    Ok(())
}
