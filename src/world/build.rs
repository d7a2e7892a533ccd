//! A world built in code (by a Rust, Python or C host) checked as a scene file is: what a file
//! refuses, a host cannot give either.

use glam::DVec2;

use super::{BodySpec, Effects, Interaction, Materials, Periodic, Wall, WallShape, World};

/// An input of a world built in code, refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WorldError {
    /// No material at all.
    #[error("a world needs at least one material")]
    NoMaterial,
    /// Two materials of one name.
    #[error("material {0:?} is defined twice")]
    DuplicateMaterial(String),
    /// A density that is not a positive number.
    #[error("material {name:?}: density {density} must be finite and > 0")]
    Density {
        /// The material.
        name: String,
        /// The density given.
        density: f64,
    },
    /// No material of this name.
    #[error("material {0:?} does not exist")]
    UnknownMaterial(String),
    /// A contact law out of range.
    #[error("contact law: {0}")]
    Law(String),
    /// Gravity that is not finite.
    #[error("gravity [{}, {}] must be finite", .0.x, .0.y)]
    Gravity(DVec2),
    /// A wall's geometry or motion out of range.
    #[error("wall {index}: {message}")]
    Wall {
        /// The wall's index.
        index: usize,
        /// What is wrong.
        message: String,
    },
    /// A body refused.
    #[error("{0}")]
    Body(String),
    /// A periodic cell refused, or a body too wide for it.
    #[error("periodic cell x: {0}")]
    Periodic(String),
}

impl Interaction {
    /// Refuses coefficients a scene file refuses: negative or not finite, restitution above 1.
    pub fn check(&self) -> Result<(), String> {
        let values = [
            ("friction", self.friction),
            ("restitution", self.restitution),
            ("cohesion", self.cohesion),
            ("rolling_resistance", self.rolling_resistance),
        ];
        if let Some((name, x)) = values.into_iter().find(|(_, x)| !(x.is_finite() && *x >= 0.0)) {
            return Err(format!("{name} {x} must be finite and >= 0"));
        }
        if self.restitution > 1.0 {
            return Err(format!("restitution {} must be <= 1", self.restitution));
        }
        Ok(())
    }
}

impl Wall {
    /// Refuses a wall a scene file refuses: coordinates or a motion that are not finite, a
    /// segment whose endpoints coincide, a polygon of fewer than three vertices.
    pub fn check(&self) -> Result<(), String> {
        let finite = |v: DVec2| v.is_finite();
        match &self.shape {
            WallShape::Segment { a, b } if !finite(*a) || !finite(*b) || a == b => {
                return Err("segment endpoints must be finite and distinct".into());
            }
            WallShape::Polygon(p) => super::bodies::check_vertices(&p.vertices)?,
            _ => {}
        }
        if !finite(self.center) || !self.angle.is_finite() {
            return Err("centre and angle must be finite".into());
        }
        if !finite(self.velocity) || !self.spin.is_finite() {
            return Err("velocity and spin must be finite".into());
        }
        Ok(())
    }
}

impl World {
    /// An empty world of the materials `(name, density)`, one contact law for every pair (which
    /// [`Self::set_interaction`] changes per pair): friction, restitution, cohesion and rolling
    /// resistance are on where the law has them; gravity, rotation and moving walls as asked.
    pub fn in_code(
        materials: Vec<(String, f64)>,
        law: Interaction,
        gravity: Option<DVec2>,
        rotation: bool,
        moving_walls: bool,
    ) -> Result<Self, WorldError> {
        law.check().map_err(WorldError::Law)?;
        if let Some(g) = gravity.filter(|g| !g.is_finite()) {
            return Err(WorldError::Gravity(g));
        }
        let effects = Effects { gravity, rotation, moving_walls, ..Effects::default() };
        let (names, density) = materials.into_iter().unzip();
        let mut world = World::new(effects, Materials::new(names, density, law));
        world.check_materials()?;
        world.switch_on(law);
        Ok(world)
    }

    /// The index of the material called `name`.
    pub fn material_named(&self, name: &str) -> Result<usize, WorldError> {
        self.materials.index_of(name).ok_or_else(|| WorldError::UnknownMaterial(name.into()))
    }

