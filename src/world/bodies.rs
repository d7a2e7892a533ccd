//! Rigid bodies as flat arrays. Angles, spins and inertias exist only when rotation is on.

use glam::DVec2;
use parry2d::shape::ConvexPolygon;

use super::clump::{disk_union, ClumpShape};
use super::concave::{convex_corners, simple_outline};

/// A polygon in its body frame (centroid at the origin, counter-clockwise), convex or not.
#[derive(Clone, Debug)]
pub struct PolygonShape {
    /// The outline's vertices in the body frame, counter-clockwise, centred on the centroid.
    pub vertices: Vec<DVec2>,
    /// For a concave polygon, which vertices are convex corners (the others are the reflex
    /// corners of its notches); empty for a convex one.
    pub corners: Vec<bool>,
}

impl PolygonShape {
    /// A polygon of counter-clockwise `vertices`, its corners found when it is concave.
    pub(crate) fn new(vertices: Vec<DVec2>, convex: bool) -> Self {
        let corners = if convex { Vec::new() } else { convex_corners(&vertices) };
        Self { vertices, corners }
    }

    /// Whether the polygon has a notch (its contacts are then read from its outline).
    pub fn is_concave(&self) -> bool {
        !self.corners.is_empty()
    }
}

/// A body's shape in its own frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BodyShape {
    /// A disk.
    Disk {
        /// Its radius (m).
        radius: f64,
    },
    /// Index into [`Bodies::polygons`].
    Polygon(u32),
    /// Index into [`Bodies::clumps`].
    Clump(u32),
}

/// What a host code or a scene gives to create a body.
#[derive(Clone, Debug)]
pub struct BodySpec {
    /// Disk or polygon.
    pub shape: SpecShape,
    /// Centre of mass (m).
    pub center: DVec2,
    /// Orientation (rad).
    pub angle: f64,
    /// Initial velocity (m/s).
    pub velocity: DVec2,
    /// Initial spin (rad/s; kept only with the effect rotation).
    pub spin: f64,
    /// Index of its material.
    pub material: usize,
    /// A fixed body has infinite mass: contacts and forces never move it. It moves only at its
    /// own velocity and spin, zero unless given (a kinematic body: a conveyor, a paddle, the
    /// rough plate of a shear cell); two fixed bodies never touch.
    pub fixed: bool,
    /// A free label carried to the outputs (layer number, group…).
    pub tag: u32,
    /// A constant force (N) on the body's centre at every step, besides gravity: a piston's
    /// load, a pressure times the plate's width.
    pub force: DVec2,
    /// The body keeps its angle (infinite moment of inertia): a piston plate that must not tilt.
    pub lock_rotation: bool,
    /// The mass (kg), instead of the material's density times the area; the moment of inertia
    /// scales with it.
    pub mass: Option<f64>,
    /// Along x (`[true, false]`), y or both, the body keeps the velocity it is given whatever
    /// contacts and forces do, and moves freely along the other axis (LMGC90's driven degrees of
    /// freedom): the top plate of a shear cell, driven along x and pressed by its force along y.
    pub hold_velocity: [bool; 2],
}

/// The shape a body is asked for with.
#[derive(Clone, Debug)]
pub enum SpecShape {
    /// A disk.
    Disk {
        /// Its radius (m).
        radius: f64,
    },
    /// Vertices relative to `center`: a convex polygon's in any order (their convex hull is
    /// used), a concave one's around its outline in either direction (the outline must not cross
    /// or touch itself).
    Polygon {
        /// Vertices relative to the given centre (recentred on the centroid when added).
        vertices: Vec<DVec2>,
    },
    /// Overlapping disks moving as one rigid grain (a non-convex grain).
    Clump {
        /// Each disk's centre relative to the given centre, and its radius (the body is
        /// recentred on the union's centroid when added).
        disks: Vec<(DVec2, f64)>,
    },
}

impl BodySpec {
    /// A disk at `center`, at rest, of `material`.
    pub fn disk(center: DVec2, radius: f64, material: usize) -> Self {
        Self {
            shape: SpecShape::Disk { radius },
            center,
            angle: 0.0,
            velocity: DVec2::ZERO,
            spin: 0.0,
            material,
            fixed: false,
            tag: 0,
            force: DVec2::ZERO,
            lock_rotation: false,
            mass: None,
            hold_velocity: [false; 2],
        }
    }

