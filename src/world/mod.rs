//! The simulated system: bodies (disks, polygons convex or not, clumps of disks), walls, materials and the effects a
//! scene switches on. Stored as flat arrays (structure of arrays): per-body data that an effect
//! needs (angles and spins for rotation, pair tables for friction…) exists only when it is on.

mod bodies;
mod build;
mod clump;
mod concave;
mod effects;
mod materials;
mod periodic;
mod walls;

pub use bodies::{unit_polygon, Bodies, BodyShape, BodySpec, PolygonShape, SpecShape};
pub use build::WorldError;
pub use clump::{unit_clump, ClumpShape, MAX_CLUMP_DISKS};
pub use concave::MAX_CONCAVE_VERTICES;
pub use effects::{Effect, Effects};
pub use materials::{Interaction, Materials};
pub use periodic::Periodic;
pub use walls::{Wall, WallShape};

use glam::DVec2;

/// Everything a time step reads and updates.
#[derive(Clone, Debug)]
pub struct World {
    /// The switches every stage reads.
    pub effects: Effects,
    /// Every body, in structure-of-arrays form.
    pub bodies: Bodies,
    /// Every wall (fixed or with a prescribed motion).
    pub walls: Vec<Wall>,
    /// Densities and the contact law of each pair of materials.
    pub materials: Materials,
    /// A periodic cell along x, if any.
    pub periodic: Option<Periodic>,
}

impl World {
    /// An empty world: bodies and walls are added afterwards.
    pub fn new(effects: Effects, materials: Materials) -> Self {
        Self { bodies: Bodies::new(effects.rotation), walls: Vec::new(), materials, effects, periodic: None }
    }

    /// Brings every body back into the periodic cell; returns how far each moved along x (empty
    /// without a cell).
    pub fn wrap_positions(&mut self) -> Vec<f64> {
        let Some(p) = self.periodic else { return Vec::new() };
        self.bodies
            .position
            .iter_mut()
            .map(|x| {
                let before = x.x;
                x.x = p.wrap(x.x);
                x.x - before
            })
            .collect()
    }

    /// Kinetic energy `½ Σ m|v|² + ½ Σ I ω²`.
    pub fn kinetic_energy(&self) -> f64 {
        self.bodies.kinetic_energy()
    }

    /// Potential energy of gravity `−Σ m g·x` (zero without gravity).
    pub fn potential_energy(&self) -> f64 {
        match self.effects.gravity {
            Some(g) => self.bodies.potential_energy(g),
            None => 0.0,
        }
    }

    /// Mean diameter of the dynamic bodies (the length that penetration is measured against).
    pub fn mean_diameter(&self) -> f64 {
        self.bodies.mean_diameter()
    }

    /// Axis-aligned bounds of bodies and walls.
    pub fn bounds(&self) -> (DVec2, DVec2) {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for k in 0..self.bodies.len() {
            let (p, r) = (self.bodies.position[k], self.bodies.bounding_radius[k]);
            lo = lo.min(p - r);
            hi = hi.max(p + r);
        }
        for w in &self.walls {
            let (a, b) = w.aabb();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        (lo, hi)
    }

    /// A fingerprint of what a checkpoint leaves to the scene (each body's shape, material and
    /// whether it is fixed; each wall's shape and material), so that a checkpoint is not applied
    /// to bodies that are not the ones it was taken of: a generator that now draws other grains,
    /// another grains file, or bodies added or removed since.
    pub fn shapes_fingerprint(&self) -> String {
        let mut words: Vec<u64> = Vec::with_capacity(3 * self.bodies.len() + 4 * self.walls.len());
        let points = |words: &mut Vec<u64>, points: &[DVec2]| {
            words.push(points.len() as u64);
            words.extend(points.iter().flat_map(|p| [p.x.to_bits(), p.y.to_bits()]));
        };
        let b = &self.bodies;
        for k in 0..b.len() {
            match b.shape[k] {
                BodyShape::Disk { radius } => words.extend([0, radius.to_bits()]),
                BodyShape::Polygon(i) => {
                    words.push(1);
                    points(&mut words, &b.polygons[i as usize].vertices);
                }
                BodyShape::Clump(i) => {
                    let disks = &b.clumps[i as usize].disks;
                    words.extend([2, disks.len() as u64]);
                    words.extend(disks.iter().flat_map(|(c, r)| [c.x.to_bits(), c.y.to_bits(), r.to_bits()]));
                }
            }
            // Held axes in bits 33 and 34: zero, the same words, for a body that holds none.
            let [x, y] = b.held_axes(k);
            let held = u64::from(x) << 33 | u64::from(y) << 34;
            words.push(b.material[k] as u64 | u64::from(b.inv_mass[k] == 0.0) << 32 | held);
        }
        for w in &self.walls {
            points(&mut words, &w.shape.local_points());
            words.push(w.material as u64);
        }
        fingerprint(bytemuck::cast_slice(&words))
    }
}

/// FNV-1a (64 bits) of `bytes`, written `fnv1a64:` and 16 hex digits: how checkpoints name the
/// scene file and the shapes they belong to.
pub fn fingerprint(bytes: &[u8]) -> String {
    let hash = bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3));
    format!("fnv1a64:{hash:016x}")
}
