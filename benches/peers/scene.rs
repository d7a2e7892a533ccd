//! The peer benchmark's pile in three engines: a moreau scene of disks in segment walls, and the
//! same bodies and walls as a rapier2d world and as a Box2D v3 world (density, friction, no
//! restitution, same time step). Penetration is measured the same way for all: moreau's exact
//! detection on the positions each engine reached. Shared by `benches/peers.rs` and
//! `tests/peers.rs`.

use boxdd_sys::ffi as b2;
use glam::DVec2;
use moreau::detection::{Configuration, Detector};
use moreau::world::{BodyShape, WallShape, World};
use rapier2d::prelude::{ColliderBuilder, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, Vector};

/// A game engine's world holding the pile: what the benchmark steps and measures.
pub trait PeerPile {
    /// One step of the world.
    fn step(&mut self);
    /// Positions and velocities of the disks, in the scene's order.
    fn state(&self) -> (Vec<DVec2>, Vec<DVec2>);
}

/// The game engines of the benchmark: name, what their 4, 8 and 16 solver passes are called,
/// and the world each builds from a scene's (disks only), time step and passes.
pub type PeerBuilder = fn(&World, f64, usize) -> Result<Box<dyn PeerPile>, String>;
pub const PEERS: [(&str, &str, PeerBuilder); 2] = [
    ("rapier2d", "iterations", |w, h, n| Ok(Box::new(rapier_pile(w, h, n)?))),
    ("box2d", "substeps", |w, h, n| Ok(Box::new(box2d_pile(w, h, n)?))),
];

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

impl PeerPile for RapierPile {
    fn step(&mut self) {
        self.world.step();
    }

    fn state(&self) -> (Vec<DVec2>, Vec<DVec2>) {
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

/// A Box2D v3 world holding the scene's disks and walls, stepped with `substeps` substeps (Box2D's
/// soft-step solver relaxes once and iterates once a substep: its counterpart of rapier2d's
/// iterations). Box2D's defaults otherwise: sleeping on, one worker thread.
pub struct Box2dPile {
    world: b2::b2WorldId,
    bodies: Vec<b2::b2BodyId>,
    h: f32,
    substeps: i32,
}

fn b2_vec(v: DVec2) -> b2::b2Vec2 {
    b2::b2Vec2 { x: v.x as f32, y: v.y as f32 }
}

/// Builds `world` (disks only) in Box2D v3 with time step `h` and `substeps` substeps.
pub fn box2d_pile(world: &World, h: f64, substeps: usize) -> Result<Box2dPile, String> {
    // SAFETY: Box2D's C API, each definition from its own default; every id used belongs to the
    // world made here, which the pile owns and destroys once (Drop), also on an early return.
    unsafe {
        let mut def = b2::b2DefaultWorldDef();
        def.gravity = b2_vec(world.effects.gravity.unwrap_or(DVec2::ZERO));
        let b = &world.bodies;
        let mut pile = Box2dPile {
            world: b2::b2CreateWorld(&def),
            bodies: Vec::with_capacity(b.len()),
            h: h as f32,
            substeps: substeps as i32,
        };
        for k in 0..b.len() {
            let BodyShape::Disk { radius } = b.shape[k] else {
                return Err(format!("body {k} is not a disk: the peer pile holds disks only"));
            };
            let material = b.material[k] as usize;
            let mut body = b2::b2DefaultBodyDef();
            body.type_ = b2::b2BodyType_b2_dynamicBody;
            body.position = b2_vec(b.position[k]);
            body.linearVelocity = b2_vec(b.velocity[k]);
            body.angularVelocity = b.spin_of(k) as f32;
            let id = b2::b2CreateBody(pile.world, &body);
            let mut shape = b2::b2DefaultShapeDef();
            shape.density = world.materials.density[material] as f32;
            shape.material.friction = world.materials.interaction(material, material).friction as f32;
            shape.material.restitution = 0.0;
            let circle = b2::b2Circle { center: b2_vec(DVec2::ZERO), radius: radius as f32 };
            b2::b2CreateCircleShape(id, &shape, &circle);
            pile.bodies.push(id);
        }
        let ground = b2::b2CreateBody(pile.world, &b2::b2DefaultBodyDef());
        for (w, wall) in world.walls.iter().enumerate() {
            let WallShape::Segment { a, b: e } = wall.shape else {
                return Err(format!("wall {w} is not a segment"));
            };
            let rot = DVec2::from_angle(wall.angle);
            let segment = b2::b2Segment {
                point1: b2_vec(wall.center + rot.rotate(a)),
                point2: b2_vec(wall.center + rot.rotate(e)),
            };
            let mut shape = b2::b2DefaultShapeDef();
            shape.material.friction = world.materials.interaction(wall.material, wall.material).friction as f32;
            shape.material.restitution = 0.0;
            b2::b2CreateSegmentShape(ground, &shape, &segment);
        }
        Ok(pile)
    }
}

impl PeerPile for Box2dPile {
    fn step(&mut self) {
        // SAFETY: the world is alive until Drop.
        unsafe { b2::b2World_Step(self.world, self.h, self.substeps) }
    }

    fn state(&self) -> (Vec<DVec2>, Vec<DVec2>) {
        let dvec = |v: b2::b2Vec2| DVec2::new(v.x as f64, v.y as f64);
        // SAFETY: every body id belongs to the live world.
        self.bodies
            .iter()
            .map(|&id| unsafe { (dvec(b2::b2Body_GetPosition(id)), dvec(b2::b2Body_GetLinearVelocity(id))) })
            .unzip()
    }
}

impl Drop for Box2dPile {
    fn drop(&mut self) {
        // SAFETY: made by b2CreateWorld, destroyed here only.
        unsafe { b2::b2DestroyWorld(self.world) }
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
