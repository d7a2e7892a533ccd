//! One Moreau–Jean θ-step (notes §1, LMGC90's `increment`/`comp_free_vlocy`/`comp_dof`), as
//! [`step`] runs them — [`assemble`] (1–3, also `Simulation::next_problem`), the solve (4),
//! `apply` (5–7):
//! 1. detect at the start of the step every pair that can meet within it (alert widened by each
//!    body's and wall's travel), so each contact keeps the normal it has before any crossing;
//! 2. free velocity v_free = v + h g;
//! 3. local problem u = W r + q, q = B v_free − (wall velocity) + max(0, g̃/h) on the normal row
//!    with g̃ = g + θ h u_n⁻ the gap at the predicted configuration X + θ h V (LMGC90 detects
//!    there; carried linearly here so that a fast pair cannot pass through the surface),
//!    + e u_n⁻ for impacts when restitution is on; cohesion c shifts the cone (r_n ≥ −c);
//! 4. solve it warm-started; 5. v⁺ = v_free + M⁻¹ Bᵀ r, X⁺ = X + h((1−θ) v + θ v⁺);
//! 6. project positions: a contact that the θ-update leaves deeper than it started (a pair
//!    meeting early in the step at θ < 1) is moved back to its surface along M⁻¹ Bᵀ, velocities
//!    unchanged (Acary's combined projection, as in Siconos' `MoreauJeanCombinedProjectionOSI`);
//! 7. with a periodic cell, grains that left it come back through the other side.

use std::time::Instant;

use glam::DVec2;

use super::checks::{check_overlaps, check_state, pressed_share, state_failure, state_is_broken};
use super::projection::{end_of_step_gaps, project_positions, targets, GapSummary};
use super::simulation::{ContactState, Simulation, StepError, StepReport};
use crate::detection::{Antagonist, Configuration, DetectedContact, Detector};
use crate::parallel::{all_finite, filled, for_each_item_pair, map_indices, max_over, parallel, CHUNK};
use crate::problem::colouring::Colouring;
use crate::problem::cone::status_of;
use crate::problem::matrix_free::Dofs;
use crate::problem::{Body, Contact, ContactProblem, Delassus, MatrixFree};
use crate::solvers::StopReason;
use crate::world::{BodyShape, Wall, World};
use rayon::prelude::*;

/// The matrix-free operator of the detected contacts, levers taken at the bodies' positions;
/// with rolling resistance, each contact's rolling radius `R_i R_j / (R_i + R_j)` (`R_i` against
/// a wall), R a disk's radius or a polygon's bounding radius.
fn operator(world: &World, contacts: &[DetectedContact], dofs: Dofs) -> Result<MatrixFree, String> {
    let b = &world.bodies;
    let position = &b.position;
    let bodies = map_indices(b.len(), |k| Body {
        inv_mass: b.inv_mass[k],
        inv_inertia: if dofs.rotation { b.inv_inertia[k] } else { 0.0 },
    });
    let contact = |a: usize| {
        let c = &contacts[a];
        let (j, lever_j) = match c.other {
            Antagonist::Body(j) => (Some(j), (c.point - position[j] - c.image).to_array()),
            Antagonist::Wall(_) => (None, [0.0; 2]),
        };
        Contact { i: c.i, j, normal: c.normal.to_array(), lever_i: (c.point - position[c.i]).to_array(), lever_j }
    };
    let mut op = MatrixFree::from_contacts(bodies, contacts.len(), contact, dofs)?;
    if !b.held.is_empty() {
        op = op.with_held_axes(b.held.clone())?;
    }
    if !world.effects.rolling_resistance {
        return Ok(op);
    }
    let radius = contacts
        .iter()
        .map(|c| {
            let ri = b.radius_of(c.i);
            match c.other {
                Antagonist::Body(j) => ri * b.radius_of(j) / (ri + b.radius_of(j)),
                Antagonist::Wall(_) => ri,
            }
        })
        .collect();
    op.with_rolling(radius)
}