    /// Holds the body's velocity along the axis named `axis` ("x" or "y"), as a scene's
    /// `hold_velocity = ["x"]` does.
    pub fn hold_axis(&mut self, axis: &str) -> Result<(), String> {
        match axis {
            "x" => self.hold_velocity[0] = true,
            "y" => self.hold_velocity[1] = true,
            other => return Err(format!("unknown axis '{other}' (x or y)")),
        }
        Ok(())
    }

    /// A polygon, vertices relative to `center` (convex, or a concave outline), at rest.
    pub fn polygon(center: DVec2, vertices: Vec<DVec2>, material: usize) -> Self {
        Self { shape: SpecShape::Polygon { vertices }, ..Self::disk(center, 0.0, material) }
    }

    /// A clump of overlapping disks (centres relative to `center`, radii), at rest.
    pub fn clump(center: DVec2, disks: Vec<(DVec2, f64)>, material: usize) -> Self {
        Self { shape: SpecShape::Clump { disks }, ..Self::disk(center, 0.0, material) }
    }

    /// A regular polygon with `sides` vertices on a circle of `radius`.
    pub fn regular_polygon(center: DVec2, radius: f64, sides: usize, angle: f64, material: usize) -> Self {
        let vertices = (0..sides)
            .map(|k| {
                let a = angle + std::f64::consts::TAU * k as f64 / sides as f64;
                DVec2::new(a.cos(), a.sin()) * radius
            })
            .collect();
        Self::polygon(center, vertices, material)
    }
}

/// Every body of a world as parallel arrays (index = body id).
#[derive(Clone, Debug)]
pub struct Bodies {
    rotation: bool,
    /// Each body's shape (a polygon's vertices in [`Self::polygons`]).
    pub shape: Vec<BodyShape>,
    /// The polygon shapes, referred to from [`Self::shape`].
    pub polygons: Vec<PolygonShape>,
    /// The clump shapes, referred to from [`Self::shape`].
    pub clumps: Vec<ClumpShape>,
    /// Centres of mass (m).
    pub position: Vec<DVec2>,
    /// Velocities (m/s).
    pub velocity: Vec<DVec2>,
    /// Empty without rotation.
    pub angle: Vec<f64>,
    /// Empty without rotation.
    pub spin: Vec<f64>,
    /// 0 for fixed bodies.
    pub mass: Vec<f64>,
    /// 1/m, 0 for fixed bodies.
    pub inv_mass: Vec<f64>,
    /// Empty without rotation.
    pub inertia: Vec<f64>,
    /// Empty without rotation.
    pub inv_inertia: Vec<f64>,
    /// Radius of the smallest circle about the centre that holds the body (detection, framing).
    pub bounding_radius: Vec<f64>,
    /// Material index.
    pub material: Vec<u16>,
    /// A user label (layers of a deposit), carried to the outputs.
    pub tag: Vec<u32>,
    /// Constant forces (N) applied at every step ([`BodySpec::force`]); empty while no body has
    /// one, so that scenes without pistons carry nothing.
    pub force: Vec<DVec2>,
    /// The axes along which each body holds its velocity ([`BodySpec::hold_velocity`]); empty
    /// while no body holds one.
    pub held: Vec<[bool; 2]>,
}

/// Area, centroid and polar moment of area about the centroid of a counter-clockwise polygon.
fn polygon_area_properties(v: &[DVec2]) -> (f64, DVec2, f64) {
    let (mut area, mut c, mut j_origin) = (0.0, DVec2::ZERO, 0.0);
    for k in 0..v.len() {
        let (a, b) = (v[k], v[(k + 1) % v.len()]);
        let cr = a.perp_dot(b);
        area += cr / 2.0;
        c += (a + b) * cr / 6.0;
        j_origin += cr * (a.dot(a) + a.dot(b) + b.dot(b)) / 12.0;
    }
    let centroid = c / area;
    (area, centroid, j_origin - area * centroid.length_squared())
}

impl Bodies {
    /// No bodies; `rotation` decides whether angles and spins are stored.
    pub fn new(rotation: bool) -> Self {
        Self {
            rotation,
            shape: Vec::new(),
            polygons: Vec::new(),
            clumps: Vec::new(),
            position: Vec::new(),
            velocity: Vec::new(),
            angle: Vec::new(),
            spin: Vec::new(),
            mass: Vec::new(),
            inv_mass: Vec::new(),
            inertia: Vec::new(),
            inv_inertia: Vec::new(),
            bounding_radius: Vec::new(),
            material: Vec::new(),
            tag: Vec::new(),
            force: Vec::new(),
            held: Vec::new(),
        }
    }

