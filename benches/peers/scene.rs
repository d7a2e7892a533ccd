//! The peer benchmark's pile in both engines: a moreau scene of disks in segment walls, and the
//! same bodies and walls as a rapier2d world (density, friction, no restitution, same time
//! step). Penetration is measured the same way for both: moreau's exact detection on the
//! positions each engine reached. Shared by `benches/peers.rs` and `tests/peers.rs`.

use glam::DVec2;
use moreau::detection::{Configuration, Detector};
use moreau::world::{BodyShape, WallShape, World};
use rapier2d::prelude::{ColliderBuilder, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, Vector};

/// A rapier2d world holding the scene's disks and walls.
pub struct RapierPile {
    pub world: PhysicsWorld,
    pub handles: Vec<RigidBodyHandle>,
}

/// Builds `world` (disks only) in rapier2d with time step `h` and `iterations` solver iterations.
pub fn rapier_pile(world: &World, h: f64, iterations: usize) -> Result<RapierPile, String> {
    let mut physics = PhysicsWorld::new();
    let g = world.effects.gravity.unwrap_or(DVec2::ZERO);
    physics.gravity = Vector::new(g.x as f32, g.y as f32);
    physics.integration_parameters.dt = h as f32;
    physics.integration_parameters.num_solver_iterations = iterations;
    let b = &world.bodies;
    let mut handles = Vec::with_capacity(b.len());
    for k in 0..b.len() {
        let BodyShape::Disk { radius } = b.shape[k] else {
            return Err(format!("body {k} is not a disk: the peer pile holds disks only"));
        };
        let law = world.materials.interaction(b.material[k] as usize, b.material[k] as usize);
        let density = world.materials.density[b.material[k] as usize];
        let p = b.position[k];
        let v = b.velocity[k];
        let body = RigidBodyBuilder::dynamic()
            .translation(Vector::new(p.x as f32, p.y as f32))
            .linvel(Vector::new(v.x as f32, v.y as f32))
            .angvel(b.spin_of(k) as f32);
        let collider =
            ColliderBuilder::ball(radius as f32).density(density as f32).friction(law.friction as f32).restitution(0.0);
        handles.push(physics.insert(body, collider).0);
    }
    for (w, wall) in world.walls.iter().enumerate() {
        let WallShape::Segment { a, b: e } = wall.shape else {
            return Err(format!("wall {w} is not a segment"));
        };
        let rot = DVec2::from_angle(wall.angle);
        let (a, e) = (wall.center + rot.rotate(a), wall.center + rot.rotate(e));
        let law = world.materials.interaction(wall.material, wall.material);
        let collider =
            ColliderBuilder::segment(Vector::new(a.x as f32, a.y as f32), Vector::new(e.x as f32, e.y as f32))
                .friction(law.friction as f32)
                .restitution(0.0);
        physics.insert_collider(collider, None);
    }
    Ok(RapierPile { world: physics, handles })
}

impl RapierPile {
    /// Positions and velocities of the disks, in the scene's order.
    pub fn state(&self) -> (Vec<DVec2>, Vec<DVec2>) {
        self.handles
            .iter()
            .map(|h| {
                let body = &self.world.bodies[*h];
                let (p, v) = (body.translation(), body.linvel());
                (DVec2::new(p.x as f64, p.y as f64), DVec2::new(v.x as f64, v.y as f64))
            })
            .unzip()
    }
}

/// Overlaps at `position` (moreau's exact detection, no alert): (mean over overlapping pairs,
/// largest, count), relative to the mean diameter.
pub fn penetration(world: &World, position: &[DVec2]) -> (f64, f64, usize) {
    let mut detector = Detector::default();
    let config = Configuration { position, angle: &world.bodies.angle, periodic: None, pass_through: None };
    let contacts = detector.detect(&world.bodies, &config, &world.walls, 0.0, &[], &[]);
    let overlaps: Vec<f64> = contacts.iter().filter(|c| c.gap < 0.0).map(|c| -c.gap).collect();
    let d = world.bodies.mean_diameter();
    let max = overlaps.iter().copied().fold(0.0, f64::max);
    let mean = if overlaps.is_empty() { 0.0 } else { overlaps.iter().sum::<f64>() / overlaps.len() as f64 };
    (mean / d, max / d, overlaps.len())
}

/// Kinetic energy of disks of the scene's masses at `velocity` (translation only).
pub fn kinetic_energy(world: &World, velocity: &[DVec2]) -> f64 {
    velocity.iter().zip(&world.bodies.mass).map(|(v, m)| 0.5 * m * v.length_squared()).sum()
}
