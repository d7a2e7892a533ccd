//! Walls: fixed or driven obstacles (segments and convex polygons) with a prescribed motion.
//! Their geometry is stored in a local frame around `center`, which moves with `velocity` and
//! turns with `spin` (a rotating drum is a ring of segments sharing one centre).

use glam::DVec2;

use super::PolygonShape;

/// A wall's geometry in its own frame.
#[derive(Clone, Debug)]
pub enum WallShape {
    /// A two-sided segment, endpoints in the wall frame.
    Segment {
        /// First endpoint.
        a: DVec2,
        /// Second endpoint.
        b: DVec2,
    },
    /// A convex polygon (solid).
    Polygon(PolygonShape),
}

/// A fixed or driven obstacle: its shape moves with its centre.
#[derive(Clone, Debug)]
pub struct Wall {
    /// Geometry in the wall frame.
    pub shape: WallShape,
    /// Centre of the wall frame (m); rotations turn about it.
    pub center: DVec2,
    /// Orientation of the wall frame (rad).
    pub angle: f64,
    /// Prescribed velocity (m/s; needs the effect moving_walls).
    pub velocity: DVec2,
    /// Prescribed spin about the centre (rad/s).
    pub spin: f64,
    /// Material index.
    pub material: usize,
}

impl WallShape {
    /// The segment's endpoints or the polygon's vertices, in the wall frame.
    pub(crate) fn local_points(&self) -> Vec<DVec2> {
        match self {
            WallShape::Segment { a, b } => vec![*a, *b],
            WallShape::Polygon(p) => p.vertices.clone(),
        }
    }

    /// Bounds in the wall frame (used with [`Wall::aabb`]).
    pub fn aabb(&self) -> (DVec2, DVec2) {
        let pts = self.local_points();
        let lo = pts.iter().fold(DVec2::splat(f64::INFINITY), |m, p| m.min(*p));
        let hi = pts.iter().fold(DVec2::splat(f64::NEG_INFINITY), |m, p| m.max(*p));
        (lo, hi)
    }
}

impl Wall {
    /// A fixed segment from `a` to `b`.
    pub fn segment(a: DVec2, b: DVec2, material: usize) -> Self {
        let c = (a + b) / 2.0;
        Self {
            shape: WallShape::Segment { a: a - c, b: b - c },
            center: c,
            angle: 0.0,
            velocity: DVec2::ZERO,
            spin: 0.0,
            material,
        }
    }

    /// World coordinates of the wall's points (segment endpoints or polygon vertices).
    pub fn world_points(&self) -> Vec<DVec2> {
        let rot = DVec2::from_angle(self.angle);
        self.shape.local_points().iter().map(|p| self.center + rot.rotate(*p)).collect()
    }

    /// World bounds.
    pub fn aabb(&self) -> (DVec2, DVec2) {
        let pts = self.world_points();
        let lo = pts.iter().fold(DVec2::splat(f64::INFINITY), |m, p| m.min(*p));
        let hi = pts.iter().fold(DVec2::splat(f64::NEG_INFINITY), |m, p| m.max(*p));
        (lo, hi)
    }

    /// Velocity of the wall's material point at `x`.
    #[inline]
    pub fn velocity_at(&self, x: DVec2) -> DVec2 {
        self.velocity + self.spin * (x - self.center).perp()
    }

    /// Whether the wall has a velocity or a spin.
    pub fn is_moving(&self) -> bool {
        self.velocity != DVec2::ZERO || self.spin != 0.0
    }

    /// Advances the prescribed motion by `h`.
    pub fn advance(&mut self, h: f64) {
        self.center += h * self.velocity;
        self.angle += h * self.spin;
    }
}
