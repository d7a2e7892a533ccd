//! The TOML schema of a scene and its translation into a [`World`]. Every table rejects unknown
//! keys, so a typo is an error naming the line instead of a silently ignored setting.

use std::path::Path;

use glam::DVec2;
use serde::Deserialize;
use toml::Spanned;

use super::grains_csv;
use super::{deposition, from_toml, generate, Ctx, OutputSettings, Scene, SceneError};
use crate::solvers::{Ordering, SolverKind, SolverOptions, StopCriterion};
use crate::stepping::StepSettings;
use crate::world::{BodySpec, Effect, Effects, Interaction, Materials, Wall, WallShape, World, WorldError};

type P = Exact<f64, 2>;

/// A TOML array of exactly `N` values: `[0.0, -9.81, 0.0]` where a 2D vector is expected is an
/// error, not a vector whose third value is dropped.
#[derive(Clone, Copy, Debug)]
struct Exact<T, const N: usize>([T; N]);

impl<T, const N: usize> std::ops::Deref for Exact<T, N> {
    type Target = [T; N];
    fn deref(&self) -> &[T; N] {
        &self.0
    }
}

impl<'de, T: Deserialize<'de>, const N: usize> Deserialize<'de> for Exact<T, N> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let values = Vec::<T>::deserialize(d)?;
        let got = values.len();
        let array: [T; N] = values.try_into().map_err(|_| {
            let hint = if N == 3 { "[x, y, r], a clump's disk" } else { "[x, y] in 2D" };
            serde::de::Error::invalid_length(got, &format!("an array of exactly {N} values ({hint})").as_str())
        })?;
        Ok(Self(array))
    }
}

/// Bounds on what a scene file may ask a generator for, so that no file can make the parser run
/// out of memory or time: this one, the most grains a generator or a grains file may make.
pub const MAX_GENERATED: usize = 5_000_000;
const MAX_PYRAMID_BASE: usize = 3_000;
const MAX_POLYGON_SIDES: usize = 1_000;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: Option<Spanned<String>>,
    description: Option<String>,
    #[serde(default)]
    effects: Vec<Spanned<Effect>>,
    gravity: Option<Spanned<P>>,
    time: Spanned<TimeSpec>,
    solver: Option<Spanned<SolverSpec>>,
    detection: Option<Spanned<DetectionSpec>>,
    periodic: Option<Spanned<PeriodicSpec>>,
    output: Option<Spanned<OutputSpec>>,
    /// Contact law of every pair of materials not listed in `interaction`.
    contact: Option<Spanned<LawSpec>>,
    #[serde(default)]
    material: Vec<Spanned<MaterialSpec>>,
    #[serde(default)]
    interaction: Vec<Spanned<PairSpec>>,
    #[serde(default)]
    wall: Vec<Spanned<WallSpec>>,
    #[serde(default)]
    body: Vec<Spanned<BodyFileSpec>>,
    #[serde(default)]
    generate: Vec<Spanned<GenerateSpec>>,
    #[serde(default)]
    grains: Vec<Spanned<GrainsFileSpec>>,
}

