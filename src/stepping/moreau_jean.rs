//! One Moreau–Jean θ-step (notes §1, LMGC90's `increment`/`comp_free_vlocy`/`comp_dof`):
//! 1. predict X̃ = X + θ h V and detect contacts there (gap g, frame, alert distance);
//! 2. free velocity v_free = v + h g;
//! 3. local problem u = W r + q, q = B v_free − (wall velocity) + max(0, g/h) on the normal row,
//!    + e u_n⁻ for impacts when restitution is on; cohesion c shifts the cone (r_n ≥ −c);
//! 4. solve it warm-started; 5. v⁺ = v_free + M⁻¹ Bᵀ r, X⁺ = X + h((1−θ) v + θ v⁺).

use std::time::Instant;

use glam::DVec2;

use super::simulation::{ContactState, Simulation, StepError, StepReport};
use crate::detection::{Antagonist, Configuration, DetectedContact};
use crate::problem::cone::status_of;
use crate::problem::matrix_free::Dofs;
use crate::problem::{Body, Contact, ContactProblem, Delassus, MatrixFree};

use crate::world::World;

/// Generalised velocity vector ([`Dofs::per_body`] entries per body) of the bodies' velocities.
fn stacked_velocities(world: &World, dofs: Dofs) -> Vec<f64> {
    let b = &world.bodies;
    let s = dofs.per_body();
    let mut v = vec![0.0; s * b.len()];
    for k in 0..b.len() {
        v[s * k] = b.velocity[k].x;
        v[s * k + 1] = b.velocity[k].y;
        if dofs.rotation {
            v[s * k + 2] = b.spin[k];
        }
    }
    v
}

/// The matrix-free operator of the detected contacts.
fn operator(
    world: &World,
    predicted: &[DVec2],
    contacts: &[DetectedContact],
    dofs: Dofs,
) -> Result<MatrixFree, String> {
    let b = &world.bodies;
    let bodies: Vec<Body> = (0..b.len())
        .map(|k| Body { inv_mass: b.inv_mass[k], inv_inertia: if dofs.rotation { b.inv_inertia[k] } else { 0.0 } })
        .collect();
    let rows: Vec<Contact> = contacts
        .iter()
        .map(|c| {
            let (j, lever_j) = match c.other {
                Antagonist::Body(j) => (Some(j), (c.point - predicted[j]).to_array()),
                Antagonist::Wall(_) => (None, [0.0; 2]),
            };
            Contact { i: c.i, j, normal: c.normal.to_array(), lever_i: (c.point - predicted[c.i]).to_array(), lever_j }
        })
        .collect();
    MatrixFree::with_dofs(bodies, &rows, dofs)
}

/// How far each body and each wall can move within the step (speed × h), so that detection
/// widens the alert distance of exactly the pairs that could close. Open contacts cost nothing
/// in the solution: their gap term keeps them inactive unless they would close within the step.
fn step_reach(world: &World, h: f64) -> (Vec<f64>, Vec<f64>) {
    let b = &world.bodies;
    let bodies = (0..b.len())
        .map(|k| {
            let spin = if b.has_rotation() { b.spin[k].abs() * b.bounding_radius[k] } else { 0.0 };
            h * (b.velocity[k].length() + spin)
        })
        .collect();
    let walls = world
        .walls
        .iter()
        .map(|w| {
            h * (w.velocity.length()
                + w.spin.abs() * w.world_points().iter().map(|p| p.distance(w.center)).fold(0.0, f64::max))
        })
        .collect();
    (bodies, walls)
}

/// Largest overlap at the end of the step, from the detection gaps moved to first order by the
/// displacement since the predicted configuration (`B ΔX`, less the walls' own motion).
fn end_of_step_penetration(
    world: &World,
    op: &MatrixFree,
    predicted: &[DVec2],
    predicted_angle: &[f64],
    contacts: &[DetectedContact],
    predicted_walls: &[crate::world::Wall],
    wall_time_left: f64,
) -> f64 {
    let b = &world.bodies;
    let s = op.dofs().per_body();
    let mut dx = vec![0.0; s * b.len()];
    for k in 0..b.len() {
        let d = b.position[k] - predicted[k];
        dx[s * k] = d.x;
        dx[s * k + 1] = d.y;
        if s == 3 {
            dx[s * k + 2] = b.angle[k] - predicted_angle[k];
        }
    }
    let mut dg = vec![0.0; 2 * contacts.len()];
    op.contact_velocities(&dx, &mut dg);
    let mut worst = 0.0f64;
    for (a, c) in contacts.iter().enumerate() {
        let mut gap = c.gap + dg[2 * a];
        if let Antagonist::Wall(w) = c.other {
            gap -= c.normal.dot(wall_time_left * predicted_walls[w].velocity_at(c.point));
        }
        worst = worst.max(-gap);
    }
    worst
}