    /// Removes body `k`; the bodies after it move down one index. (Its polygon or clump, if
    /// any, stays in `polygons` or `clumps`, unused.)
    pub fn remove(&mut self, k: usize) {
        self.shape.remove(k);
        self.position.remove(k);
        self.velocity.remove(k);
        self.mass.remove(k);
        self.inv_mass.remove(k);
        self.bounding_radius.remove(k);
        self.material.remove(k);
        self.tag.remove(k);
        if !self.force.is_empty() {
            self.force.remove(k);
        }
        if !self.held.is_empty() {
            self.held.remove(k);
        }
        if self.rotation {
            self.angle.remove(k);
            self.spin.remove(k);
            self.inertia.remove(k);
            self.inv_inertia.remove(k);
        }
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// Whether there is no body.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Whether bodies carry an angle and a spin.
    pub fn has_rotation(&self) -> bool {
        self.rotation
    }

    /// Adds a body of the given density; returns its index or says what is wrong with it
    /// (a polygon's outline must not cross itself).
    pub fn add(&mut self, spec: &BodySpec, density: f64) -> Result<usize, String> {
        let finite = |v: DVec2| v.x.is_finite() && v.y.is_finite();
        let state = [
            ("position", finite(spec.center), format!("[{}, {}]", spec.center.x, spec.center.y)),
            ("velocity", finite(spec.velocity), format!("[{}, {}]", spec.velocity.x, spec.velocity.y)),
            ("angle", spec.angle.is_finite(), spec.angle.to_string()),
            ("spin", spec.spin.is_finite(), spec.spin.to_string()),
        ];
        if let Some((name, _, value)) = state.iter().find(|(_, ok, _)| !ok) {
            return Err(format!("{name} {value} must be finite"));
        }
        if !(density.is_finite() && density > 0.0) {
            return Err(format!("density {density} must be finite and > 0"));
        }
        if !finite(spec.force) {
            return Err(format!("force [{}, {}] must be finite", spec.force.x, spec.force.y));
        }
        if spec.lock_rotation && spec.spin != 0.0 {
            return Err(format!("spin {}: a body that keeps its angle (lock_rotation) does not turn", spec.spin));
        }
        if spec.fixed && (spec.force != DVec2::ZERO || spec.mass.is_some()) {
            return Err(
                "a fixed body takes no force and no mass (it moves only at the velocity and spin it is given)".into()
            );
        }
        if spec.fixed && spec.hold_velocity.contains(&true) {
            return Err(
                "a fixed body holds its velocity along both axes already (hold_velocity is for a moving one)".into()
            );
        }
        for (axis, name) in [(0, "x"), (1, "y")] {
            let force = [spec.force.x, spec.force.y][axis];
            if spec.hold_velocity[axis] && force != 0.0 {
                return Err(format!(
                    "force {force} along {name}, where the body holds its velocity (hold_velocity): it would do nothing"
                ));
            }
        }
        if let Some(m) = spec.mass.filter(|m| !(m.is_finite() && *m > 0.0)) {
            return Err(format!("mass {m} must be finite and > 0"));
        }
        let (shape, area, second_moment, bounding, center) = match &spec.shape {
            SpecShape::Disk { radius } => {
                let r = *radius;
                if !(r.is_finite() && r > 0.0) {
                    return Err(format!("disk radius {r} must be finite and > 0"));
                }
                let area = std::f64::consts::PI * r * r;
                (BodyShape::Disk { radius: r }, area, area * r * r / 2.0, r, spec.center)
            }
            SpecShape::Polygon { vertices } => {
                check_vertices(vertices)?;
                // The hull is computed in f32 (parry2d), which panics on vertices closer than its
                // tolerance: refuse a polygon smaller than f32 can tell apart at its position.
                let span = vertices.iter().map(|v| (*v - vertices[0]).length()).fold(0.0, f64::max);
                let reach = vertices.iter().map(|v| v.abs().max_element()).fold(0.0, f64::max);
                let needed = (1e-5 * reach).max(1e-12);
                if span.is_nan() || span < needed {
                    return Err(format!(
                        "degenerate polygon: its vertices lie within {span:e} m of each other (at least {needed:e} m needed)"
                    ));
                }
                let convex = check_convex(vertices).is_ok();
                let ccw = if convex {
                    let pts: Vec<_> =
                        vertices.iter().map(|v| parry2d::math::Vector::new(v.x as f32, v.y as f32)).collect();
                    let hull = ConvexPolygon::from_convex_hull(&pts).ok_or_else(|| {
                        "degenerate polygon: its vertices have no convex hull of positive area".to_string()
                    })?;
                    hull.points().iter().map(|p| DVec2::new(p.x as f64, p.y as f64)).collect()
                } else {
                    simple_outline(vertices)?
                };
                let (area, centroid, polar) = polygon_area_properties(&ccw);
                let size = ccw.iter().map(|v| (*v - centroid).length()).fold(0.0, f64::max);
                if area.is_nan() || area <= 1e-12 * size * size || ccw.len() < 3 {
                    return Err(format!("degenerate polygon: area {area:e} is zero for its size {size:e}"));
                }
                let local: Vec<DVec2> = ccw.iter().map(|v| *v - centroid).collect();
                self.polygons.push(PolygonShape::new(local, convex));
                let c = spec.center + DVec2::from_angle(spec.angle).rotate(centroid);
                (BodyShape::Polygon(self.polygons.len() as u32 - 1), area, polar, size, c)
            }
            SpecShape::Clump { disks } => {
                let union = disk_union(disks)?;
                let local: Vec<(DVec2, f64)> = disks.iter().map(|(c, r)| (*c - union.centroid, *r)).collect();
                let size = local.iter().map(|(c, r)| c.length() + r).fold(0.0, f64::max);
                let outline = union.outline.iter().map(|p| *p - union.centroid).collect();
                self.clumps.push(ClumpShape { disks: local, outline });
                let c = spec.center + DVec2::from_angle(spec.angle).rotate(union.centroid);
                (BodyShape::Clump(self.clumps.len() as u32 - 1), union.area, union.polar, size, c)
            }
        };
        // A given mass sets the density the inertia is computed with.
        let density = spec.mass.map_or(density, |m| m / area);
        let (mass, inertia) = if spec.fixed { (0.0, 0.0) } else { (density * area, density * second_moment) };
        let representable = |x: f64| x.is_finite() && x > 0.0 && (1.0 / x).is_finite();
        if !spec.fixed && !(representable(mass) && (!self.rotation || representable(inertia))) {
            return Err(format!(
                "its mass {mass:e} or moment of inertia {inertia:e} (density {density:e} × its size {bounding:e} m) \
                 is beyond f64: scale the lengths or the density"
            ));
        }
        self.shape.push(shape);
        self.position.push(center);
        self.velocity.push(spec.velocity);
        self.mass.push(mass);
        self.inv_mass.push(if spec.fixed { 0.0 } else { 1.0 / mass });
        if self.rotation {
            self.angle.push(spec.angle);
            let turns = !(spec.fixed || spec.lock_rotation);
            self.spin.push(spec.spin);
            self.inertia.push(inertia);
            self.inv_inertia.push(if turns { 1.0 / inertia } else { 0.0 });
        } else if let BodyShape::Polygon(p) = shape {
            // Without rotation a polygon keeps its initial orientation: bake it in.
            let rot = DVec2::from_angle(spec.angle);
            self.polygons[p as usize].vertices.iter_mut().for_each(|v| *v = rot.rotate(*v));
        } else if let BodyShape::Clump(c) = shape {
            let rot = DVec2::from_angle(spec.angle);
            let clump = &mut self.clumps[c as usize];
            clump.disks.iter_mut().for_each(|(c, _)| *c = rot.rotate(*c));
            clump.outline.iter_mut().for_each(|p| *p = rot.rotate(*p));
        }
        self.bounding_radius.push(bounding);
        self.material.push(spec.material as u16);
        self.tag.push(spec.tag);
        if spec.force != DVec2::ZERO || !self.force.is_empty() {
            self.force.resize(self.len() - 1, DVec2::ZERO);
            self.force.push(spec.force);
        }
        if spec.hold_velocity.contains(&true) || !self.held.is_empty() {
            self.held.resize(self.len() - 1, [false; 2]);
            self.held.push(spec.hold_velocity);
        }
        Ok(self.len() - 1)
    }

    /// Body `k`'s angle (0 without rotation).
    #[inline]
    pub fn angle_of(&self, k: usize) -> f64 {
        if self.rotation {
            self.angle[k]
        } else {
            0.0
        }
    }

    /// Body `k`'s spin (0 without rotation).
    #[inline]
    pub fn spin_of(&self, k: usize) -> f64 {
        if self.rotation {
            self.spin[k]
        } else {
            0.0
        }
    }

    /// Disk radius, or the bounding radius of a polygon or a clump.
    pub fn radius_of(&self, k: usize) -> f64 {
        match self.shape[k] {
            BodyShape::Disk { radius } => radius,
            BodyShape::Polygon(_) | BodyShape::Clump(_) => self.bounding_radius[k],
        }
    }

    /// World coordinates of a polygon body's vertices, or of a clump's outline (empty for a
    /// disk).
    pub fn world_vertices(&self, k: usize) -> Vec<DVec2> {
        let local = match self.shape[k] {
            BodyShape::Disk { .. } => return Vec::new(),
            BodyShape::Polygon(p) => &self.polygons[p as usize].vertices,
            BodyShape::Clump(c) => &self.clumps[c as usize].outline,
        };
        let rot = DVec2::from_angle(self.angle_of(k));
        local.iter().map(|v| self.position[k] + rot.rotate(*v)).collect()
    }

    /// A clump body's disks in the world frame (centre, radius), at `position` and `angle`.
    pub fn clump_disks(&self, c: u32, position: DVec2, angle: f64) -> impl Iterator<Item = (DVec2, f64)> + Clone + '_ {
        let rot = DVec2::from_angle(angle);
        self.clumps[c as usize].disks.iter().map(move |(o, r)| (position + rot.rotate(*o), *r))
    }

