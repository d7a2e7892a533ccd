//! The effects a scene names. An effect that is not named is off and costs nothing.

use glam::DVec2;
use serde::Deserialize;

/// An effect a scene may name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// Gravity on every moving body.
    Gravity,
    /// Coulomb friction: a tangential row per contact.
    Friction,
    /// Bodies turn: angles, spins, inertia and lever arms.
    Rotation,
    /// Newton restitution at impacts.
    Restitution,
    /// Cohesion: a shifted Coulomb cone.
    Cohesion,
    /// Rolling resistance: a rolling unknown per contact.
    RollingResistance,
    /// Walls with a prescribed velocity or spin.
    MovingWalls,
}

impl Effect {
    /// The name scenes use for it.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Gravity => "gravity",
            Effect::Friction => "friction",
            Effect::Rotation => "rotation",
            Effect::Restitution => "restitution",
            Effect::Cohesion => "cohesion",
            Effect::RollingResistance => "rolling_resistance",
            Effect::MovingWalls => "moving_walls",
        }
    }
}

/// Switches read by detection, assembly and stepping. Everything off by default.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Effects {
    /// Gravity acceleration, when on.
    pub gravity: Option<DVec2>,
    /// Coulomb friction: tangential rows exist.
    pub friction: bool,
    /// Bodies carry an angle and a spin.
    pub rotation: bool,
    /// Newton restitution at impacts.
    pub restitution: bool,
    /// Cohesion (shifted Coulomb cone, pulling up to `c` within the alert distance).
    pub cohesion: bool,
    /// Walls may have a prescribed velocity.
    pub moving_walls: bool,
    /// A rolling unknown per contact: a torque resisting relative rolling, at most η R r_n.
    pub rolling_resistance: bool,
}

impl Effects {
    /// The velocity gravity gives over a step of `h`, `g h` (0 without gravity).
    pub fn gravity_step(&self, h: f64) -> f64 {
        self.gravity.map_or(0.0, |g| g.length() * h)
    }

    /// The names of the effects that are on, for reports.
    pub fn names(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        let on = [
            (self.gravity.is_some(), Effect::Gravity),
            (self.friction, Effect::Friction),
            (self.rotation, Effect::Rotation),
            (self.restitution, Effect::Restitution),
            (self.cohesion, Effect::Cohesion),
            (self.rolling_resistance, Effect::RollingResistance),
            (self.moving_walls, Effect::MovingWalls),
        ];
        for (is_on, e) in on {
            if is_on {
                v.push(e.name());
            }
        }
        v
    }
}
