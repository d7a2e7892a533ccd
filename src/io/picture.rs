//! A PNG picture of the current state (plotters): grains coloured by tag, walls, and the force
//! chains — a line between the centres of every loaded contact, its width proportional to the
//! normal impulse.

use std::path::Path;

use anyhow::{anyhow, Result};
use glam::DVec2;
use plotters::prelude::*;

use crate::detection::Antagonist;
use crate::stepping::Simulation;
use crate::world::BodyShape;

const PALETTE: [RGBColor; 4] =
    [RGBColor(200, 200, 205), RGBColor(230, 205, 150), RGBColor(170, 200, 230), RGBColor(210, 170, 170)];

/// Writes the picture, `width` pixels wide.
pub fn write_png(sim: &Simulation, path: &Path, width: u32) -> Result<()> {
    let world = &sim.world;
    let (lo, hi) = world.bounds();
    let span = (hi - lo).max(DVec2::splat(1e-12));
    let margin = 10.0;
    let scale = (width as f64 - 2.0 * margin) / span.x;
    let height = ((span.y * scale + 2.0 * margin).ceil() as u32).clamp(50, 4 * width);
    let px = |p: DVec2| -> (i32, i32) {
        ((margin + (p.x - lo.x) * scale) as i32, (height as f64 - margin - (p.y - lo.y) * scale) as i32)
    };
    let err = |e: DrawingAreaErrorKind<_>| anyhow!("drawing {}: {e:?}", path.display());
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let b = &world.bodies;
    for k in 0..b.len() {
        let color = PALETTE[b.tag[k] as usize % PALETTE.len()];
        match b.shape[k] {
            BodyShape::Disk { radius } => {
                let r = ((radius * scale) as i32).max(1);
                root.draw(&Circle::new(px(b.position[k]), r, color.filled())).map_err(err)?;
                root.draw(&Circle::new(px(b.position[k]), r, RGBColor(120, 120, 130).stroke_width(1))).map_err(err)?;
            }
            BodyShape::Polygon(_) => {
                let pts: Vec<_> = b.world_vertices(k).into_iter().map(px).collect();
                root.draw(&Polygon::new(pts.clone(), color.filled())).map_err(err)?;
                let mut closed = pts.clone();
                closed.push(pts[0]);
                root.draw(&PathElement::new(closed, RGBColor(120, 120, 130).stroke_width(1))).map_err(err)?;
            }
        }
    }
    for w in &world.walls {
        let pts: Vec<_> = w.world_points().into_iter().map(px).collect();
        let mut closed = pts.clone();
        if pts.len() > 2 {
            closed.push(pts[0]);
        }
        root.draw(&PathElement::new(closed, BLACK.stroke_width(3))).map_err(err)?;
    }
    let contacts = sim.contacts();
    let max_rn = contacts.iter().map(|c| c.impulse[0]).fold(0.0, f64::max);
    if max_rn > 0.0 {
        let mean_radius = b.mean_diameter() / 2.0;
        let max_width = (0.5 * mean_radius * scale).clamp(1.0, 12.0);
        for c in contacts {
            let share = c.impulse[0] / max_rn;
            if share < 0.02 {
                continue;
            }
            let a = b.position[c.contact.i];
            let z = match c.contact.other {
                Antagonist::Body(j) => b.position[j],
                Antagonist::Wall(_) => c.contact.point,
            };
            let w = ((share * max_width).round() as u32).max(1);
            root.draw(&PathElement::new(vec![px(a), px(z)], RGBColor(180, 30, 30).stroke_width(w))).map_err(err)?;
        }
    }
    root.present().map_err(err)?;
    Ok(())
}