    /// Kinetic energy of translation and rotation (J).
    pub fn kinetic_energy(&self) -> f64 {
        self.kinetic_energy_of(0..self.len())
    }

    /// The kinetic energy of the bodies `ks` (J): translation, then rotation when it is on.
    fn kinetic_energy_of(&self, ks: impl Iterator<Item = usize> + Clone) -> f64 {
        let mut e: f64 = ks.clone().map(|k| 0.5 * self.mass[k] * self.velocity[k].length_squared()).sum();
        if self.rotation {
            e += ks.map(|k| 0.5 * self.inertia[k] * self.spin[k] * self.spin[k]).sum::<f64>();
        }
        e
    }

    /// Root-mean-square speed of the moving bodies (m/s), rotation included: `√(2 E / M)` over the
    /// bodies of nonzero inverse mass (a fixed body driven at a speed never counts). Zero when none moves.
    pub fn rms_speed(&self) -> f64 {
        let moving = (0..self.len()).filter(|&k| self.inv_mass[k] > 0.0);
        let mass: f64 = moving.clone().map(|k| self.mass[k]).sum();
        if mass > 0.0 {
            (2.0 * self.kinetic_energy_of(moving) / mass).sqrt()
        } else {
            0.0
        }
    }

    /// Potential energy in `gravity`, relative to y = 0 (J).
    pub fn potential_energy(&self, gravity: DVec2) -> f64 {
        (0..self.len()).map(|k| -self.mass[k] * gravity.dot(self.position[k])).sum()
    }