/// Disks read from a CSV file (`grains_csv.rs`), path relative to the scene file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GrainsFileSpec {
    file: String,
    material: Option<String>,
    /// "auto" (default): the file's order when it keeps grains together, else "space"; "space":
    /// the grains numbered in rows across the packing; "file": in the file's order.
    order: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TimeSpec {
    step: f64,
    steps: usize,
    theta: Option<f64>,
    /// The position projection's slack, a fraction of the smaller grain's radius (default 1e-4).
    projection_slack: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SolverSpec {
    name: Option<String>,
    tol: Option<f64>,
    max_iter: Option<usize>,
    ordering: Option<String>,
    omega: Option<f64>,
    /// NLGS: Anderson acceleration over this many past sweeps (0: off).
    anderson: Option<usize>,
    /// NLGS: focused sweeps after each full sweep (0: off).
    focus: Option<usize>,
    /// GPU NLGS: sweeps of each block of contacts per dispatch (0: colour sweeps).
    block_sweeps: Option<usize>,
    /// natural (default), velocity, quad, maxm, qm16 (LMGC90's tests).
    criterion: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DetectionSpec {
    /// Absolute alert distance; default 5 % of the smallest grain radius.
    alert: Option<f64>,
}

/// A periodic cell along x.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PeriodicSpec {
    x: [f64; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OutputSpec {
    every: Option<usize>,
    vtk: Option<bool>,
    picture_step: Option<usize>,
    checkpoint_every: Option<usize>,
    wall_forces: Option<bool>,
    profile: Option<bool>,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(deny_unknown_fields)]
struct LawSpec {
    friction: Option<f64>,
    restitution: Option<f64>,
    cohesion: Option<f64>,
    rolling_resistance: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialSpec {
    name: String,
    density: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PairSpec {
    materials: [String; 2],
    friction: Option<f64>,
    restitution: Option<f64>,
    cohesion: Option<f64>,
    rolling_resistance: Option<f64>,
    pass_through: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoxSpec {
    min: P,
    max: P,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DrumSpec {
    center: P,
    radius: f64,
    sides: usize,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WallSpec {
    segment: Option<Exact<P, 2>>,
    /// A solid box (a fixed convex polygon).
    #[serde(rename = "box")]
    solid_box: Option<BoxSpec>,
    /// An open container: left, bottom and right segments of the box.
    container: Option<BoxSpec>,
    polygon: Option<Vec<P>>,
    /// A ring of `sides` segments (the inside of a drum).
    drum: Option<DrumSpec>,
    material: Option<String>,
    velocity: Option<P>,
    angular_velocity: Option<f64>,
    /// Centre of rotation (default: the shape's centre).
    center: Option<P>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DiskSpec {
    center: P,
    radius: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PolygonSpec {
    center: P,
    /// Vertices relative to the centre.
    vertices: Vec<P>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ClumpSpec {
    center: P,
    /// `[x, y, r]` of each disk, centres relative to `center`.
    disks: Vec<Exact<f64, 3>>,
}

fn clump_disks(disks: &[Exact<f64, 3>]) -> Vec<(DVec2, f64)> {
    disks.iter().map(|d| (DVec2::new(d[0], d[1]), d[2])).collect()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RegularSpec {
    center: P,
    radius: f64,
    sides: usize,
    angle: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BodyFileSpec {
    disk: Option<DiskSpec>,
    polygon: Option<PolygonSpec>,
    regular: Option<RegularSpec>,
    clump: Option<ClumpSpec>,
    material: Option<String>,
    velocity: Option<P>,
    spin: Option<f64>,
    angle: Option<f64>,
    fixed: Option<bool>,
    tag: Option<u32>,
    force: Option<P>,
    lock_rotation: Option<bool>,
    mass: Option<f64>,
    hold_velocity: Option<Vec<String>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum GenerateKind {
    /// Grains on a square lattice filling the region from the bottom.
    Grid,
    /// Geometric deposition: a dense packing already in contact (disks only).
    Deposition,
    /// A pyramid of square boxes (side 2 r_min) standing on `region.min`, `base` boxes wide.
    Pyramid,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GenerateSpec {
    kind: GenerateKind,
    /// Number of grains (grid, deposition).
    count: Option<usize>,
    /// Boxes in the bottom row (pyramid).
    base: Option<usize>,
    /// `[r_min, r_max]`, radii uniform in between (for polygons: circumradius).
    radius: P,
    region: BoxSpec,
    /// Polygon grains with this many sides (default: disks).
    sides: Option<usize>,
    /// Clump grains shaped as these disks (`[x, y, r]` each), scaled so that the clump's
    /// bounding radius is the grain's radius, turned at random.
    clump: Option<Vec<Exact<f64, 3>>>,
    /// Polygon grains shaped as this outline (`[x, y]` each; concave or not), scaled so that
    /// its bounding radius about its centroid is the grain's radius, turned at random.
    polygon: Option<Vec<P>>,
    material: Option<String>,
    /// Materials given to successive layers (with `layers`).
    materials: Option<Vec<String>>,
    /// Split the grains, in generation order (bottom to top), into this many tagged layers.
    layers: Option<usize>,
    /// Extra room between grid neighbours (default 2 % of r_max).
    spacing: Option<f64>,
    velocity: Option<P>,
    /// The grains are fixed, moving at `velocity` (a rough floor, a belt, a shear cell's plate).
    fixed: Option<bool>,
    /// The first layer's tag (default 0); the next layers count up from it.
    tag: Option<u32>,
    seed: Option<u64>,
}

fn v(p: P) -> DVec2 {
    DVec2::new(p[0], p[1])
}

fn finite(p: &[f64]) -> bool {
    p.iter().all(|x| x.is_finite())
}

fn check_law(law: &LawSpec) -> Result<Interaction, String> {
    let law = Interaction {
        friction: law.friction.unwrap_or(0.0),
        restitution: law.restitution.unwrap_or(0.0),
        cohesion: law.cohesion.unwrap_or(0.0),
        rolling_resistance: law.rolling_resistance.unwrap_or(0.0),
    };
    law.check()?;
    Ok(law)
}

/// Builds a scene from its parsed file, one named part at a time; every error names the line
/// and the field, warnings gather as it goes.
struct Builder<'a> {
    file: &'a SceneFile,
    cx: Ctx<'a>,
    warnings: Vec<String>,
    notes: Vec<String>,
    /// The smallest grain radius (generated grains: their drawn radius), for the default alert.
    smallest_radius: f64,
}

pub(super) fn build(text: &str, origin: &Path) -> Result<Scene, SceneError> {
    let file: SceneFile = from_toml(text, origin)?;
    let mut b = Builder {
        file: &file,
        cx: Ctx { text, origin },
        warnings: Vec::new(),
        notes: Vec::new(),
        smallest_radius: f64::INFINITY,
    };
    let effects = b.effects()?;
    let materials = b.materials(&effects)?;
    let mut world = World::new(effects, materials);
    b.walls(&mut world)?;
    b.bodies(&mut world)?;
    b.smallest_radius = (0..world.bodies.len()).map(|k| world.bodies.radius_of(k)).fold(f64::INFINITY, f64::min);
    b.generators(&mut world)?;
    b.grains(&mut world)?;
    if world.bodies.is_empty() {
        return b.cx.err(0..0, "body", "the scene has no bodies (add [[body]], [[generate]] or [[grains]])");
    }
    b.periodic(&mut world)?;
    let settings = b.settings(&effects)?;
    let output = b.output()?;
    Ok(Scene {
        name: super::scene_name(&b.cx, file.name.as_ref(), origin, "scene")?,
        description: file.description.clone().unwrap_or_default(),
        world,
        settings,
        steps: file.time.get_ref().steps,
        output,
        warnings: b.warnings,
        notes: b.notes,
    })
}

impl Builder<'_> {
    /// The effects named, and gravity.
    fn effects(&mut self) -> Result<Effects, SceneError> {
        let mut effects = Effects::default();
        for e in &self.file.effects {
            match *e.get_ref() {
                Effect::Gravity => effects.gravity = Some(DVec2::new(0.0, -9.81)),
                Effect::Friction => effects.friction = true,
                Effect::Rotation => effects.rotation = true,
                Effect::Restitution => effects.restitution = true,
                Effect::Cohesion => effects.cohesion = true,
                Effect::MovingWalls => effects.moving_walls = true,
                Effect::RollingResistance => effects.rolling_resistance = true,
            }
        }
        if let Some(g) = &self.file.gravity {
            if !finite(&g.get_ref()[..]) {
                return self.cx.err(g.span(), "gravity", "must be finite");
            }
            if effects.gravity.is_some() {
                effects.gravity = Some(v(*g.get_ref()));
            } else {
                self.warnings.push("`gravity` is given but the effect `gravity` is not named: gravity is off".into());
            }
        }

        Ok(effects)
    }

    /// Materials, the default contact law and the per-pair interactions.
    fn materials(&mut self, effects: &Effects) -> Result<Materials, SceneError> {
        if self.file.material.is_empty() {
            return self.cx.err(0..0, "material", "a scene needs at least one [[material]] (name, density)");
        }
        let mut names = Vec::new();
        let mut density = Vec::new();
        for (k, m) in self.file.material.iter().enumerate() {
            let spec = m.get_ref();
            if names.contains(&spec.name) {
                return self.cx.err(
                    m.span(),
                    format!("material[{k}].name"),
                    format!("material {:?} is defined twice", spec.name),
                );
            }
            if !(spec.density.is_finite() && spec.density > 0.0) {
                return self.cx.err(
                    m.span(),
                    format!("material[{k}].density"),
                    format!("{} must be finite and > 0", spec.density),
                );
            }
            names.push(spec.name.clone());
            density.push(spec.density);
        }
        let default_law = match &self.file.contact {
            Some(c) => check_law(c.get_ref()).or_else(|m| self.cx.err(c.span(), "contact", m))?,
            None => Interaction::default(),
        };
        let mut materials = Materials::new(names, density, default_law);
        for (k, p) in self.file.interaction.iter().enumerate() {
            let spec = p.get_ref();
            let law = check_law(&LawSpec {
                friction: spec.friction,
                restitution: spec.restitution,
                cohesion: spec.cohesion,
                rolling_resistance: spec.rolling_resistance,
            })
            .or_else(|m| self.cx.err(p.span(), format!("interaction[{k}]"), m))?;
            let a =
                self.material_index(&Some(spec.materials[0].clone()), p.span(), format!("interaction[{k}].materials"))?;
            let b =
                self.material_index(&Some(spec.materials[1].clone()), p.span(), format!("interaction[{k}].materials"))?;
            materials.set(a, b, law);
            materials.set_pass_through(a, b, spec.pass_through.unwrap_or(false));
        }
        for (on, name, max) in [
            (effects.friction, "friction", materials.max_friction()),
            (effects.restitution, "restitution", materials.max_restitution()),
            (effects.cohesion, "cohesion", materials.max_cohesion()),
            (effects.rolling_resistance, "rolling_resistance", materials.max_rolling_resistance()),
        ] {
            if !on && max > 0.0 {
                self.warnings
                    .push(format!("{name} coefficients are given but the effect `{name}` is not named: {name} is off"));
            }
            if on && max == 0.0 {
                self.warnings.push(format!("the effect `{name}` is named but every {name} coefficient is 0"));
            }
        }

        Ok(materials)
    }

    /// The index of material `name` (the first material when `None`).
    fn material_index(
        &self,
        name: &Option<String>,
        span: std::ops::Range<usize>,
        field: String,
    ) -> Result<usize, SceneError> {
        match name {
            None => Ok(0),
            Some(n) => match materials_names(self.file).iter().position(|m| m == n) {
                Some(k) => Ok(k),
                None => self.cx.err(span, field, format!("unknown material {n:?}")),
            },
        }
    }

    /// Every `[[wall]]`, each built as shapes around a centre.
    fn walls(&self, world: &mut World) -> Result<(), SceneError> {
        let effects = world.effects;
        let mut walls = Vec::new();
        for (k, w) in self.file.wall.iter().enumerate() {
            let spec = w.get_ref();
            let field = |f: &str| format!("wall[{k}].{f}");
            let material = self.material_index(&spec.material, w.span(), field("material"))?;
            let velocity = spec.velocity.map(v).unwrap_or(DVec2::ZERO);
            let spin = spec.angular_velocity.unwrap_or(0.0);
            if !velocity.is_finite() || !spin.is_finite() {
                return self.cx.err(w.span(), field("velocity"), "must be finite");
            }
            if (velocity != DVec2::ZERO || spin != 0.0) && !effects.moving_walls {
                return self.cx.err(
                    w.span(),
                    field("velocity"),
                    "a moving wall needs the effect `moving_walls` in `effects`",
                );
            }
            let shapes = [
                spec.segment.is_some(),
                spec.solid_box.is_some(),
                spec.container.is_some(),
                spec.polygon.is_some(),
                spec.drum.is_some(),
            ];
            if shapes.iter().filter(|&&s| s).count() != 1 {
                return self.cx.err(
                    w.span(),
                    format!("wall[{k}]"),
                    "give exactly one of segment, box, container, polygon, drum",
                );
            }
            // Every wall is built as (local shapes around a centre).
            let mut parts: Vec<(WallShape, DVec2)> = Vec::new();
            let segment_part = |a: DVec2, b: DVec2, c: DVec2| (WallShape::Segment { a: a - c, b: b - c }, c);
            if let Some(Exact([a, b])) = spec.segment {
                if !finite(&[a[0], a[1], b[0], b[1]]) || v(a) == v(b) {
                    return self.cx.err(w.span(), field("segment"), "endpoints must be finite and distinct");
                }
                let c = spec.center.map(v).unwrap_or((v(a) + v(b)) / 2.0);
                parts.push(segment_part(v(a), v(b), c));
            }
            let check_box = |b: &BoxSpec, f: &str| -> Result<(DVec2, DVec2), SceneError> {
                if !finite(&[b.min[0], b.min[1], b.max[0], b.max[1]]) || b.min[0] >= b.max[0] || b.min[1] >= b.max[1] {
                    return self.cx.err(w.span(), field(f), "needs finite min < max");
                }
                Ok((v(b.min), v(b.max)))
            };
            let mut polygon_vertices: Option<Vec<DVec2>> = None;
            if let Some(b) = &spec.solid_box {
                let (lo, hi) = check_box(b, "box")?;
                polygon_vertices = Some(vec![lo, DVec2::new(hi.x, lo.y), hi, DVec2::new(lo.x, hi.y)]);
            }
            if let Some(p) = &spec.polygon {
                polygon_vertices = Some(p.iter().map(|x| v(*x)).collect());
            }
            if let Some(vertices) = polygon_vertices {
                let wall = Wall::polygon(&vertices, spec.center.map(v), material)
                    .or_else(|m| self.cx.err(w.span(), field("polygon"), m))?;
                parts.push((wall.shape, wall.center));
            }
            if let Some(b) = &spec.container {
                let (lo, hi) = check_box(b, "container")?;
                let c = spec.center.map(v).unwrap_or((lo + hi) / 2.0);
                let (bl, br, tl, tr) = (lo, DVec2::new(hi.x, lo.y), DVec2::new(lo.x, hi.y), hi);
                parts.push(segment_part(tl, bl, c));
                parts.push(segment_part(bl, br, c));
                parts.push(segment_part(br, tr, c));
            }
            if let Some(d) = &spec.drum {
                let ring = Wall::drum(v(d.center), d.radius, d.sides, spec.center.map(v), material)
                    .or_else(|m| self.cx.err(w.span(), field("drum"), m))?;
                parts.extend(ring.into_iter().map(|w| (w.shape, w.center)));
            }
            for (shape, center) in parts {
                walls.push(Wall { shape, center, angle: 0.0, velocity, spin, material });
            }
        }

        world.walls.extend(walls);
        Ok(())
    }

    /// Every `[[body]]`.
    fn bodies(&mut self, world: &mut World) -> Result<(), SceneError> {
        let effects = world.effects;
        for (k, b) in self.file.body.iter().enumerate() {
            let spec = b.get_ref();
            let field = |f: &str| format!("body[{k}].{f}");
            let material = self.material_index(&spec.material, b.span(), field("material"))?;
            let mut body = match (&spec.disk, &spec.polygon, &spec.regular, &spec.clump) {
                (Some(d), None, None, None) => BodySpec::disk(v(d.center), d.radius, material),
                (None, Some(p), None, None) => {
                    BodySpec::polygon(v(p.center), p.vertices.iter().map(|x| v(*x)).collect(), material)
                }
                (None, None, None, Some(c)) => BodySpec::clump(v(c.center), clump_disks(&c.disks), material),
                (None, None, Some(r), None) => {
                    if r.sides < 3 || r.sides > MAX_POLYGON_SIDES {
                        return self.cx.err(
                            b.span(),
                            field("regular.sides"),
                            format!("{} sides: a polygon needs 3 to {MAX_POLYGON_SIDES}", r.sides),
                        );
                    }
                    BodySpec::regular_polygon(v(r.center), r.radius, r.sides, 0.0, material)
                }
                _ => {
                    return self.cx.err(
                        b.span(),
                        format!("body[{k}]"),
                        "give exactly one of disk, polygon, regular, clump",
                    )
                }
            };
            body.velocity = spec.velocity.map(v).unwrap_or(DVec2::ZERO);
            body.spin = spec.spin.unwrap_or(0.0);
            body.angle = spec.angle.or(spec.regular.as_ref().and_then(|r| r.angle)).unwrap_or(0.0);
            body.fixed = spec.fixed.unwrap_or(false);
            body.tag = spec.tag.unwrap_or(0);
            body.force = spec.force.map(v).unwrap_or(DVec2::ZERO);
            body.lock_rotation = spec.lock_rotation.unwrap_or(false);
            body.mass = spec.mass;
            for axis in spec.hold_velocity.iter().flatten() {
                if let Err(e) = body.hold_axis(axis) {
                    return self.cx.err(b.span(), format!("body[{k}].hold_velocity"), e);
                }
            }
            if body.spin != 0.0 && !effects.rotation {
                self.warnings
                    .push(format!("body[{k}] has a spin but the effect `rotation` is not named: it is ignored"));
            }
            let density = world.materials.density[material];
            world.bodies.add(&body, density).or_else(|m| self.cx.err(b.span(), format!("body[{k}]"), m))?;
        }

        Ok(())
    }

    /// Every `[[generate]]`: grids, depositions, pyramids.
    fn generators(&mut self, world: &mut World) -> Result<(), SceneError> {
        for (k, g) in self.file.generate.iter().enumerate() {
            let spec = g.get_ref();
            let field = |f: &str| format!("generate[{k}].{f}");
            let [r_min, r_max] = spec.radius.0;
            if !(r_min.is_finite() && r_max.is_finite() && r_min > 0.0 && r_min <= r_max) {
                return self.cx.err(
                    g.span(),
                    field("radius"),
                    format!("[{r_min}, {r_max}] must satisfy 0 < r_min <= r_max"),
                );
            }
            let (lo, hi) = (v(spec.region.min), v(spec.region.max));
            if !(lo.is_finite() && hi.is_finite() && lo.x < hi.x && lo.y < hi.y) {
                return self.cx.err(g.span(), field("region"), "needs finite min < max");
            }
            let count = match (spec.kind, spec.count, spec.base) {
                (GenerateKind::Pyramid, _, Some(b)) if b > MAX_PYRAMID_BASE => {
                    return self.cx.err(
                        g.span(),
                        field("base"),
                        format!("{b} is more than the {MAX_PYRAMID_BASE} a scene may generate"),
                    )
                }
                (_, Some(c), _) if c > MAX_GENERATED => {
                    return self.cx.err(
                        g.span(),
                        field("count"),
                        format!("{c} is more than the {MAX_GENERATED} grains a generator may make"),
                    )
                }
                (GenerateKind::Pyramid, _, Some(b)) if b >= 1 => b * (b + 1) / 2,
                (GenerateKind::Pyramid, _, _) => {
                    return self.cx.err(g.span(), field("base"), "a pyramid needs base >= 1")
                }
                (_, Some(c), _) if c >= 1 => c,
                _ => return self.cx.err(g.span(), field("count"), "needs count >= 1"),
            };
            let layer_materials: Vec<usize> = match (&spec.materials, &spec.material) {
                (Some(list), _) if !list.is_empty() => list
                    .iter()
                    .map(|n| self.material_index(&Some(n.clone()), g.span(), field("materials")))
                    .collect::<Result<_, _>>()?,
                (_, m) => vec![self.material_index(m, g.span(), field("material"))?],
            };
            let layers = spec.layers.unwrap_or(1).max(1);
            let seed = spec.seed.unwrap_or(k as u64);
            let shapes = [spec.sides.is_some(), spec.clump.is_some(), spec.polygon.is_some()];
            if shapes.iter().filter(|&&s| s).count() > 1 {
                let second = if spec.polygon.is_some() { "polygon" } else { "clump" };
                return self.cx.err(g.span(), field(second), "give only one of sides, clump and polygon");
            }
            let outline = match (&spec.polygon, spec.kind) {
                (None, _) => None,
                (Some(_), GenerateKind::Grid) => {
                    let vertices: Vec<DVec2> = spec.polygon.iter().flatten().map(|p| v(*p)).collect();
                    Some(
                        crate::world::unit_polygon(&vertices)
                            .or_else(|m| self.cx.err(g.span(), field("polygon"), m))?,
                    )
                }
                (Some(_), _) => return self.cx.err(g.span(), field("polygon"), "polygon grains need kind = \"grid\""),
            };
            let template = match (&spec.clump, spec.sides, spec.kind) {
                (None, _, _) | (Some(_), Some(_), _) => None,
                (Some(_), _, GenerateKind::Pyramid) => {
                    return self.cx.err(
                        g.span(),
                        field("clump"),
                        "a pyramid is made of boxes; clumps need grid or deposition",
                    )
                }
                (Some(disks), None, _) => Some(
                    crate::world::unit_clump(&clump_disks(disks))
                        .or_else(|m| self.cx.err(g.span(), field("clump"), m))?,
                ),
            };
            let (centers, radii) = self.layout(k, g, count, seed)?;
            let velocity = spec.velocity.map(v).unwrap_or(DVec2::ZERO);
            let mut rng_angle = rand::rngs::SmallRng::seed_from_u64(seed ^ 0x9e37_79b9);
            for (n, (c, r)) in centers.iter().zip(&radii).enumerate() {
                let layer = n * layers / centers.len();
                let material = layer_materials[layer % layer_materials.len()];
                let mut body = match spec.sides {
                    _ if spec.kind == GenerateKind::Pyramid => {
                        let h = *r;
                        let square = vec![DVec2::new(-h, -h), DVec2::new(h, -h), DVec2::new(h, h), DVec2::new(-h, h)];
                        BodySpec::polygon(*c, square, material)
                    }
                    None if template.is_some() => {
                        use rand::Rng;
                        let disks = template.iter().flatten().map(|(o, d)| (*o * *r, d * *r)).collect();
                        let mut clump = BodySpec::clump(*c, disks, material);
                        clump.angle = rng_angle.gen_range(0.0..std::f64::consts::TAU);
                        clump
                    }
                    None if outline.is_some() => {
                        use rand::Rng;
                        let vertices = outline.iter().flatten().map(|p| *p * *r).collect();
                        let mut polygon = BodySpec::polygon(*c, vertices, material);
                        polygon.angle = rng_angle.gen_range(0.0..std::f64::consts::TAU);
                        polygon
                    }
                    None => BodySpec::disk(*c, *r, material),
                    Some(s) if (3..=MAX_POLYGON_SIDES).contains(&s) => {
                        use rand::Rng;
                        let angle = rng_angle.gen_range(0.0..std::f64::consts::TAU);
                        BodySpec::regular_polygon(*c, *r, s, angle, material)
                    }
                    Some(s) => {
                        return self.cx.err(
                            g.span(),
                            field("sides"),
                            format!("{s} sides: a polygon needs 3 to {MAX_POLYGON_SIDES}"),
                        )
                    }
                };
                body.velocity = velocity;
                body.fixed = spec.fixed.unwrap_or(false);
                body.tag = spec.tag.unwrap_or(0).saturating_add(layer as u32);
                let density = world.materials.density[material];
                world.bodies.add(&body, density).or_else(|m| self.cx.err(g.span(), format!("generate[{k}]"), m))?;
                self.smallest_radius = self.smallest_radius.min(*r);
            }
        }
        Ok(())
    }

    /// Centres and radii of generator `k`'s `count` grains (checked sizes and region).
    fn layout(
        &self,
        k: usize,
        g: &Spanned<GenerateSpec>,
        count: usize,
        seed: u64,
    ) -> Result<(Vec<DVec2>, Vec<f64>), SceneError> {
        let spec = g.get_ref();
        let field = |f: &str| format!("generate[{k}].{f}");
        let [r_min, r_max] = spec.radius.0;
        let (lo, hi) = (v(spec.region.min), v(spec.region.max));
        Ok(match spec.kind {
            GenerateKind::Grid => {
                let spacing = spec.spacing.unwrap_or(0.02 * r_max);
                generate::grid_fill(lo, hi, count, r_min, r_max, spacing, seed)
                    .or_else(|m| self.cx.err(g.span(), field("count"), m))?
            }
            GenerateKind::Deposition => {
                if spec.sides.is_some() {
                    return self.cx.err(
                        g.span(),
                        field("sides"),
                        "deposition generates disks only; use kind = \"grid\" for polygons",
                    );
                }
                if hi.x - lo.x < 2.0 * r_max {
                    return self.cx.err(g.span(), field("region"), "narrower than one grain");
                }
                let (c, r) = deposition::deposit_disks(lo.x, hi.x, lo.y, count, r_min, r_max, seed);
                if let Some(top) = c.iter().zip(&r).map(|(c, r)| c.y + r).reduce(f64::max) {
                    if top > hi.y {
                        return self.cx.err(
                            g.span(),
                            field("region"),
                            format!("{count} grains pile up to y = {top:.4}, above the region's top {}", hi.y),
                        );
                    }
                }
                (c, r)
            }
            GenerateKind::Pyramid => {
                let base = spec.base.unwrap_or(1);
                let side = 2.0 * r_min;
                let mut centers = Vec::with_capacity(count);
                for row in 0..base {
                    for k in 0..base - row {
                        centers.push(
                            lo + DVec2::new((row as f64 / 2.0 + k as f64 + 0.5) * side, (row as f64 + 0.5) * side),
                        );
                    }
                }
                (centers, vec![r_min; count])
            }
        })
    }

    /// Every `[[grains]]` file.
    fn grains(&mut self, world: &mut World) -> Result<(), SceneError> {
        let effects = world.effects;
        for (k, g) in self.file.grains.iter().enumerate() {
            let spec = g.get_ref();
            let field = |f: &str| format!("grains[{k}].{f}");
            let material = self.material_index(&spec.material, g.span(), field("material"))?;
            let path = self.cx.origin.parent().unwrap_or(Path::new(".")).join(&spec.file);
            let rows = grains_csv::read_grains(&path, MAX_GENERATED, &world.materials.names)
                .or_else(|m| self.cx.err(g.span(), field("file"), m))?;
            let asked = grains_csv::GrainOrder::from_name(spec.order.as_deref().unwrap_or("auto"))
                .or_else(|m| self.cx.err(g.span(), field("order"), m))?;
            let order = asked.resolved(&rows);
            if asked != order && order == grains_csv::GrainOrder::Space {
                self.notes.push(format!(
                    "grains[{k}]: the {} grains of {} lie in no spatial order: numbered in rows across the packing \
                     (order = \"file\" keeps the file's)",
                    rows.len(),
                    path.display()
                ));
            }
            for (n, row) in order.numbering(&rows).into_iter().map(|n| (n, &rows[n])) {
                // A file's material column names each grain's; [[grains]] material the rest.
                let body = row.body(material);
                world.bodies.add(&body, world.materials.density[body.material]).or_else(|m| {
                    self.cx.err(g.span(), field("file"), format!("{}: grain {}: {m}", path.display(), n + 1))
                })?;
                self.smallest_radius = self.smallest_radius.min(row.radius);
            }
            if rows.iter().any(|r| r.spin != 0.0) && !effects.rotation {
                self.warnings
                    .push(format!("grains[{k}] have spins but the effect `rotation` is not named: they are ignored"));
            }
        }
        Ok(())
    }

    /// The periodic cell, if any (the grains wrapped into it).
    fn periodic(&self, world: &mut World) -> Result<(), SceneError> {
        if let Some(p) = &self.file.periodic {
            let [x0, x1] = p.get_ref().x;
            world.set_periodic(x0, x1).or_else(|e| {
                let why = match e {
                    WorldError::Periodic(m) => m,
                    other => other.to_string(),
                };
                self.cx.err(p.span(), "periodic.x", why)
            })?;
        }
        Ok(())
    }

    /// Time step, solver and detection, checked together.
    fn settings(&self, effects: &Effects) -> Result<StepSettings, SceneError> {
        let time = self.file.time.get_ref();
        let solver = self.file.solver.as_ref().map(|s| s.get_ref());
        let solver_span = self.file.solver.as_ref().map(|s| s.span()).unwrap_or(0..0);
        let kind = match solver.and_then(|s| s.name.as_deref()) {
            None => SolverKind::Nlgs,
            Some(n) => SolverKind::from_name(&n.to_lowercase()).or_else(|_| {
                let known: Vec<_> = SolverKind::ALL.iter().map(|k| k.name()).collect();
                self.cx.err(
                    solver_span.clone(),
                    "solver.name",
                    format!("unknown solver {n:?} (one of {})", known.join(", ")),
                )
            })?,
        };
        let mut options = SolverOptions { tol: 1e-4, max_iter: 10_000, ..SolverOptions::default() };
        if let Some(s) = solver {
            options.tol = s.tol.unwrap_or(options.tol);
            options.max_iter = s.max_iter.unwrap_or(options.max_iter);
            options.omega = s.omega.unwrap_or(1.0);
            options.anderson = s.anderson.unwrap_or(0);
            options.focus = s.focus.unwrap_or(0);
            options.block_sweeps = s.block_sweeps.unwrap_or(0);
            if let Some(c) = &s.criterion {
                options.criterion = StopCriterion::from_name(c)
                    .or_else(|why| self.cx.err(solver_span.clone(), "solver.criterion", why))?;
            }
            if let Some(o) = &s.ordering {
                options.ordering = Ordering::from_name(o).or_else(|_| {
                    self.cx.err(solver_span.clone(), "solver.ordering", format!("unknown ordering {o:?}"))
                })?;
            }
        }
        let alert = match self.file.detection.as_ref().and_then(|d| d.get_ref().alert) {
            Some(a) => a,
            None => crate::stepping::DEFAULT_ALERT_FRACTION * self.smallest_radius,
        };
        let projection_slack = time.projection_slack.unwrap_or(crate::stepping::DEFAULT_PROJECTION_SLACK);
        let theta = time.theta.unwrap_or(0.5);
        let settings = StepSettings { h: time.step, theta, alert, projection_slack, solver: kind, options };
        if let Err(m) = settings.validate() {
            let span = if m.contains("alert") { self.file.detection.as_ref().map(|d| d.span()) } else { None };
            return self.cx.err(span.unwrap_or_else(|| self.file.time.span()), "time/solver/detection", m);
        }
        if effects.rolling_resistance {
            if !effects.rotation {
                let span =
                    self.file.effects.iter().find(|e| *e.get_ref() == Effect::RollingResistance).map(|e| e.span());
                return self.cx.err(
                    span.unwrap_or(0..0),
                    "effects",
                    "rolling_resistance needs the effect `rotation` (it resists spins)",
                );
            }
            if let Some(why) = crate::solvers::rolling_refusal(true, kind, settings.options.criterion) {
                return self.cx.err(solver_span, "solver", why);
            }
        }
        Ok(settings)
    }

    /// The number of steps checked, and what to write.
    fn output(&self) -> Result<OutputSettings, SceneError> {
        let time = self.file.time.get_ref();
        if time.steps == 0 {
            return self.cx.err(self.file.time.span(), "time.steps", "must be >= 1");
        }
        if let Some(o) = self.file.output.as_ref().filter(|o| o.get_ref().every == Some(0)) {
            return self.cx.err(o.span(), "output.every", "must be >= 1 (`vtk = false` writes no VTK)");
        }
        if let Some(o) = self.file.output.as_ref().filter(|o| o.get_ref().picture_step == Some(0)) {
            return self.cx.err(o.span(), "output.picture_step", "steps count from 1");
        }
        let output = self.file.output.as_ref().map(|o| o.get_ref());
        Ok(OutputSettings {
            every: output.and_then(|o| o.every).unwrap_or(1),
            vtk: output.and_then(|o| o.vtk).unwrap_or(false),
            picture_step: output.and_then(|o| o.picture_step),
            checkpoint_every: output.and_then(|o| o.checkpoint_every).unwrap_or(0),
            wall_forces: output.and_then(|o| o.wall_forces).unwrap_or(false),
            profile: output.and_then(|o| o.profile).unwrap_or(false),
        })
    }
}

fn materials_names(file: &SceneFile) -> Vec<String> {
    file.material.iter().map(|m| m.get_ref().name.clone()).collect()
}

use rand::SeedableRng;