    /// The contact law between materials `a` and `b`; an effect the law needs is switched on.
    pub fn set_interaction(&mut self, a: &str, b: &str, law: Interaction) -> Result<(), WorldError> {
        law.check().map_err(WorldError::Law)?;
        let (a, b) = (self.material_named(a)?, self.material_named(b)?);
        self.set_law(a, b, law);
        Ok(())
    }

    /// Makes the bodies and walls of materials `a` and `b` pass through each other (`through`),
    /// or touch again: a scene's `[[interaction]] pass_through = true`.
    pub fn set_pass_through(&mut self, a: &str, b: &str, through: bool) -> Result<(), WorldError> {
        let (a, b) = (self.material_named(a)?, self.material_named(b)?);
        self.materials.set_pass_through(a, b, through);
        Ok(())
    }

    fn set_law(&mut self, a: usize, b: usize, law: Interaction) {
        self.switch_on(law);
        self.materials.set(a, b, law);
    }

    /// The effects `law` needs, on.
    fn switch_on(&mut self, law: Interaction) {
        let e = &mut self.effects;
        e.friction |= law.friction > 0.0;
        e.restitution |= law.restitution > 0.0;
        e.cohesion |= law.cohesion > 0.0;
        e.rolling_resistance |= law.rolling_resistance > 0.0;
    }

    /// Adds a body of its material's density; returns its index.
    pub fn add_body(&mut self, spec: &BodySpec) -> Result<usize, WorldError> {
        let density = *self.materials.density.get(spec.material).ok_or_else(|| {
            WorldError::Body(format!("material {} does not exist ({} materials)", spec.material, self.materials.len()))
        })?;
        if spec.spin != 0.0 && !self.effects.rotation {
            return Err(WorldError::Body(format!(
                "spin {} needs the effect rotation (bodies of this world do not turn)",
                spec.spin
            )));
        }
        let k = self.bodies.add(spec, density).map_err(WorldError::Body)?;
        if let Some(cell) = self.periodic {
            if let Err(why) = self.fits_cell(cell, k..k + 1) {
                self.bodies.remove(k);
                return Err(WorldError::Periodic(why));
            }
            self.bodies.position[k].x = cell.wrap(self.bodies.position[k].x);
        }
        Ok(k)
    }

    /// Makes the world periodic along x over `[x0, x1)`: a grain that leaves at `x1` comes back at
    /// `x0`, and grains touch through the boundary. Every body is brought into the cell, and the
    /// bodies added later too. The cell must be at least four of its widest bodies long.
    pub fn set_periodic(&mut self, x0: f64, x1: f64) -> Result<(), WorldError> {
        let cell = Periodic::new(x0, x1).map_err(WorldError::Periodic)?;
        self.fits_cell(cell, 0..self.bodies.len()).map_err(WorldError::Periodic)?;
        self.periodic = Some(cell);
        self.wrap_positions();
        Ok(())
    }

    /// Whether the bodies `range` fit `cell`: a pair must touch directly or through the boundary,
    /// never both, so the cell is at least four of the widest bodies long.
    fn fits_cell(&self, cell: Periodic, range: std::ops::Range<usize>) -> Result<(), String> {
        let widest = self.bodies.bounding_radius[range].iter().fold(0.0f64, |m, r| m.max(2.0 * r));
        if cell.length() < 4.0 * widest {
            return Err(format!(
                "the cell is {:e} m long: at least 4 of its widest bodies ({widest:e} m) must fit",
                cell.length()
            ));
        }
        Ok(())
    }

    /// Adds a wall; returns its index.
    pub fn add_wall(&mut self, wall: Wall) -> Result<usize, WorldError> {
        Ok(self.add_walls(vec![wall])?.start)
    }

    /// Adds walls that stand together (a drum's segments); returns their indices. None is added
    /// when one is refused.
    pub fn add_walls(&mut self, walls: Vec<Wall>) -> Result<std::ops::Range<usize>, WorldError> {
        let first = self.walls.len();
        walls.iter().enumerate().try_for_each(|(k, w)| self.check_wall(first + k, w))?;
        self.walls.extend(walls);
        Ok(first..self.walls.len())
    }

    /// Whether `wall` may stand as wall `index` of this world: its material, its motion (the
    /// effect moving_walls) and its geometry.
    pub(crate) fn check_wall(&self, index: usize, wall: &Wall) -> Result<(), WorldError> {
        let refuse = |message: String| Err(WorldError::Wall { index, message });
        if wall.material >= self.materials.len() {
            return refuse(format!("material {} does not exist ({} materials)", wall.material, self.materials.len()));
        }
        if wall.is_moving() && !self.effects.moving_walls {
            return refuse("a wall with a velocity or a spin needs the effect moving_walls".into());
        }
        wall.check().or_else(refuse)
    }