    /// Mean diameter of the moving bodies (m), the scale penetrations are reported in.
    pub fn mean_diameter(&self) -> f64 {
        let dynamic: Vec<f64> =
            (0..self.len()).filter(|&k| self.inv_mass[k] > 0.0).map(|k| self.radius_of(k)).collect();
        if dynamic.is_empty() {
            return 0.0;
        }
        2.0 * dynamic.iter().sum::<f64>() / dynamic.len() as f64
    }

    /// Bytes held by the body arrays (what an effect that is off saves shows here).
    pub fn memory_bytes(&self) -> usize {
        let f = std::mem::size_of::<f64>();
        let v = std::mem::size_of::<DVec2>();
        self.shape.capacity() * std::mem::size_of::<BodyShape>()
            + (self.position.capacity() + self.velocity.capacity()) * v
            + (self.angle.capacity() + self.spin.capacity() + self.mass.capacity() + self.inv_mass.capacity()) * f
            + (self.inertia.capacity() + self.inv_inertia.capacity() + self.bounding_radius.capacity()) * f
            + self.material.capacity() * 2
            + self.tag.capacity() * 4
            + self.force.capacity() * v
    }

    /// The constant force on body `k` ([`BodySpec::force`]).
    #[inline]
    pub fn force_of(&self, k: usize) -> DVec2 {
        self.force.get(k).copied().unwrap_or(DVec2::ZERO)
    }

