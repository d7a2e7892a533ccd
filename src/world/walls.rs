//! Walls: fixed or driven obstacles (segments and polygons) with a prescribed motion.
//! Their geometry is stored in a local frame around `center`, which moves with `velocity` and
//! turns with `spin` (a rotating drum is a ring of segments sharing one centre).

use glam::DVec2;

use super::PolygonShape;

/// The most segments a drum may have.
pub const MAX_DRUM_SIDES: usize = 100_000;

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
    /// A polygon (solid; convex or not).
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
        Self::segment_about(a, b, (a + b) / 2.0, material)
    }

    /// A fixed segment from `a` to `b` whose frame is at `center` (a spin turns it about that).
    fn segment_about(a: DVec2, b: DVec2, center: DVec2, material: usize) -> Self {
        Self::fixed(WallShape::Segment { a: a - center, b: b - center }, center, material)
    }

    /// A fixed wall of `shape` (in its frame) with its frame at `center`.
    fn fixed(shape: WallShape, center: DVec2, material: usize) -> Self {
        Self { shape, center, angle: 0.0, velocity: DVec2::ZERO, spin: 0.0, material }
    }

    /// A solid polygon of world `vertices` (a convex one's in any order, a concave outline's in
    /// either direction), its frame at `frame` or else at the polygon's centroid.
    pub fn polygon(vertices: &[DVec2], frame: Option<DVec2>, material: usize) -> Result<Self, String> {
        super::bodies::check_vertices(vertices)?;
        let mut tmp = super::Bodies::new(true);
        let centroid_guess = vertices.iter().copied().sum::<DVec2>() / vertices.len().max(1) as f64;
        let rel: Vec<DVec2> = vertices.iter().map(|p| *p - centroid_guess).collect();
        tmp.add(&super::BodySpec::polygon(centroid_guess, rel, 0), 1.0)?;
        let centroid = tmp.position[0];
        let c = frame.unwrap_or(centroid);
        let mut shape = tmp.polygons.remove(0);
        shape.vertices.iter_mut().for_each(|p| *p = *p + centroid - c);
        Ok(Self::fixed(WallShape::Polygon(shape), c, material))
    }

    /// A drum: `sides` segments on the circle of `radius` about `center`, each with its frame at
    /// `frame` or else at the centre, about which a spin turns them.
    pub fn drum(
        center: DVec2,
        radius: f64,
        sides: usize,
        frame: Option<DVec2>,
        material: usize,
    ) -> Result<Vec<Self>, String> {
        if !(center.is_finite() && radius.is_finite() && radius > 0.0 && (3..=MAX_DRUM_SIDES).contains(&sides)) {
            return Err(format!("needs a finite centre, radius > 0 and 3 <= sides <= {MAX_DRUM_SIDES}"));
        }
        let c = frame.unwrap_or(center);
        let at = |k: usize| center + radius * DVec2::from_angle(std::f64::consts::TAU * k as f64 / sides as f64);
        Ok((0..sides).map(|s| Self::segment_about(at(s), at(s + 1), c, material)).collect())
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
