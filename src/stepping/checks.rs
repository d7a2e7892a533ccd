//! What a world must satisfy to be stepped, and what every step's new state must satisfy:
//! scenes that cannot be integrated are refused up front, suspicious starts are warned about,
//! and a step whose state is not finite, runs away or leaves grains crushed into each other is
//! undone and reported.

use glam::DVec2;

use crate::detection::{Antagonist, Configuration, DetectedContact, Detector};
use crate::world::World;

/// f64 positions must resolve this fraction of the smallest grain radius.
const RESOLUTION: f64 = 1e-6;

/// A body that moves farther than this many scene extents in one step has run away.
const RUNAWAY: f64 = 1e3;

/// Diagonal of the bounds of bodies and walls, at least the largest grain's diameter.
pub fn extent(world: &World) -> f64 {
    if world.bodies.is_empty() && world.walls.is_empty() {
        return 0.0;
    }
    let (lo, hi) = world.bounds();
    let largest = world.bodies.bounding_radius.iter().fold(0.0f64, |m, r| m.max(2.0 * r));
    (hi - lo).length().max(largest)
}

/// Refuses a world that cannot be stepped with time step `h` (say why, naming the body);
/// returns warnings about its start (grains outside the walls, in a wall, on top of each other).
pub fn check_start(world: &World, h: f64) -> Result<Vec<String>, String> {
    let b = &world.bodies;
    let dynamic = || (0..b.len()).filter(|&k| b.inv_mass[k] > 0.0);
    // Gaps are differences of positions: f64 must resolve a small fraction of a grain there.
    let far = (0..b.len())
        .map(|k| b.position[k].abs().max_element() + b.bounding_radius[k])
        .chain(world.walls.iter().flat_map(|w| w.world_points()).map(|p| p.abs().max_element()))
        .fold(0.0, f64::max);
    if let Some(smallest) = b.bounding_radius.iter().copied().reduce(f64::min) {
        if far * f64::EPSILON > RESOLUTION * smallest {
            return Err(format!(
                "coordinates reach {far:.3e} m, where f64 resolves {:.1e} m, more than {RESOLUTION:e} of the smallest \
                 grain radius ({smallest:.3e} m): move the scene nearer the origin or scale it",
                far * f64::EPSILON
            ));
        }
    }
    for k in dynamic() {
        let energy = 0.5 * b.mass[k] * b.velocity[k].length_squared();
        if !energy.is_finite() {
            return Err(format!(
                "body {k}: its kinetic energy overflows f64 (mass {:e}, velocity {:?})",
                b.mass[k],
                b.velocity[k].to_array()
            ));
        }
    }
    let mut warnings = Vec::new();
    let size = extent(world);
    let gravity = world.effects.gravity.map_or(0.0, |g| g.length());
    let travel = |k: usize| h * b.velocity[k].length() + h * h * gravity;
    if let Some(k) = dynamic().max_by(|&i, &j| travel(i).total_cmp(&travel(j))) {
        if travel(k) > size {
            let what = format!(
                "in one step (h = {h:e} s) body {k} moves {:.3e} m, farther than across the whole scene ({size:.3e} m)",
                travel(k)
            );
            if !world.walls.is_empty() {
                return Err(format!("{what}: the walls cannot hold it; take a smaller time step"));
            }
            warnings.push(format!("{what}: take a smaller time step unless it is a free flight"));
        }
    }
    warnings.extend(start_overlaps(world));
    Ok(warnings)
}

/// The share of a radius (the smaller one of a pair) beyond which an overlap a grain starts with,
/// with another grain or with a wall, is warned about (the warnings say "1 %").
const START_OVERLAP: f64 = 1e-2;