pub(super) fn step(sim: &mut Simulation) -> Result<StepReport, StepError> {
    let start = Instant::now();
    let (h, theta) = (sim.settings.h, sim.settings.theta);
    let step = sim.step_index + 1;
    let world = &mut sim.world;
    let effects = world.effects;
    let dofs = Dofs { rotation: effects.rotation, friction: effects.friction };

    // 1. Predicted configuration and detection.
    let b = &world.bodies;
    let predicted: Vec<DVec2> = (0..b.len()).map(|k| b.position[k] + theta * h * b.velocity[k]).collect();
    let predicted_angle: Vec<f64> =
        if effects.rotation { (0..b.len()).map(|k| b.angle[k] + theta * h * b.spin[k]).collect() } else { Vec::new() };
    let mut walls = world.walls.clone();
    walls.iter_mut().for_each(|w| w.advance(theta * h));
    let config = Configuration { position: &predicted, angle: &predicted_angle };
    let (reach, wall_reach) = step_reach(world, h);
    let mut detected = sim.detector.detect(b, &config, &walls, sim.settings.alert, &reach, &wall_reach);
    detected.retain(|c| match c.other {
        Antagonist::Body(j) => b.inv_mass[c.i] > 0.0 || b.inv_mass[j] > 0.0,
        Antagonist::Wall(_) => b.inv_mass[c.i] > 0.0,
    });
    let detection_seconds = start.elapsed().as_secs_f64();

    // 2. Free velocity.
    let v_begin = stacked_velocities(world, dofs);
    let mut v_free = v_begin.clone();
    if let Some(g) = effects.gravity {
        let s = dofs.per_body();
        for k in 0..world.bodies.len() {
            if world.bodies.inv_mass[k] > 0.0 {
                v_free[s * k] += h * g.x;
                v_free[s * k + 1] += h * g.y;
            }
        }
    }

    let nc = detected.len();
    let mut report = StepReport {
        step,
        time: sim.time + h,
        contacts: nc,
        warm_started: 0,
        iterations: 0,
        error: 0.0,
        converged: true,
        stop: crate::solvers::StopReason::Converged,
        stop_reason: "no contact".into(),
        gpu_dispatches: 0,
        gpu_bytes: 0,
        max_penetration: 0.0,
        kinetic_energy: 0.0,
        potential_energy: 0.0,
        seconds: 0.0,
        detection_seconds,
        solve_seconds: 0.0,
    };
    let mut v_end = v_free.clone();
    let mut step_problem = None;
    if nc > 0 {
        // 3. The local problem.
        let op =
            operator(world, &predicted, &detected, dofs).map_err(|message| StepError::Problem { step, message })?;
        let mut q = vec![0.0; 2 * nc];
        op.contact_velocities(&v_free, &mut q);
        let mut u_begin = Vec::new();
        if effects.restitution {
            u_begin = vec![0.0; 2 * nc];
            op.contact_velocities(&v_begin, &mut u_begin);
        }
        let mats = &world.materials;
        let mut mu = vec![0.0; nc];
        let mut shift = Vec::new();
        if effects.cohesion {
            shift = vec![0.0; 2 * nc];
        }
        for (a, c) in detected.iter().enumerate() {
            let (other_material, wall_velocity) = match c.other {
                Antagonist::Body(j) => (world.bodies.material[j] as usize, DVec2::ZERO),
                Antagonist::Wall(w) => {
                    (walls[w].material, if effects.moving_walls { walls[w].velocity_at(c.point) } else { DVec2::ZERO })
                }
            };
            let law = mats.interaction(world.bodies.material[c.i] as usize, other_material);
            let (n, t) = (c.normal, c.normal.perp());
            q[2 * a] -= n.dot(wall_velocity);
            if effects.friction {
                q[2 * a + 1] -= t.dot(wall_velocity);
                mu[a] = law.friction;
            }
            // Newton's impact law for a contact that closes within this step, u_n⁺ ≥ −e u_n⁻;
            // otherwise the gap term: an open contact acts only if it would close within the step.
            let approach =
                if effects.restitution && law.restitution > 0.0 { u_begin[2 * a] - n.dot(wall_velocity) } else { 0.0 };
            if approach < 0.0 && c.gap + h * approach <= 0.0 {
                q[2 * a] += law.restitution * approach;
            } else if c.gap > 0.0 {
                q[2 * a] += c.gap / h;
            }
            if effects.cohesion {
                shift[2 * a] = law.cohesion;
            }
        }
        let (mut r0, warm) = sim.warm_start.initial_impulses(&detected);
        report.warm_started = warm;
        // Cohesion: solve for r' = r + c e_n in the plain cone, q' = q − W c e_n.
        if effects.cohesion {
            let mut ws = vec![0.0; 2 * nc];
            op.apply(&shift, &mut ws);
            for k in 0..2 * nc {
                q[k] -= ws[k];
                r0[k] += shift[k];
            }
        }
        let problem = ContactProblem::new(Delassus::MatrixFree(op), q, mu)
            .map_err(|e| StepError::Problem { step, message: e.to_string() })?;
        // 4. Solve.
        let solve_start = Instant::now();
        let solved = sim
            .backend
            .solve(&problem, sim.settings.solver, &sim.settings.options, Some(&r0))
            .map_err(|e| StepError::Device { step, message: e.to_string() })?;
        report.solve_seconds = solve_start.elapsed().as_secs_f64();
        report.iterations = solved.iterations;
        report.error = solved.error;
        report.converged = solved.converged;
        report.stop = solved.stop;
        (report.gpu_dispatches, report.gpu_bytes) = (solved.gpu_dispatches, solved.gpu_bytes);
        report.stop_reason = solved.stop_reason.clone();
        let mut r = solved.r;
        if r.iter().any(|x| !x.is_finite()) {
            return Err(StepError::Diverged {
                step,
                message: format!("the {} solve returned non-finite impulses", sim.settings.solver.name()),
            });
        }
        if effects.cohesion {
            for k in 0..2 * nc {
                r[k] -= shift[k];
            }
        }
        sim.warm_start.remember(&detected, &r);
        // 5. Velocity update.
        let Delassus::MatrixFree(op) = &problem.w else { unreachable!("the step builds a matrix-free problem") };
        let dv = op.body_velocities(&r);
        for (v, d) in v_end.iter_mut().zip(&dv) {
            *v += d;
        }
        let mu = &problem.mu;
        sim.contacts = detected
            .iter()
            .enumerate()
            .map(|(a, c)| {
                let imp = [r[2 * a], r[2 * a + 1]];
                let shifted = [imp[0] + if effects.cohesion { shift[2 * a] } else { 0.0 }, imp[1]];
                ContactState { contact: *c, impulse: imp, status: status_of(shifted, mu[a]) }
            })
            .collect();
        step_problem = Some(problem);
    } else {
        sim.warm_start.remember(&[], &[]);
        sim.contacts.clear();
    }

    // Position update.
    let s = dofs.per_body();
    let world = &mut sim.world;
    let bodies = &mut world.bodies;
    for k in 0..bodies.len() {
        let v_new = DVec2::new(v_end[s * k], v_end[s * k + 1]);
        if !v_new.is_finite() {
            return Err(StepError::Diverged { step, message: format!("body {k} has a non-finite velocity") });
        }
        bodies.position[k] += h * ((1.0 - theta) * bodies.velocity[k] + theta * v_new);
        bodies.velocity[k] = v_new;
        if dofs.rotation {
            let w_new = v_end[s * k + 2];
            bodies.angle[k] += h * ((1.0 - theta) * bodies.spin[k] + theta * w_new);
            bodies.spin[k] = w_new;
        }
    }
    world.walls.iter_mut().for_each(|w| w.advance(h));
    if let Some(problem) = step_problem {
        let Delassus::MatrixFree(op) = &problem.w else { unreachable!("the step builds a matrix-free problem") };
        report.max_penetration =
            end_of_step_penetration(world, op, &predicted, &predicted_angle, &detected, &walls, h * (1.0 - theta));
        if sim.keep_problem {
            sim.last_problem = Some(problem);
        }
    }
    sim.time += h;
    sim.step_index = step;
    report.kinetic_energy = world.kinetic_energy();
    report.potential_energy = world.potential_energy();
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}