/// How far each body and each wall can move within the step (speed × h, gravity included), so
/// that detection widens the alert distance of exactly the pairs that could close. Open
/// contacts cost nothing in the solution: their gap term keeps them inactive unless they would
/// close within the step. A body the solve sets moving faster (a grain kicked by another) is
/// caught by [`update_bodies`], and the end of the step is detected again.
fn step_reach(world: &World, h: f64) -> (Vec<f64>, Vec<f64>) {
    let b = &world.bodies;
    let fall = world.effects.gravity.map_or(0.0, |g| h * g.length());
    let bodies = map_indices(b.len(), |k| {
        let spin = if b.has_rotation() { b.spin[k].abs() * b.bounding_radius[k] } else { 0.0 };
        h * (b.velocity[k].length() + fall + spin)
    });
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

/// Contacts of the step, detected at the start-of-step configuration: every pair that can come
/// within the alert distance during the step, with its gap, normal and point there.
fn detect(
    detector: &mut Detector,
    world: &World,
    alert: f64,
    (reach, wall_reach): (&[f64], &[f64]),
) -> Vec<DetectedContact> {
    let b = &world.bodies;
    let config = Configuration {
        position: &b.position,
        angle: &b.angle,
        periodic: world.periodic,
        pass_through: world.materials.any_pass_through().then_some(&world.materials),
    };
    let mut detected = detector.detect(b, &config, &world.walls, alert, reach, wall_reach);
    // Pairs of fixed bodies, when there are fixed bodies (detection drops a fixed body's walls):
    // a pass over every contact otherwise for nothing, 7 MB a step on the 40,000-disk pile.
    if b.inv_mass.contains(&0.0) {
        detected.retain(|c| match c.other {
            Antagonist::Body(j) => b.inv_mass[c.i] > 0.0 || b.inv_mass[j] > 0.0,
            Antagonist::Wall(_) => b.inv_mass[c.i] > 0.0,
        });
    }
    detected
}

/// Velocities at the start of the step ([`Dofs::per_body`] entries per body), and free
/// velocities (gravity over the step): both in one pass over the bodies, on threads.
fn free_velocities(world: &World, forces: &[(DVec2, f64)], dofs: Dofs, h: f64) -> (Vec<f64>, Vec<f64>) {
    let s = dofs.per_body();
    let b = &world.bodies;
    let gravity = world.effects.gravity;
    let (mut v_begin, mut v_free) = (filled(s * b.len(), 0.0), filled(s * b.len(), 0.0));
    for_each_item_pair((&mut v_begin, s), (&mut v_free, s), |k, vb, vf| {
        (vb[0], vb[1]) = (b.velocity[k].x, b.velocity[k].y);
        if dofs.rotation {
            vb[2] = b.spin[k];
        }
        vf.copy_from_slice(vb);
        // Along an axis where a body holds its velocity, nothing changes it.
        if let Some(g) = gravity {
            let [mx, my] = b.axis_inv_mass(k);
            if mx > 0.0 {
                vf[0] += h * g.x;
            }
            if my > 0.0 {
                vf[1] += h * g.y;
            }
        }
    });
    // Constant forces of driven bodies (pistons), then a host's forces for this step (see
    // `Simulation::apply_force`).
    for k in b.driven() {
        let [mx, my] = b.axis_inv_mass(k);
        v_free[s * k] += h * mx * b.force[k].x;
        v_free[s * k + 1] += h * my * b.force[k].y;
    }
    for (k, (force, torque)) in forces.iter().enumerate() {
        let [mx, my] = b.axis_inv_mass(k);
        v_free[s * k] += h * mx * force.x;
        v_free[s * k + 1] += h * my * force.y;
        if dofs.rotation {
            v_free[s * k + 2] += h * b.inv_inertia[k] * torque;
        }
    }
    (v_begin, v_free)
}

/// The largest velocity change the step's applied forces give a body, `h max|a|` (g h under
/// gravity): `criterion = step-velocity` holds every contact to `tol` times it.
fn applied_velocity_step(v_begin: &[f64], v_free: &[f64], dofs: Dofs) -> f64 {
    let s = dofs.per_body();
    let change = |k: usize| (v_free[s * k] - v_begin[s * k]).hypot(v_free[s * k + 1] - v_begin[s * k + 1]);
    max_over(v_begin.len() / s, change)
}

/// A contact's antagonist's material, and a moving wall's velocity at the contact point and its
/// spin (zero against a body, or without `moving_walls`).
fn antagonist(world: &World, c: &DetectedContact) -> (usize, DVec2, f64) {
    match c.other {
        Antagonist::Body(j) => (world.bodies.material[j] as usize, DVec2::ZERO, 0.0),
        Antagonist::Wall(w) => {
            let wall = &world.walls[w];
            match world.effects.moving_walls {
                true => (wall.material, wall.velocity_at(c.point), wall.spin),
                false => (wall.material, DVec2::ZERO, 0.0),
            }
        }
    }
}

/// The energy the step's contacts dissipate and the work moving walls and driven bodies do on the
/// grains through them (J): `D = −Σ r·ū` and `W`, where `ū = B v̄ − w` is a contact's relative
/// velocity (normal, tangential, rolling) at the bodies' mean velocity `v̄ = ½(v⁻ + v⁺)` over
/// the step and `w` its wall's motion. `Σ r·B v̄` splits into the power into the velocities the
/// impulses move, `Σ (M Δv)·v̄` (a pass over the bodies), and into those driven or fixed, which
/// with the walls' `Σ r·w` is `W` (a pass over the contacts, made only when something is driven
/// or a wall moves): `D = W − Σ (M Δv)·v̄`. With θ = ½ the step's change of kinetic and
/// gravity's potential energy is that power, `ΔK + ΔP = W − D`, when no other force acts and the
/// position projection moves nothing (`tests/simulation_physics.rs`).
fn contact_energies(
    world: &World,
    op: &MatrixFree,
    contacts: &[DetectedContact],
    r: &[f64],
    (v_begin, v_free, dv): (&[f64], &[f64], &[f64]),
) -> [f64; 2] {
    let mean = |i: usize| 0.5 * (v_begin[i] + v_free[i] + dv[i]);
    let (moved, driven) = op.impulse_power(dv, mean);
    let walls_move =
        world.effects.moving_walls && world.walls.iter().any(|w| w.velocity != DVec2::ZERO || w.spin != 0.0);
    if driven.is_none() && !walls_move {
        return [-moved, 0.0];
    }
    let (nc, rolling, friction) = (contacts.len(), op.has_rolling(), world.effects.friction);
    let work = crate::parallel::chunked_sum(nc, |a| {
        let c = &contacts[a];
        let rr = if rolling { r[2 * nc + a] } else { 0.0 };
        let mut work = 0.0;
        if let Some(v) = &driven {
            // The impulses' power into driven velocities, which their drive takes up.
            let u = op.gather_one(a, v.as_slice());
            work -= r[2 * a] * u[0] + if friction { r[2 * a + 1] * u[1] } else { 0.0 };
            if rolling {
                work -= rr * op.gather_rolling(a, v.as_slice());
            }
        }
        if let (true, Antagonist::Wall(_)) = (walls_move, c.other) {
            let (_, velocity, spin) = antagonist(world, c);
            work += r[2 * a] * c.normal.dot(velocity) + if rolling { rr * op.rolling_radius(a) * spin } else { 0.0 };
            if friction {
                work += r[2 * a + 1] * c.normal.perp().dot(velocity);
            }
        }
        work
    });
    [work - moved, work]
}

/// The step's contact problem, in cohesion-shifted impulses r' = r + c e_n (`shift`, empty
/// without cohesion), and the warm start `r0` moved the same way.
fn local_problem(
    world: &World,
    op: MatrixFree,
    contacts: &[DetectedContact],
    (v_begin, v_free): (&[f64], &[f64]),
    (h, theta): (f64, f64),
    r0: &mut [f64],
) -> Result<(ContactProblem, Vec<f64>), String> {
    let effects = world.effects;
    let nc = contacts.len();
    let unknowns = op.unknowns();
    let antagonist = |c: &DetectedContact| antagonist(world, c);
    let law_with =
        |c: &DetectedContact, other: usize| world.materials.interaction(world.bodies.material[c.i] as usize, other);
    // The (n, t) rows: q = B v_free less the wall's velocity, plus the gap term or the impact,
    // with μ and g̃/h, contacts from `first` on, in one pass (they are memory-bound).
    let rows = |first: usize, q: &mut [f64], mu: &mut [f64], gap_rate: &mut [f64]| {
        for (k, (mu, gap_rate)) in mu.iter_mut().zip(gap_rate).enumerate() {
            let (a, c) = (first + k, &contacts[first + k]);
            let (other, wall_velocity, _) = antagonist(c);
            let law = law_with(c, other);
            let (n, t) = (c.normal, c.normal.perp());
            let u_free = op.gather_one(a, v_free);
            let mut qn = u_free[0] - n.dot(wall_velocity);
            q[2 * k + 1] = u_free[1];
            if effects.friction {
                q[2 * k + 1] -= t.dot(wall_velocity);
                *mu = law.friction;
            }
            // Newton's impact law for a contact that closes within this step, u_n⁺ ≥ −e u_n⁻;
            // otherwise the gap term: an open contact acts only if it would close within the step.
            let approach = op.gather_one(a, v_begin)[0] - n.dot(wall_velocity);
            let predicted_gap = c.gap + theta * h * approach;
            if effects.restitution && law.restitution > 0.0 && approach < 0.0 && c.gap + h * approach <= 0.0 {
                qn += law.restitution * approach;
            } else if predicted_gap > 0.0 {
                *gap_rate = predicted_gap / h;
                qn += *gap_rate;
            }
            q[2 * k] = qn;
        }
    };
    let mut q = filled(unknowns, 0.0);
    let mut mu = filled(nc, 0.0);
    let mut gap_rate = filled(nc, 0.0);
    if parallel(nc) {
        q[..2 * nc]
            .par_chunks_mut(2 * CHUNK)
            .zip(mu.par_chunks_mut(CHUNK))
            .zip(gap_rate.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(chunk, ((q, mu), gap_rate))| rows(chunk * CHUNK, q, mu, gap_rate));
    } else {
        rows(0, &mut q[..2 * nc], &mut mu, &mut gap_rate);
    }
    // Rolling rows, relative to a turning wall: u_r = R (ω_i − ω_wall).
    let mut rolling = if op.has_rolling() { vec![0.0; nc] } else { Vec::new() };
    for (a, eta) in rolling.iter_mut().enumerate() {
        let c = &contacts[a];
        let (other, _, wall_spin) = antagonist(c);
        q[2 * nc + a] = op.gather_rolling(a, v_free) - op.rolling_radius(a) * wall_spin;
        *eta = law_with(c, other).rolling_resistance;
    }
    let mut shift = if effects.cohesion { vec![0.0; unknowns] } else { Vec::new() };
    if effects.cohesion {
        for (a, c) in contacts.iter().enumerate() {
            shift[2 * a] = law_with(c, antagonist(c).0).cohesion;
        }
    }
    // Cohesion: solve for r' = r + c e_n in the plain cone, q' = q − W c e_n.
    if effects.cohesion {
        let mut ws = vec![0.0; unknowns];
        op.apply(&shift, &mut ws);
        for k in 0..unknowns {
            q[k] -= ws[k];
            r0[k] += shift[k];
        }
    }
    let floor = applied_velocity_step(v_begin, v_free, op.dofs());
    let problem = ContactProblem::with_rolling(Delassus::MatrixFree(op), q, mu, rolling)
        .and_then(|p| p.with_gap_rates(gap_rate))
        .and_then(|p| p.with_velocity_floor(floor))
        .map_err(|e| e.to_string())?;
    Ok((problem, shift))
}

/// The state a failed step goes back to.
struct Snapshot {
    position: Vec<DVec2>,
    velocity: Vec<DVec2>,
    angle: Vec<f64>,
    spin: Vec<f64>,
    walls: Vec<Wall>,
}

impl Snapshot {
    fn restore(self, world: &mut World) {
        let b = &mut world.bodies;
        (b.position, b.velocity, b.angle, b.spin) = (self.position, self.velocity, self.angle, self.spin);
        world.walls = self.walls;
    }
}

/// What stage 5 leaves besides the new state.
struct Updated {
    /// The state the step started from: the world's own vectors, moved out rather than copied.
    before: Snapshot,
    /// Whether a body ended the step farther than detection allowed for (its reach plus half the
    /// alert distance): then a pair of bodies may have met unseen within the step.
    outran: bool,
    /// The first body whose new state [`state_is_broken`].
    broken: Option<usize>,
}

/// Stage 5 in one pass over the bodies (on threads): v⁺ = v_free + Δv (`dv` = M⁻¹ Bᵀ r, `None`
/// without contacts) and X⁺ = X + h((1−θ) v + θ v⁺), each body's new state checked as it is made
/// (its reach, with the alert distance `alert`; finite and within the scene's `extent`); the walls
/// advance by h. One pass where a pass each for the copy of the old state, the velocities, the
/// update and the two checks read the bodies five times on one thread (0.7 ms of a step of the
/// 40,000-disk pile).
fn update_bodies(
    world: &mut World,
    (v_free, dv): (&[f64], Option<&[f64]>),
    dofs: Dofs,
    (h, theta): (f64, f64),
    (reach, alert, extent): (&[f64], f64, f64),
) -> Updated {
    let (s, turns) = (dofs.per_body(), dofs.rotation);
    let b = &world.bodies;
    let n = b.len();
    let v_end = |i: usize| dv.map_or(v_free[i], |dv| v_free[i] + dv[i]);
    // Bodies from `first` on: their new state, whether one outran its reach, the first broken.
    let part = |first: usize, position: &mut [DVec2], velocity: &mut [DVec2], angle: &mut [f64], spin: &mut [f64]| {
        let (mut outran, mut broken) = (false, None);
        for (i, (x, v)) in position.iter_mut().zip(velocity).enumerate() {
            let k = first + i;
            *v = DVec2::new(v_end(s * k), v_end(s * k + 1));
            *x = b.position[k] + h * ((1.0 - theta) * b.velocity[k] + theta * *v);
            if turns {
                spin[i] = v_end(s * k + 2);
                angle[i] = b.angle[k] + h * ((1.0 - theta) * b.spin[k] + theta * spin[i]);
            }
            let (angle, spin) = match turns {
                true => (Some(angle[i]), Some(spin[i])),
                false => (b.angle.get(k).copied(), b.spin.get(k).copied()),
            };
            let turn = angle.zip(b.angle.get(k)).map_or(0.0, |(a1, a0)| (a1 - a0).abs() * b.bounding_radius[k]);
            outran |= x.distance(b.position[k]) + turn > reach[k] + 0.5 * alert;
            if broken.is_none() && state_is_broken((*x, *v, angle, spin), b.position[k], extent) {
                broken = Some(k);
            }
        }
        (outran, broken)
    };
    let mut position = filled(n, DVec2::ZERO);
    let mut velocity = filled(n, DVec2::ZERO);
    let (mut angle, mut spin) = match turns {
        true => (filled(n, 0.0), filled(n, 0.0)),
        false => (Vec::new(), Vec::new()),
    };
    let combine = |(o1, b1): (bool, Option<usize>), (o2, b2): (bool, Option<usize>)| (o1 || o2, b1.or(b2));
    let parts = (position.par_chunks_mut(CHUNK)).zip(velocity.par_chunks_mut(CHUNK)).enumerate();
    let (outran, broken) = match (parallel(n), turns) {
        (false, _) => part(0, &mut position, &mut velocity, &mut angle, &mut spin),
        (true, true) => parts
            .zip(angle.par_chunks_mut(CHUNK).zip(spin.par_chunks_mut(CHUNK)))
            .map(|((c, (x, v)), (a, w))| part(c * CHUNK, x, v, a, w))
            .reduce(|| (false, None), combine),
        (true, false) => {
            parts.map(|(c, (x, v))| part(c * CHUNK, x, v, &mut [], &mut [])).reduce(|| (false, None), combine)
        }
    };
    let b = &mut world.bodies;
    let before = Snapshot {
        position: std::mem::replace(&mut b.position, position),
        velocity: std::mem::replace(&mut b.velocity, velocity),
        angle: if turns { std::mem::replace(&mut b.angle, angle) } else { b.angle.clone() },
        spin: if turns { std::mem::replace(&mut b.spin, spin) } else { b.spin.clone() },
        walls: world.walls.clone(),
    };
    world.walls.iter_mut().for_each(|w| w.advance(h));
    Updated { before, outran, broken }
}

/// Did a polygon turn in the step far enough for gaps moved to first order to miss by more than
/// the projection's slack? Its corners move along arcs, and a corner sliding on a turning face
/// follows the face: both second order in the turn. A hexagon spinning at 50 rad/s crept 1.8e-5 m
/// a step into its neighbour, unseen; past a turn of √slack radians the end of the step is
/// detected again and the projection reads the true gaps. Disks and clumps keep first order.
fn polygon_turned(before: &Snapshot, world: &World, slack: f64) -> bool {
    let (b, limit) = (&world.bodies, slack.sqrt());
    !b.polygons.is_empty()
        && (0..b.len()).any(|k| {
            matches!(b.shape[k], BodyShape::Polygon(_))
                && before.angle.get(k).zip(b.angle.get(k)).is_some_and(|(a0, a1)| (a1 - a0).abs() > limit)
        })
}

/// The contact problem of the coming step (stages 1–3), before any body moves.
pub(super) struct Assembled {
    pub detected: Vec<DetectedContact>,
    /// How far each body and wall may move within the step (detection's widening).
    reach: (Vec<f64>, Vec<f64>),
    v_begin: Vec<f64>,
    v_free: Vec<f64>,
    /// `None` without contacts.
    pub problem: Option<ContactProblem>,
    /// The warm start (cohesion-shifted like the problem), and how many contacts it matched.
    pub r0: Vec<f64>,
    warm_started: usize,
    /// The cohesion shift of the impulses (empty without cohesion).
    shift: Vec<f64>,
    detection_seconds: f64,
}

/// Stages 1–3: detection at the start of the step, free velocities, the local problem with its
/// warm start. Moves nothing.
pub(super) fn assemble(sim: &mut Simulation, step: usize) -> Result<Assembled, StepError> {
    let start = Instant::now();
    let (h, theta, alert) = (sim.settings.h, sim.settings.theta, sim.settings.alert);
    let effects = sim.world.effects;
    let dofs = Dofs { rotation: effects.rotation, friction: effects.friction };
    // 1. Detection at the start of the step.
    let reach = step_reach(&sim.world, h);
    let detected = detect(&mut sim.detector, &sim.world, alert, (&reach.0, &reach.1));
    let detection_seconds = start.elapsed().as_secs_f64();
    // 2. Free velocities.
    let (v_begin, v_free) = free_velocities(&sim.world, &sim.forces, dofs, h);
    let mut assembled = Assembled {
        detected,
        reach,
        v_begin,
        v_free,
        problem: None,
        r0: Vec::new(),
        warm_started: 0,
        shift: Vec::new(),
        detection_seconds,
    };
    if assembled.detected.is_empty() {
        return Ok(assembled);
    }
    // 3. The local problem, warm-started from last step's impulses (and colours).
    let world = &sim.world;
    let op = operator(world, &assembled.detected, dofs).map_err(|message| StepError::Problem { step, message })?;
    let recalled = sim.warm_start.recall(&assembled.detected, &op.moving(), op.has_rolling(), h);
    if let Some(incidence) = recalled.incidence {
        op.give_incidence(incidence);
    }
    if let Some(kept) = &recalled.colours {
        op.give_colouring(Colouring::repaired(&op, kept));
    }
    if let Some(table) = recalled.neighbours {
        op.give_neighbours(table);
    }
    if let Some(blocks) = recalled.block_colours {
        op.give_block_colours(blocks);
    }
    let mut r0 = recalled.impulses;
    let velocities = (assembled.v_begin.as_slice(), assembled.v_free.as_slice());
    let (problem, shift) = local_problem(world, op, &assembled.detected, velocities, (h, theta), &mut r0)
        .map_err(|message| StepError::Problem { step, message })?;
    (assembled.problem, assembled.r0, assembled.shift) = (Some(problem), r0, shift);
    assembled.warm_started = recalled.matched;
    Ok(assembled)
}

/// One step: assemble (stages 1–3), solve (4), apply (5–7); a new state that is not finite or
/// runs away is undone.
pub(super) fn step(sim: &mut Simulation) -> Result<StepReport, StepError> {
    let start = Instant::now();
    let step = sim.step_index + 1;
    let assembled = assemble(sim, step)?;
    let solved = match &assembled.problem {
        None => None,
        Some(problem) => {
            // 4. Solve.
            let solve_start = Instant::now();
            let solved = sim
                .backend
                .solve(problem, sim.settings.solver, &sim.settings.options, Some(&assembled.r0))
                .map_err(|e| StepError::Device { step, message: e.to_string() })?;
            Some((solved, solve_start.elapsed().as_secs_f64()))
        }
    };
    let mut report = apply(sim, assembled, solved, step)?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// Stages 5–7 with the solve's answer: velocities and positions, the position projection, the
/// checks of the new state, the warm start and contacts handed to the next step, the periodic
/// wrap.
fn apply(
    sim: &mut Simulation,
    assembled: Assembled,
    solved: Option<(crate::solvers::SolveReport, f64)>,
    step: usize,
) -> Result<StepReport, StepError> {
    let (h, theta, alert) = (sim.settings.h, sim.settings.theta, sim.settings.alert);
    let effects = sim.world.effects;
    let dofs = Dofs { rotation: effects.rotation, friction: effects.friction };
    let extent = sim.extent();
    let Assembled { detected, reach, v_begin, v_free, problem, shift, mut detection_seconds, .. } = assembled;
    let mut report = StepReport {
        step,
        time: sim.time + h,
        contacts: detected.len(),
        warm_started: assembled.warm_started,
        iterations: 0,
        gpu_iterations: 0,
        error: 0.0,
        converged: true,
        stop: StopReason::Converged,
        stop_reason: "no contact".into(),
        gpu_dispatches: 0,
        gpu_bytes: 0,
        missed: 0,
        projected: 0,
        max_penetration: 0.0,
        kinetic_energy: 0.0,
        potential_energy: 0.0,
        dissipated_energy: 0.0,
        boundary_work: 0.0,
        seconds: 0.0,
        detection_seconds,
        solve_seconds: 0.0,
        projection_seconds: 0.0,
        gpu_checks: Default::default(),
        velocity_scale: 0.0,
    };
    let mut dv = None;
    let mut impulses = Vec::new();
    if let (Some(local), Some((solved, seconds))) = (&problem, solved) {
        report.solve_seconds = seconds;
        report.velocity_scale = crate::solvers::stopping::velocity_scale(local, sim.settings.options.criterion);
        report.iterations = solved.iterations;
        report.gpu_iterations = solved.gpu_iterations();
        report.error = solved.judged_error;
        report.converged = solved.converged;
        report.stop = solved.stop;
        (report.gpu_dispatches, report.gpu_bytes) = (solved.gpu_dispatches, solved.gpu_bytes);
        report.gpu_checks = solved.gpu_checks;
        report.stop_reason = solved.stop_reason.clone();
        impulses = solved.r;
        // The solve's last product's `M⁻¹ Bᵀ r`, when it was of these impulses (unshifted).
        let kept = solved.body_velocity.filter(|_| shift.is_empty());
        if !all_finite(&impulses) {
            return Err(StepError::Diverged {
                step,
                message: format!("the {} solve returned non-finite impulses", sim.settings.solver.name()),
            });
        }
        for (r, c) in impulses.iter_mut().zip(&shift) {
            *r -= c;
        }
        let Delassus::MatrixFree(op) = &local.w else { unreachable!("the step builds a matrix-free problem") };
        let dv = dv.insert(kept.unwrap_or_else(|| op.body_velocities(&impulses)));
        [report.dissipated_energy, report.boundary_work] =
            contact_energies(&sim.world, op, &detected, &impulses, (&v_begin, &v_free, dv));
    }

    // 5. Update, then 6. projection of what the θ-update pushed in: on the start's contacts
    // moved to first order, or, when a grain was kicked beyond its reach or a polygon turned
    // past what first order sees, on the contacts detected at the end of the step (those the
    // start missed must not overlap at all).
    let checks = (reach.0.as_slice(), alert, extent);
    let Updated { before, outran, broken } =
        update_bodies(&mut sim.world, (&v_free, dv.as_deref()), dofs, (h, theta), checks);
    let mut projected = 0;
    let projection_start = Instant::now();
    let mut crushed = None;
    if let Some(problem) = &problem {
        let Delassus::MatrixFree(op) = &problem.w else { unreachable!("the step builds a matrix-free problem") };
        let (end, end_op);
        let detect_again = outran || polygon_turned(&before, &sim.world, sim.settings.projection_slack);
        // What the projection has to do, the deepest overlap and the deepest pressed pair are read
        // as the end gaps are made; again only when the projection moved bodies.
        let slack = sim.settings.projection_slack;
        let shares = (slack, pressed_share(slack));
        let (op, contacts, mut gaps, target, summary) = if detect_again {
            let again = Instant::now();
            end = detect(&mut sim.detector, &sim.world, alert, (&[], &[]));
            detection_seconds += again.elapsed().as_secs_f64();
            let (target, missed) = targets(&end, &detected);
            report.missed = missed;
            end_op = operator(&sim.world, &end, dofs).map_err(|message| StepError::Problem { step, message })?;
            let gaps: Vec<f64> = end.iter().map(|c| c.gap).collect();
            let summary = GapSummary::of(&end, (&gaps, &target), shares, &sim.world.bodies);
            (&end_op, end.as_slice(), gaps, target, summary)
        } else {
            let start = (before.walls.as_slice(), before.position.as_slice(), before.angle.as_slice());
            let (gaps, target, summary) = end_of_step_gaps(op, &detected, start, (&sim.world, h), shares);
            (op, detected.as_slice(), gaps, target, summary)
        };
        let traffic;
        (projected, traffic) = project_positions(
            &mut sim.world,
            &sim.backend,
            op,
            contacts,
            &mut gaps,
            &target,
            slack,
            report.iterations,
            &summary,
        );
        let summary = match projected {
            0 => summary,
            _ => GapSummary::of(contacts, (&gaps, &target), shares, &sim.world.bodies),
        };
        report.projected = projected;
        report.add_gpu_traffic(traffic);
        report.max_penetration = summary.max_penetration;
        crushed = check_overlaps(contacts, summary.deepest_pressed, &sim.world).err();
        // Less the detection at the end of the step, which counts as detection.
        report.projection_seconds =
            projection_start.elapsed().as_secs_f64() - (detection_seconds - report.detection_seconds);
    }
    // The bodies' new state as the update checked it, again where the projection moved them.
    let broken = match projected {
        0 => broken.map(|k| state_failure(&before.position, &sim.world, extent, k)),
        _ => check_state(&before.position, &sim.world, extent).err(),
    };
    if let Some(message) = crushed.or(broken) {
        before.restore(&mut sim.world);
        return Err(StepError::Diverged { step, message });
    }
    // 7. Grains that left the periodic cell come back through the other side; the step's
    // contacts move with their grains, so that points and images stay beside them.
    let moved = sim.world.wrap_positions();
    let op = problem.as_ref().and_then(|p| match &p.w {
        Delassus::MatrixFree(op) => Some(op),
        Delassus::Sparse(_) => None,
    });
    sim.warm_start.remember(&detected, &impulses, op, sim.settings.h);
    sim.contacts = match &problem {
        None => Vec::new(),
        Some(problem) => map_indices(detected.len(), |a| {
            let c = &detected[a];
            let imp = [impulses[2 * a], impulses[2 * a + 1]];
            let shifted = [imp[0] + shift.get(2 * a).copied().unwrap_or(0.0), imp[1]];
            let mut contact = *c;
            if let Some(&dx) = moved.get(c.i) {
                let dj = match c.other {
                    Antagonist::Body(j) => moved[j],
                    Antagonist::Wall(_) => dx,
                };
                contact.point.x += dx;
                contact.image.x += dx - dj;
            }
            ContactState { contact, impulse: imp, status: status_of(shifted, problem.mu[a]) }
        }),
    };
    if sim.keep_problem {
        sim.last_problem = problem;
    }
    sim.forces.clear();
    sim.time += h;
    sim.step_index = step;
    report.detection_seconds = detection_seconds;
    report.kinetic_energy = sim.world.kinetic_energy();
    report.potential_energy = sim.world.potential_energy();
    Ok(report)
}
