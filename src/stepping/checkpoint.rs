//! What a simulation needs to go on later exactly as it would have: the moving state of bodies
//! and walls, the time, and what one step hands to the next (impulses for the warm start and the
//! colours of the contact graph). Shapes, masses, materials and settings come from the scene
//! again; a checkpoint names the scene it came from, so it is not applied to another.

use serde::{Deserialize, Serialize};

use super::warm_start::{Key, WarmStart};
use super::{Simulation, StepError};
use crate::backend::Backend;
use crate::detection::Antagonist;

/// The state of a [`Simulation`] between two steps (serialisable: `io::checkpoint` writes it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// Format version, for readers of old files.
    pub format: u32,
    /// The scene's name and a fingerprint of its file (`io::checkpoint::fingerprint`), set by
    /// whoever knows the file.
    pub scene: String,
    /// See [`Self::scene`].
    pub scene_fingerprint: String,
    /// Steps done when it was taken.
    pub steps_done: usize,
    /// Simulated time then (s).
    pub time: f64,
    /// Body positions.
    pub position: Vec<[f64; 2]>,
    /// Body velocities.
    pub velocity: Vec<[f64; 2]>,
    /// Empty without the effect rotation.
    pub angle: Vec<f64>,
    /// Body spins (empty without rotation).
    pub spin: Vec<f64>,
    /// Each wall's motion state.
    pub walls: Vec<WallState>,
    /// Last step's contacts, sorted by key, with impulse and colour.
    pub contacts: Vec<CarriedContact>,
    /// Which bodies could move when the colours were given (absent: no colours).
    pub moving: Option<Vec<bool>>,
    /// The GPU's paused mixing then: solves still to sweep plain, and the pause's length
    /// (`backend`'s `MixingPause`; zeros on the CPU and in files written before it).
    #[serde(default)]
    pub mixing_pause: [usize; 2],
    /// The world's [`crate::world::World::shapes_fingerprint`] then: restored only onto the same shapes
    /// (absent in files written before it, which are not checked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shapes: Option<String>,
    /// The step the contacts' impulses were taken over: restored at another step, they are
    /// scaled to it (absent in files written before it, or when no step was taken).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_step: Option<f64>,
}

/// The checkpoint format this version writes and reads.
pub const CHECKPOINT_FORMAT: u32 = 1;

/// A wall's motion state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WallState {
    /// Centre of the wall frame.
    pub center: [f64; 2],
    /// Orientation.
    pub angle: f64,
    /// Velocity.
    pub velocity: [f64; 2],
    /// Spin.
    pub spin: f64,
}

/// One contact carried to the next step: body, antagonist (`other_body` or `other_wall`),
/// feature, impulse and, when last step's solve coloured the graph, colour.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CarriedContact {
    /// The candidate body.
    pub body: usize,
    /// The antagonist, when a body.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub other_body: Option<usize>,
    /// The antagonist, when a wall.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub other_wall: Option<usize>,
    /// Which feature pair of the two shapes (detection's key).
    pub feature: u64,
    /// Normal and tangential impulse.
    pub impulse: [f64; 2],
    /// The rolling impulse (rolling resistance; absent when zero).
    #[serde(skip_serializing_if = "is_zero", default)]
    pub rolling: f64,
    /// The colour last step's solve gave it.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub colour: Option<u32>,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl CarriedContact {
    fn key(&self) -> Result<Key, String> {
        let other = match (self.other_body, self.other_wall) {
            (Some(j), None) => Antagonist::Body(j),
            (None, Some(w)) => Antagonist::Wall(w),
            _ => return Err(format!("contact of body {}: give exactly one of other_body, other_wall", self.body)),
        };
        Ok((self.body, other, self.feature))
    }
}

impl Simulation {
    /// The state to go on from later (the scene fields are left empty for the caller).
    pub fn checkpoint(&self) -> Checkpoint {
        let b = &self.world.bodies;
        let (entries, colours) = (self.warm_start.entries(), self.warm_start.colours());
        let contacts = entries
            .iter()
            .enumerate()
            .map(|(e, &((body, other, feature), [rn, rt, rolling]))| CarriedContact {
                body,
                other_body: if let Antagonist::Body(j) = other { Some(j) } else { None },
                other_wall: if let Antagonist::Wall(w) = other { Some(w) } else { None },
                feature,
                impulse: [rn, rt],
                rolling,
                colour: colours.map(|(of_entry, _)| of_entry[e]),
            })
            .collect();
        Checkpoint {
            format: CHECKPOINT_FORMAT,
            scene: String::new(),
            scene_fingerprint: String::new(),
            steps_done: self.step_index,
            time: self.time,
            position: b.position.iter().map(|p| p.to_array()).collect(),
            velocity: b.velocity.iter().map(|v| v.to_array()).collect(),
            angle: b.angle.clone(),
            spin: b.spin.clone(),
            walls: self
                .world
                .walls
                .iter()
                .map(|w| WallState {
                    center: w.center.to_array(),
                    angle: w.angle,
                    velocity: w.velocity.to_array(),
                    spin: w.spin,
                })
                .collect(),
            contacts,
            moving: colours.map(|(_, moving)| moving.to_vec()),
            mixing_pause: self.backend.mixing_pause(),
            shapes: Some(self.world.shapes_fingerprint()),
            time_step: Some(self.warm_start.time_step()).filter(|&h| h > 0.0),
        }
    }