    fn check_materials(&self) -> Result<(), WorldError> {
        let m = &self.materials;
        if m.is_empty() {
            return Err(WorldError::NoMaterial);
        }
        for (k, (name, &density)) in m.names.iter().zip(&m.density).enumerate() {
            if m.names[..k].contains(name) {
                return Err(WorldError::DuplicateMaterial(name.clone()));
            }
            if !(density.is_finite() && density > 0.0) {
                return Err(WorldError::Density { name: name.clone(), density });
            }
        }
        Ok(())
    }

    /// Checks what a host may have set by hand (the fields are public): the materials, every
    /// pair's law, gravity, the periodic cell against the widest body, and every wall, as [`Self::in_code`] and [`Self::add_wall`] check them.
    /// Bodies are checked as they are added.
    pub fn validate(&self) -> Result<(), WorldError> {
        self.check_materials()?;
        let n = self.materials.len();
        for a in 0..n {
            for b in a..n {
                self.materials.interaction(a, b).check().map_err(|m| {
                    WorldError::Law(format!(
                        "materials {:?} and {:?}: {m}",
                        self.materials.names[a], self.materials.names[b]
                    ))
                })?;
            }
        }
        if let Some(g) = self.effects.gravity.filter(|g| !g.is_finite()) {
            return Err(WorldError::Gravity(g));
        }
        if let Some(cell) = self.periodic {
            Periodic::new(cell.x0, cell.x1)
                .and_then(|cell| self.fits_cell(cell, 0..self.bodies.len()))
                .map_err(WorldError::Periodic)?;
        }
        self.walls.iter().enumerate().try_for_each(|(k, w)| self.check_wall(k, w))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sand() -> Vec<(String, f64)> {
        vec![("sand".into(), 1600.0), ("steel".into(), 7800.0)]
    }

    #[test]
    fn a_world_in_code_refuses_what_a_scene_file_refuses_naming_it() {
        let law = Interaction { friction: 0.5, ..Interaction::default() };
        let refused = |materials, law: Interaction, gravity| World::in_code(materials, law, gravity, false, false);
        let cases: Vec<(Result<World, WorldError>, &str)> = vec![
            (refused(vec![], law, None), "at least one material"),
            (refused(vec![("a".into(), 1.0), ("a".into(), 2.0)], law, None), "material \"a\" is defined twice"),
            (refused(vec![("a".into(), f64::NAN)], law, None), "material \"a\": density NaN must be finite and > 0"),
            (refused(sand(), Interaction { restitution: 2.0, ..law }, None), "restitution 2 must be <= 1"),
            (refused(sand(), Interaction { friction: -0.1, ..law }, None), "friction -0.1 must be finite and >= 0"),
            (refused(sand(), law, Some(DVec2::new(0.0, f64::INFINITY))), "gravity [0, inf] must be finite"),
        ];
        for (result, message) in cases {
            let error = result.err().map(|e| e.to_string()).unwrap_or_default();
            assert!(error.contains(message), "{error:?} should say {message:?}");
        }
        let mut world = World::in_code(sand(), law, Some(DVec2::new(0.0, -9.81)), false, false).unwrap();
        let point = DVec2::new(1.0, 0.0);
        let walls = [
            (Wall::segment(point, point, 0), "wall 0: segment endpoints must be finite and distinct"),
            (Wall::segment(DVec2::new(f64::NAN, 0.0), point, 0), "wall 0: segment endpoints must be finite"),
            (Wall { angle: f64::INFINITY, ..Wall::segment(DVec2::ZERO, point, 0) }, "wall 0: centre and angle must be"),
            (Wall { velocity: DVec2::X, ..Wall::segment(DVec2::ZERO, point, 0) }, "needs the effect moving_walls"),
            (Wall::segment(DVec2::ZERO, point, 2), "wall 0: material 2 does not exist (2 materials)"),
        ];
        for (wall, message) in walls {
            let error = world.add_wall(wall).unwrap_err().to_string();
            assert!(error.contains(message), "{error:?} should say {message:?}");
        }
        let corners = [DVec2::ZERO, point, DVec2::new(0.5, f64::NAN)];
        assert_eq!(Wall::polygon(&corners, None, 0).unwrap_err(), "polygon vertex 2 [0.5, NaN] is not finite");
        assert_eq!(Wall::polygon(&corners[..2], None, 0).unwrap_err(), "a polygon needs at least 3 vertices, got 2");
        let thrown = BodySpec { velocity: DVec2::new(1.0, f64::INFINITY), ..BodySpec::disk(DVec2::Y, 0.1, 0) };
        assert_eq!(world.add_body(&thrown).unwrap_err().to_string(), "velocity [1, inf] must be finite");
        let glass = Interaction { restitution: 1.5, ..law };
        assert!(world.set_interaction("sand", "steel", glass).unwrap_err().to_string().contains("restitution 1.5"));
        assert_eq!(world.set_interaction("sand", "wood", law), Err(WorldError::UnknownMaterial("wood".into())));
        assert!(world.walls.is_empty() && world.validate().is_ok(), "a refused input changes nothing");
    }

    #[test]
    fn a_law_switches_its_effects_on_and_validate_finds_what_was_set_by_hand() {
        let mut world = World::in_code(sand(), Interaction::default(), None, true, false).unwrap();
        assert!(!world.effects.friction && !world.effects.restitution && world.effects.rotation);
        let law = Interaction { friction: 0.4, restitution: 0.2, ..Interaction::default() };
        world.set_interaction("steel", "sand", law).unwrap();
        assert!(world.effects.friction && world.effects.restitution && !world.effects.cohesion);
        assert_eq!(world.materials.interaction(0, 1), law);
        assert_eq!(world.materials.interaction(0, 0), Interaction::default());
        world.add_wall(Wall::segment(DVec2::ZERO, DVec2::X, 1)).unwrap();
        assert!(world.validate().is_ok());
        let spinning = BodySpec { spin: 1.0, ..BodySpec::disk(DVec2::Y, 0.1, 0) };
        assert_eq!(world.add_body(&spinning), Ok(0), "this world turns");
        world.effects.rotation = false;
        let error = world.add_body(&spinning).unwrap_err().to_string();
        assert!(error.contains("spin 1 needs the effect rotation"), "{error}");
        world.materials.set(1, 1, Interaction { cohesion: f64::NAN, ..law });
        let error = world.validate().unwrap_err().to_string();
        assert!(error.contains("materials \"steel\" and \"steel\": cohesion NaN"), "{error}");
        world.materials.set(1, 1, law);
        world.walls.push(Wall::segment(DVec2::X, DVec2::X, 0));
        assert!(world.validate().unwrap_err().to_string().starts_with("wall 1: segment endpoints"));
    }

    #[test]
    fn a_periodic_cell_in_code_wraps_its_bodies_and_refuses_one_too_wide() {
        let mut world = World::in_code(sand(), Interaction::default(), None, false, false).unwrap();
        world.add_body(&BodySpec::disk(DVec2::new(2.5, 0.0), 0.1, 0)).unwrap();
        let refused = |w: &mut World, x0, x1| w.set_periodic(x0, x1).unwrap_err().to_string();
        assert!(refused(&mut world, 1.0, f64::NAN).contains("[1, NaN] must be finite with x0 < x1"));
        let short = refused(&mut world, 0.0, 0.5);
        assert!(short.contains("the cell is 5e-1 m long: at least 4 of its widest bodies (2e-1 m)"), "{short}");
        assert_eq!(world.periodic, None, "a refused cell changes nothing");
        world.set_periodic(0.0, 1.0).unwrap();
        assert_eq!(world.bodies.position[0], DVec2::new(0.5, 0.0), "brought into the cell");
        assert_eq!(world.add_body(&BodySpec::disk(DVec2::new(-0.25, 1.0), 0.1, 0)), Ok(1));
        assert_eq!(world.bodies.position[1].x, 0.75, "a body added later too");
        let wide = world.add_body(&BodySpec::disk(DVec2::new(0.5, 3.0), 0.2, 0)).unwrap_err().to_string();
        assert!(wide.starts_with("periodic cell x: the cell is 1e0 m long"), "{wide}");
        assert_eq!(world.bodies.len(), 2, "the wide body is not kept");
        world.periodic = Some(Periodic { x0: 0.0, x1: 0.3 });
        assert!(world.validate().unwrap_err().to_string().contains("the cell is 3e-1 m long"));
    }
}
