//! A world's grains written as a grains CSV file (`x,y,r,vx,vy,spin,tag,material,fixed`, the format
//! `[[grains]]` reads, `scene/grains_csv.rs`): a packing prepared by one run (a deposit let to
//! settle) becomes the start of others, as LMGC90 hands a deposited sample to its next study.

use std::fmt::Write as _;
use std::path::Path;

use crate::scene::grains_csv::COLUMNS;
use crate::world::{BodyShape, World};

/// Why `world` cannot be written as a grains file: it holds disks, so a polygon or a clump
/// would not come back as it was.
pub fn unsavable(world: &World) -> Option<String> {
    let b = &world.bodies;
    if b.is_empty() {
        return Some("the world has no bodies".into());
    }
    (0..b.len()).find_map(|k| match b.shape[k] {
        BodyShape::Polygon(_) => Some(format!("body {k} is a polygon; a grains file holds disks")),
        BodyShape::Clump(_) => Some(format!("body {k} is a clump; a grains file holds disks")),
        _ if b.held_axes(k).contains(&true) => {
            Some(format!("body {k} holds its velocity along an axis; a grains file has no column for it"))
        }
        _ => None,
    })
}

/// The grains file's text: a header, then one row per body with every number written so that
/// it reads back to the same bits.
pub fn grains_text(world: &World) -> Result<String, String> {
    if let Some(why) = unsavable(world) {
        return Err(why);
    }
    let b = &world.bodies;
    let mut text = COLUMNS.join(",") + "\n";
    for k in 0..b.len() {
        let (p, v) = (b.position[k], b.velocity[k]);
        let material = &world.materials.names[b.material[k] as usize];
        let (r, spin, tag, fixed) = (b.radius_of(k), b.spin_of(k), b.tag[k], u8::from(b.inv_mass[k] == 0.0));
        let _ = writeln!(text, "{},{},{},{},{},{spin},{tag},{material},{fixed}", p.x, p.y, r, v.x, v.y);
    }
    Ok(text)
}

/// Writes `world`'s grains at `path` (see [`grains_text`]).
pub fn write_grains(world: &World, path: &Path) -> Result<(), String> {
    let text = grains_text(world)?;
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::*;
    use crate::scene::grains_csv::parse_grains;
    use crate::world::{BodySpec, Effects, Interaction, Materials};

    #[test]
    fn written_grains_read_back_to_the_same_bits() {
        let materials = Materials::new(vec!["m".into(), "n".into()], vec![2500.0, 900.0], Interaction::default());
        let mut world = World::new(Effects { rotation: true, ..Effects::default() }, materials);
        let m = 0;
        for k in 0..5 {
            let x = 0.1 + k as f64 / 3.0;
            let mut spec = BodySpec::disk(DVec2::new(x, x.sin() / 7.0), 0.01 + 1e-3 * x, m);
            (spec.velocity, spec.spin, spec.tag) = (DVec2::new(x / 9.0, -x), 1.0 / (k as f64 + 3.0), k);
            spec.material = (k % 2) as usize;
            world.bodies.add(&spec, [2500.0, 900.0][k as usize % 2]).unwrap();
        }
        // A fixed grain moving along x: a belt's or a shear plate's.
        let belt = BodySpec { fixed: true, velocity: DVec2::X, ..BodySpec::disk(DVec2::ZERO, 0.01, m) };
        world.bodies.add(&belt, 2500.0).unwrap();
        let names = &world.materials.names;
        let rows = parse_grains(&grains_text(&world).unwrap(), 10, names).unwrap();
        let b = &world.bodies;
        for (k, row) in rows.iter().enumerate() {
            assert_eq!((row.center, row.radius), (b.position[k], b.radius_of(k)));
            assert_eq!((row.velocity, row.spin, row.tag), (b.velocity[k], b.spin_of(k), b.tag[k]));
            assert_eq!(row.material, Some(b.material[k] as usize));
            assert_eq!(row.fixed, b.inv_mass[k] == 0.0, "body {k}");
        }
        assert_eq!(rows.len(), 6);
        assert!(rows[5].fixed && rows[5].velocity == DVec2::X, "a fixed grain keeps its motion");

        let square = vec![DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        world.bodies.add(&BodySpec::polygon(DVec2::ZERO, square, m), 2500.0).unwrap();
        assert_eq!(grains_text(&world).unwrap_err(), "body 6 is a polygon; a grains file holds disks");
    }
}