/// Grains outside the walls' bounds, overlapping a wall, or on top of another grain at the start.
fn start_overlaps(world: &World) -> Vec<String> {
    let b = &world.bodies;
    let mut warnings = Vec::new();
    if !world.walls.is_empty() {
        let (mut lo, mut hi) = world
            .walls
            .iter()
            .map(|w| w.aabb())
            .fold((DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)), |(lo, hi), (a, c)| {
                (lo.min(a), hi.max(c))
            });
        // Walls hold grains against gravity: above a floor, or over an open top, is inside.
        if let Some(g) = world.effects.gravity {
            let up = -g.normalize_or_zero();
            let open = |u: f64, lo: &mut f64, hi: &mut f64| {
                if u > 0.5 {
                    *hi = f64::INFINITY;
                } else if u < -0.5 {
                    *lo = f64::NEG_INFINITY;
                }
            };
            open(up.x, &mut lo.x, &mut hi.x);
            open(up.y, &mut lo.y, &mut hi.y);
        }
        let outside: Vec<usize> = (0..b.len())
            .filter(|&k| b.inv_mass[k] > 0.0)
            .filter(|&k| {
                let p = b.position[k];
                p.x < lo.x || p.y < lo.y || p.x > hi.x || p.y > hi.y
            })
            .collect();
        if let Some(&k) = outside.first() {
            warnings.push(format!(
                "{} grain(s) start outside the walls' bounds, below or beside them (first: body {k} at {:?})",
                outside.len(),
                b.position[k].to_array()
            ));
        }
    }
    let config = Configuration {
        position: &b.position,
        angle: &b.angle,
        periodic: world.periodic,
        pass_through: world.materials.any_pass_through().then_some(&world.materials),
    };
    let contacts = Detector::default().detect(b, &config, &world.walls, 0.0, &[], &[]);
    let (mut in_wall, mut coincident, mut overlapping) = (Vec::new(), Vec::new(), Vec::new());
    for c in &contacts {
        match c.other {
            Antagonist::Wall(w) if -c.gap > START_OVERLAP * b.bounding_radius[c.i] => in_wall.push((c.i, w, -c.gap)),
            Antagonist::Body(j) if b.position[c.i].distance(b.position[j]) <= 1e-9 * b.bounding_radius[c.i] => {
                coincident.push((c.i, j))
            }
            // Moreau–Jean keeps overlaps it starts with (it stops approach, it does not push apart).
            Antagonist::Body(j) if -c.gap > START_OVERLAP * b.bounding_radius[c.i].min(b.bounding_radius[j]) => {
                overlapping.push((c.i, j, -c.gap))
            }
            _ => {}
        }
    }
    if let Some(&(i, j, depth)) = overlapping.iter().max_by(|a, b| a.2.total_cmp(&b.2)) {
        warnings.push(format!(
            "{} pair(s) of bodies start overlapping by more than 1 % of the smaller radius (deepest: bodies {i} and {j}, \
             {depth:.3e} m); the overlaps stay",
            overlapping.len()
        ));
    }
    if let Some(&(k, w, depth)) = in_wall.iter().max_by(|a, b| a.2.total_cmp(&b.2)) {
        // A grain may touch several walls: count grains, not grain–wall pairs.
        let mut grains: Vec<usize> = in_wall.iter().map(|p| p.0).collect();
        grains.sort_unstable();
        grains.dedup();
        warnings.push(format!(
            "{} grain(s) start overlapping a wall by more than 1 % of their radius (deepest: body {k} in wall {w}, \
             {depth:.3e} m); the overlaps stay (a grain may still slide, roll or leave; one whose centre is past a \
             wall's line is taken to be on its far side)",
            grains.len()
        ));
    }
    if let Some(&(i, j)) = coincident.first() {
        warnings.push(format!(
            "{} pair(s) of grains start at the same position (first: bodies {i} and {j}); their contact normal is arbitrary",
            coincident.len()
        ));
    }
    warnings
}

/// An overlap deeper than this share of the smaller body's bounding radius, left after a step's
/// position projection, is no rounding or loose solve: the contact problem had no answer.
pub const CRUSH: f64 = 0.5;

/// `, or it is squeezed …` when some wall or fixed body moves by prescription: a grain caught
/// between two such motions has no finite impulse to hold it.
fn squeeze_hint(world: &World) -> &'static str {
    let b = &world.bodies;
    let prescribed = |j: usize| {
        let [mx, my] = b.axis_inv_mass(j);
        (mx == 0.0 && b.velocity[j].x != 0.0) || (my == 0.0 && b.velocity[j].y != 0.0)
    };
    let driven = (0..b.len()).any(|j| prescribed(j) || (b.inv_mass[j] == 0.0 && b.spin_of(j) != 0.0))
        || world.walls.iter().any(|w| w.is_moving());
    if driven {
        ", or it is squeezed between walls or fixed bodies whose motion is prescribed, which no contact force can stop"
    } else {
        ""
    }
}