    /// The bodies driven by a constant force.
    pub fn driven(&self) -> impl Iterator<Item = usize> + '_ {
        self.force.iter().enumerate().filter(|(_, f)| **f != DVec2::ZERO).map(|(k, _)| k)
    }

    /// The axes (x, y) along which body `k` holds its velocity ([`BodySpec::hold_velocity`]).
    #[inline]
    pub fn held_axes(&self, k: usize) -> [bool; 2] {
        self.held.get(k).copied().unwrap_or([false; 2])
    }

    /// Body `k`'s inverse mass along x and y: 0 where it is fixed or holds its velocity.
    #[inline]
    pub fn axis_inv_mass(&self, k: usize) -> [f64; 2] {
        self.held_axes(k).map(|h| if h { 0.0 } else { self.inv_mass[k] })
    }
}

/// A polygon's vertices moved to its centroid and scaled to a bounding radius of 1 (the
/// template a generator scales to each grain's radius); says what is wrong with an outline
/// [`Bodies::add`] would refuse.
pub fn unit_polygon(vertices: &[DVec2]) -> Result<Vec<DVec2>, String> {
    let mut probe = Bodies::new(true);
    probe.add(&BodySpec::polygon(DVec2::ZERO, vertices.to_vec(), 0), 1.0)?;
    let (centroid, reach) = (probe.position[0], probe.bounding_radius[0]);
    Ok(vertices.iter().map(|v| (*v - centroid) / reach).collect())
}

/// Refuses a polygon of fewer than three vertices or with one that is not finite, naming it.
pub(crate) fn check_vertices(vertices: &[DVec2]) -> Result<(), String> {
    if vertices.len() < 3 {
        return Err(format!("a polygon needs at least 3 vertices, got {}", vertices.len()));
    }
    if let Some(k) = vertices.iter().position(|v| !v.is_finite()) {
        return Err(format!("polygon vertex {k} [{}, {}] is not finite", vertices[k].x, vertices[k].y));
    }
    // The convex hull is computed in f32 (parry2d), whose products of coordinates overflow past
    // about 1e19 (and whose hull panicked on the infinities of a vertex at 1e308).
    match vertices.iter().position(|v| v.abs().max_element() > MAX_VERTEX_COORDINATE) {
        Some(k) => Err(format!(
            "polygon vertex {k} [{:e}, {:e}] lies beyond {MAX_VERTEX_COORDINATE:e} m, farther than the polygon's \
             hull (computed in f32) can handle",
            vertices[k].x, vertices[k].y
        )),
        None => Ok(()),
    }
}

/// The largest coordinate of a polygon's vertex, in metres.
const MAX_VERTEX_COORDINATE: f64 = 1e18;

/// Whether the vertices go once around a convex polygon, in either orientation: a concave or
/// self-intersecting outline must not be silently replaced by its hull.
fn check_convex(vertices: &[DVec2]) -> Result<(), String> {
    let n = vertices.len();
    let (mut orientation, mut turning) = (0.0f64, 0.0f64);
    for k in 0..n {
        let (a, b, c) = (vertices[k], vertices[(k + 1) % n], vertices[(k + 2) % n]);
        let (e1, e2) = (b - a, c - b);
        if e1 == DVec2::ZERO || e2 == DVec2::ZERO {
            continue;
        }
        let cross = e1.perp_dot(e2);
        turning += cross.atan2(e1.dot(e2));
        if cross.abs() > 1e-9 * e1.length() * e2.length() {
            if orientation == 0.0 {
                orientation = cross.signum();
            } else if cross.signum() != orientation {
                return Err(format!("polygon is not convex: it turns the other way at vertex {}", (k + 1) % n));
            }
        }
    }
    let windings = turning.abs() / std::f64::consts::TAU;
    if (windings - 1.0).abs() > 1e-6 {
        return Err(format!("polygon's edges cross each other: its outline winds {windings:.0} times around"));
    }
    Ok(())
}