    /// Goes on from `c`: the next step is the one after `c.steps_done`, exactly as it would
    /// have been in the run that wrote it (same solver, thread count and device). The world
    /// must be the one it came from (same bodies and walls, in order); sizes and values are
    /// checked, and nothing changes when the checkpoint is refused.
    pub fn restore(&mut self, c: &Checkpoint) -> Result<(), StepError> {
        let refused = |m: String| StepError::Settings(format!("checkpoint: {m}"));
        let refuse = |m: String| Err(refused(m));
        let (n, walls) = (self.world.bodies.len(), self.world.walls.len());
        if c.format != CHECKPOINT_FORMAT {
            return refuse(format!("format {} is not {CHECKPOINT_FORMAT}", c.format));
        }
        let rotation = if self.world.bodies.has_rotation() { n } else { 0 };
        let sizes = [
            ("position", c.position.len(), n),
            ("velocity", c.velocity.len(), n),
            ("angle", c.angle.len(), rotation),
            ("spin", c.spin.len(), rotation),
            ("walls", c.walls.len(), walls),
        ];
        if let Some((what, got, expected)) = sizes.into_iter().find(|s| s.1 != s.2) {
            return refuse(format!("{what} has {got} entries, the scene {expected}"));
        }
        if let Some(written) = &c.shapes {
            let now = self.world.shapes_fingerprint();
            if *written != now {
                return refuse(format!(
                    "it was taken of bodies and walls with other shapes, materials or fixings (fingerprint \
                     {written}; this world's {now}): the scene's generator or grains file now gives other \
                     grains, or bodies were added or removed since"
                ));
            }
        }
        let finite = c.time.is_finite()
            && c.position.iter().chain(&c.velocity).flatten().all(|x| x.is_finite())
            && c.angle.iter().chain(&c.spin).all(|x| x.is_finite())
            && c.walls
                .iter()
                .all(|w| w.center.iter().chain(&w.velocity).chain([&w.angle, &w.spin]).all(|x| x.is_finite()));
        if !finite {
            return refuse("a value is not finite".into());
        }
        if c.time < 0.0 {
            return refuse(format!("time {} is negative", c.time));
        }
        if let Some(h) = c.time_step.filter(|h| !(h.is_finite() && *h > 0.0)) {
            return refuse(format!("time_step {h} must be finite and > 0"));
        }
        let keys = c.contacts.iter().map(CarriedContact::key).collect::<Result<Vec<_>, _>>().map_err(refused)?;
        if let Some(bad) = keys.iter().find(|k| {
            k.0 >= n || matches!(k.1, Antagonist::Body(j) if j >= n) || matches!(k.1, Antagonist::Wall(w) if w >= walls)
        }) {
            return refuse(format!("a contact names body {} or {:?}, which the scene lacks", bad.0, bad.1));
        }
        if !keys.windows(2).all(|w| w[0] <= w[1]) {
            return refuse("contacts are not sorted by (body, antagonist, feature)".into());
        }
        let colours = match (&c.moving, c.contacts.iter().map(|x| x.colour).collect::<Option<Vec<u32>>>()) {
            (Some(moving), Some(of_entry)) if moving.len() == n => Some((of_entry, moving.clone())),
            (None, _) => None,
            _ => return refuse("colours need one per contact and a moving mask of one per body".into()),
        };
        if let Some((of_entry, moving)) = &colours {
            if let Some(why) = improper_colour(&keys, of_entry, moving) {
                return refuse(why);
            }
        }
        if let Err(why) = Backend::check_mixing_pause(c.mixing_pause) {
            return refuse(why);
        }
        let entries =
            keys.into_iter().zip(c.contacts.iter().map(|x| [x.impulse[0], x.impulse[1], x.rolling])).collect();
        let b = &mut self.world.bodies;
        b.position = c.position.iter().map(|&p| p.into()).collect();
        b.velocity = c.velocity.iter().map(|&v| v.into()).collect();
        b.angle = c.angle.clone();
        b.spin = c.spin.clone();
        for (wall, s) in self.world.walls.iter_mut().zip(&c.walls) {
            (wall.center, wall.angle, wall.velocity, wall.spin) = (s.center.into(), s.angle, s.velocity.into(), s.spin);
        }
        self.warm_start = WarmStart::from_parts(entries, colours, c.time_step.unwrap_or(0.0));
        // Checked above, before anything was changed.
        let _ = self.backend.set_mixing_pause(c.mixing_pause);
        (self.time, self.step_index) = (c.time, c.steps_done);
        self.contacts.clear();
        self.forces.clear();
        self.last_problem = None;
        self.extent = None;
        Ok(())
    }
}

/// Why `colour` (one per contact) is not a proper colouring of `keys` for the bodies that move:
/// a colour past the number of contacts, or two contacts of one colour on one moving body.
fn improper_colour(keys: &[Key], colour: &[u32], moving: &[bool]) -> Option<String> {
    if let Some(c) = colour.iter().find(|&&c| c as usize >= colour.len()) {
        return Some(format!("colour {c} is not below the number of contacts"));
    }
    let mut touched: Vec<(u32, usize)> = keys
        .iter()
        .zip(colour)
        .flat_map(|(k, &c)| {
            let other = if let Antagonist::Body(j) = k.1 { Some(j) } else { None };
            [Some(k.0), other].into_iter().flatten().filter(|&b| moving[b]).map(move |b| (c, b))
        })
        .collect();
    touched.sort_unstable();
    touched
        .windows(2)
        .find(|w| w[0] == w[1])
        .map(|w| format!("two contacts of colour {} touch body {}: the colouring is not proper", w[0].0, w[0].1))
}