/// The share of a pair's size (the smaller bounding radius) by which a pair must end below its
/// target for [`check_overlaps`] to judge it: the projection's `slack`, at least 1e-3.
pub fn pressed_share(slack: f64) -> f64 {
    slack.max(1e-3)
}

/// The deepest pair left overlapping by more than [`CRUSH`] after a step that the position
/// projection could not bring back to its target (its overlap at the start of the step, within
/// [`pressed_share`] of its size), in words: a grain that started inside a wall stays there and
/// is only warned about, but one pressed deeper step after step is caught. `deepest` is that pair
/// (index, overlap / size) as [`GapSummary`](super::projection::GapSummary) finds it. Exact
/// antiparallel constraints (a grain pushed into a wall by a driven body) make the problem
/// infeasible: the impulses grow without bound and cancel, the grain stays, and the driven body
/// passes through it.
pub fn check_overlaps(
    contacts: &[DetectedContact],
    deepest: Option<(usize, f64)>,
    world: &World,
) -> Result<(), String> {
    match deepest.map(|(a, depth)| (&contacts[a], depth)) {
        Some((c, depth)) if depth > CRUSH => {
            let other = match c.other {
                Antagonist::Body(j) => format!("body {j}"),
                Antagonist::Wall(w) => format!("wall {w}"),
            };
            Err(format!(
                "body {} and {other} overlap by {:.0} % of the smaller one's radius, pressed deeper than the step's \
                 projection could undo: its contact problem had no answer; the time step is too large for the forces{}",
                c.i,
                100.0 * depth,
                squeeze_hint(world)
            ))
        }
        _ => Ok(()),
    }
}

/// The first body whose state after a step is not finite or ran away (moved farther than
/// [`RUNAWAY`] scene extents within the step), in words.
pub fn check_state(start: &[DVec2], world: &World, extent: f64) -> Result<(), String> {
    let broken = |k: usize| state_is_broken(state_of(world, k), start[k], extent);
    match (0..start.len()).find(|&k| broken(k)) {
        Some(k) => Err(state_failure(start, world, extent, k)),
        None => Ok(()),
    }
}

/// A body's state: position, velocity, and angle and spin when it turns.
pub type BodyState = (DVec2, DVec2, Option<f64>, Option<f64>);

fn state_of(world: &World, k: usize) -> BodyState {
    let b = &world.bodies;
    (b.position[k], b.velocity[k], b.angle.get(k).copied(), b.spin.get(k).copied())
}

fn is_finite((position, velocity, angle, spin): BodyState) -> bool {
    position.is_finite() && velocity.is_finite() && angle.is_none_or(f64::is_finite) && spin.is_none_or(f64::is_finite)
}

/// Whether a body's new state is not finite, or it moved farther than [`RUNAWAY`] scene extents
/// from where it started the step (`from`).
pub fn state_is_broken(state: BodyState, from: DVec2, extent: f64) -> bool {
    !is_finite(state) || state.0.distance(from) > RUNAWAY * extent
}

/// [`check_state`]'s words for body `k`, whose state [`state_is_broken`].
pub fn state_failure(start: &[DVec2], world: &World, extent: f64, k: usize) -> String {
    let b = &world.bodies;
    if !is_finite(state_of(world, k)) {
        return format!(
            "body {k} is no longer finite (position {:?}, velocity {:?})",
            b.position[k].to_array(),
            b.velocity[k].to_array()
        );
    }
    let moved = b.position[k].distance(start[k]);
    format!(
        "body {k} ran away: it moved {moved:.3e} m in one step, more than {RUNAWAY:e} times the scene's extent \
         ({extent:.3e} m); the time step is too large for the forces{}",
        squeeze_hint(world)
    )
}
