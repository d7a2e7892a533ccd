//! Outputs of the structural punch: the mesh with displacements and stresses as VTK (`.vtu`, for
//! ParaView), the vertical stress as a PNG (both halves, mirrored at the symmetry axis), and the
//! contact nodes as CSV.

use std::path::Path;

use anyhow::{Context, Result};
use vtkio::model::{Attribute, Attributes, CellType};

use super::vtk::grid;
use crate::structure::{PunchModel, PunchSolution};

/// Von Mises stress in plane strain (σ_zz = ν (σ_xx + σ_yy)).
fn von_mises(s: &[f64; 3], poisson: f64) -> f64 {
    let szz = poisson * (s[0] + s[1]);
    (0.5 * ((s[0] - s[1]).powi(2) + (s[1] - szz).powi(2) + (szz - s[0]).powi(2)) + 3.0 * s[2] * s[2]).sqrt()
}

/// Writes the deformed punch (displacements, stresses, von Mises) as a `.vtu` file.
pub fn write_vtu(model: &PunchModel, sol: &PunchSolution, path: &Path) -> Result<()> {
    let mesh = &model.mesh;
    let points: Vec<f64> = mesh.nodes.iter().flat_map(|p| [p[0], p[1], 0.0]).collect();
    let conn: Vec<u64> = mesh.quads.iter().flat_map(|q| q.map(|n| n as u64)).collect();
    let offs: Vec<u64> = (1..=mesh.quads.len() as u64).map(|k| 4 * k).collect();
    let mut force = vec![0.0; mesh.nodes.len()];
    for (k, &n) in mesh.contact.iter().enumerate() {
        force[n] = sol.w[k];
    }
    let column = |c: usize| sol.stress.iter().map(|s| s[c]).collect::<Vec<f64>>();
    let data = Attributes {
        point: vec![
            Attribute::vectors("displacement")
                .with_data(sol.u.chunks(2).flat_map(|d| [d[0], d[1], 0.0]).collect::<Vec<f64>>()),
            Attribute::scalars("contact_force", 1).with_data(force),
        ],
        cell: vec![
            Attribute::scalars("sigma_xx", 1).with_data(column(0)),
            Attribute::scalars("sigma_yy", 1).with_data(column(1)),
            Attribute::scalars("sigma_xy", 1).with_data(column(2)),
            Attribute::scalars("von_mises", 1)
                .with_data(sol.stress.iter().map(|s| von_mises(s, model.material.poisson)).collect::<Vec<f64>>()),
        ],
    };
    grid("moreau punch", points, conn, offs, vec![CellType::Quad; mesh.quads.len()], data)
        .export(path)
        .with_context(|| format!("writing {}", path.display()))
}

#[derive(serde::Serialize)]
struct ContactRow {
    node: usize,
    x: f64,
    initial_gap: f64,
    gap: f64,
    force: f64,
    pressure: f64,
}

/// Writes each contact node's position, gap, force and pressure as CSV.
pub fn write_contact_csv(model: &PunchModel, sol: &PunchSolution, path: &Path) -> Result<()> {
    let mut w = csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?;
    for (k, &n) in model.mesh.contact.iter().enumerate() {
        w.serialize(ContactRow {
            node: n,
            x: model.mesh.nodes[n][0],
            initial_gap: model.gap[k],
            gap: sol.z[k],
            force: sol.w[k],
            pressure: sol.pressure[k],
        })?;
    }
    w.flush()?;
    Ok(())
}

/// The vertical stress σ_yy on the undeformed mesh, both halves, with a colour scale.
#[cfg(feature = "plots")]
pub fn write_stress_png(model: &PunchModel, sol: &PunchSolution, path: &Path, width: u32) -> Result<()> {
    use super::plots::font_available;
    use anyhow::anyhow;
    use plotters::prelude::*;
    let mesh = &model.mesh;
    let (w_half, h) = (model.geometry.half_width, model.geometry.height);
    let bar = 120.0;
    let margin = 20.0;
    let scale = (width as f64 - 2.0 * margin - bar) / (2.0 * w_half);
    let height = (h * scale + 2.0 * margin).ceil() as u32 + 30;
    let px = |x: f64, y: f64| -> (i32, i32) {
        ((margin + (x + w_half) * scale) as i32, (height as f64 - margin - 30.0 - y * scale) as i32)
    };
    let syy: Vec<f64> = sol.stress.iter().map(|s| s[1]).collect();
    let (lo, hi) = syy.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    let hi = if hi > lo { hi } else { lo + 1.0 };
    // Normalised in f64: stresses of a very soft or very stiff body leave f32 no range (and
    // plotters' own normalisation a 0/0), and a non-finite one is drawn at the bottom.
    let colour = |v: f64| {
        let t = (v - lo) / (hi - lo);
        ViridisRGB.get_color(if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) as f32 })
    };
    let err = |e: DrawingAreaErrorKind<_>| anyhow!("drawing {}: {e:?}", path.display());
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    for (q, &v) in mesh.quads.iter().zip(&syy) {
        for side in [1.0, -1.0] {
            let pts: Vec<_> = q.iter().map(|&n| px(side * mesh.nodes[n][0], mesh.nodes[n][1])).collect();
            root.draw(&Polygon::new(pts, colour(v).filled())).map_err(err)?;
        }
    }
    // The rigid plate.
    root.draw(&PathElement::new(vec![px(-w_half, 0.0), px(w_half, 0.0)], BLACK.stroke_width(3))).map_err(err)?;
    // Colour scale: top = largest σ_yy.
    let (x0, x1) = (width as i32 - bar as i32 + 10, width as i32 - bar as i32 + 35);
    let (top, bottom) = (margin as i32, (height as f64 - margin - 30.0) as i32);
    for y in top..bottom {
        let v = hi - (hi - lo) * (y - top) as f64 / (bottom - top).max(1) as f64;
        root.draw(&Rectangle::new([(x0, y), (x1, y + 1)], colour(v).filled())).map_err(err)?;
    }
    if font_available() {
        let text = ("sans-serif", 14).into_font();
        root.draw(&Text::new(format!("{hi:.3e}"), (x1 + 4, top), text.clone())).map_err(err)?;
        root.draw(&Text::new(format!("{lo:.3e}"), (x1 + 4, bottom - 14), text.clone())).map_err(err)?;
        root.draw(&Text::new("σ_yy (Pa)".to_string(), (x0, bottom + 8), text.clone())).map_err(err)?;
        let title = format!(
            "vertical stress, punch pushed down {:.2e} m: load {:.3e} N/m (both halves)",
            model.displacement,
            -2.0 * sol.platen_force
        );
        root.draw(&Text::new(title, (margin as i32, (height - 22) as i32), text)).map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}
