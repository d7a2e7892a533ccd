//! VTK output for ParaView (vtkio, XML `.vtu`) and `.pvd` time series.
//! `grains_NNNNNN.vtu`: one vertex per body (glyph it by `radius`, orient it by `orientation`),
//! polygons as polygon cells after the vertices; `contacts_NNNNNN.vtu`: one line per contact
//! (centre to centre, or centre to contact point for a wall) with the contact point, the normal,
//! the force vector, the impulses, the gap, the two bodies and the status (its array's name is
//! its legend) — the force chains; `walls_NNNNNN.vtu`: the walls as lines.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

use crate::detection::Antagonist;
use crate::stepping::Simulation;
use crate::world::{BodyShape, WallShape};

pub(crate) fn grid(
    title: &str,
    points: Vec<f64>,
    connectivity: Vec<u64>,
    offsets: Vec<u64>,
    types: Vec<CellType>,
    data: Attributes,
) -> Vtk {
    Vtk {
        version: Version::default(),
        title: title.to_string(),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: points.into(),
            cells: Cells { cell_verts: VertexNumbers::XML { connectivity, offsets }, types },
            data,
        }),
    }
}

/// Writes the three files of one output step into `dir`; returns their names.
pub fn write_step(sim: &Simulation, dir: &Path, index: usize) -> Result<[PathBuf; 3]> {
    let world = &sim.world;
    let b = &world.bodies;
    let n = b.len();

    // Grains: a vertex cell per body; polygons add a polygon cell over their vertices, clumps
    // one over their outline.
    let mut points = Vec::with_capacity(3 * n);
    let (mut conn, mut offs, mut types) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..n {
        points.extend([b.position[k].x, b.position[k].y, 0.0]);
        conn.push(k as u64);
        offs.push(conn.len() as u64);
        types.push(CellType::Vertex);
    }
    let mut cell_body: Vec<i64> = (0..n as i64).collect();
    for k in 0..n {
        if !matches!(b.shape[k], BodyShape::Disk { .. }) {
            for p in b.world_vertices(k) {
                conn.push((points.len() / 3) as u64);
                points.extend([p.x, p.y, 0.0]);
            }
            offs.push(conn.len() as u64);
            types.push(CellType::Polygon);
            cell_body.push(k as i64);
        }
    }
    let extra = points.len() / 3 - n;
    let pad = |mut v: Vec<f64>, per: usize| {
        v.extend(std::iter::repeat_n(0.0, extra * per));
        v
    };
    let velocity: Vec<f64> = (0..n).flat_map(|k| [b.velocity[k].x, b.velocity[k].y, 0.0]).collect();
    let data = Attributes {
        point: vec![
            Attribute::vectors("velocity").with_data(pad(velocity, 3)),
            Attribute::scalars("spin", 1).with_data(pad((0..n).map(|k| b.spin_of(k)).collect(), 1)),
            Attribute::scalars("angle", 1).with_data(pad((0..n).map(|k| b.angle_of(k)).collect(), 1)),
            Attribute::vectors("orientation")
                .with_data(pad((0..n).flat_map(|k| [b.angle_of(k).cos(), b.angle_of(k).sin(), 0.0]).collect(), 3)),
            Attribute::scalars("radius", 1).with_data(pad((0..n).map(|k| b.radius_of(k)).collect(), 1)),
            Attribute::scalars("tag", 1).with_data(pad((0..n).map(|k| b.tag[k] as f64).collect(), 1)),
        ],
        cell: vec![Attribute::scalars("body", 1).with_data(cell_body)],
    };
    let grains = dir.join(format!("grains_{index:06}.vtu"));
    grid("moreau grains", points, conn, offs, types, data)
        .export(&grains)
        .with_context(|| format!("writing {}", grains.display()))?;

    // Contacts: a line per contact.
    let contacts = sim.contacts();
    let mut points = Vec::with_capacity(6 * contacts.len());
    let (mut conn, mut offs) = (Vec::new(), Vec::new());
    for c in contacts {
        let a = b.position[c.contact.i];
        let z = match c.contact.other {
            // Through a periodic boundary: to the other grain's image beside this one.
            Antagonist::Body(j) => b.position[j] + c.contact.image,
            Antagonist::Wall(_) => c.contact.point,
        };
        conn.extend([(points.len() / 3) as u64, (points.len() / 3 + 1) as u64]);
        points.extend([a.x, a.y, 0.0, z.x, z.y, 0.0]);
        offs.push(conn.len() as u64);
    }
    let h = sim.settings.h;
    let vector = |f: &dyn Fn(&crate::stepping::ContactState) -> glam::DVec2| -> Vec<f64> {
        contacts.iter().flat_map(|c| f(c).extend(0.0).to_array()).collect()
    };
    let data = Attributes {
        point: vec![],
        cell: vec![
            Attribute::vectors("contact_point").with_data(vector(&|c| c.contact.point)),
            Attribute::vectors("normal").with_data(vector(&|c| c.contact.normal)),
            Attribute::vectors("force").with_data(vector(&|c| c.force(h))),
            Attribute::scalars("body", 1).with_data(contacts.iter().map(|c| c.contact.i as i64).collect::<Vec<i64>>()),
            Attribute::scalars("other", 1).with_data(
                contacts
                    .iter()
                    .map(|c| match c.contact.other {
                        Antagonist::Body(j) | Antagonist::Wall(j) => j as i64,
                    })
                    .collect::<Vec<i64>>(),
            ),
            Attribute::scalars("other_is_wall", 1).with_data(
                contacts.iter().map(|c| matches!(c.contact.other, Antagonist::Wall(_)) as i32).collect::<Vec<i32>>(),
            ),
            Attribute::scalars("normal_impulse", 1)
                .with_data(contacts.iter().map(|c| c.impulse[0]).collect::<Vec<f64>>()),
            Attribute::scalars("tangential_impulse", 1)
                .with_data(contacts.iter().map(|c| c.impulse[1]).collect::<Vec<f64>>()),
            Attribute::scalars("gap", 1).with_data(contacts.iter().map(|c| c.contact.gap).collect::<Vec<f64>>()),
            Attribute::scalars(STATUS_LEGEND, 1)
                .with_data(contacts.iter().map(|c| c.status.code() as i32).collect::<Vec<i32>>()),
        ],
    };
    let types = vec![CellType::Line; contacts.len()];
    let contacts_path = dir.join(format!("contacts_{index:06}.vtu"));
    grid("moreau contacts", points, conn, offs, types, data)
        .export(&contacts_path)
        .with_context(|| format!("writing {}", contacts_path.display()))?;

    // Walls.
    let mut points = Vec::new();
    let (mut conn, mut offs, mut types) = (Vec::new(), Vec::new(), Vec::new());
    for w in &world.walls {
        let pts = w.world_points();
        for p in &pts {
            conn.push((points.len() / 3) as u64);
            points.extend([p.x, p.y, 0.0]);
        }
        offs.push(conn.len() as u64);
        types.push(match w.shape {
            WallShape::Segment { .. } => CellType::Line,
            WallShape::Polygon(_) => CellType::Polygon,
        });
    }
    let walls = dir.join(format!("walls_{index:06}.vtu"));
    grid("moreau walls", points, conn, offs, types, Attributes::new())
        .export(&walls)
        .with_context(|| format!("writing {}", walls.display()))?;
    Ok([grains, contacts_path, walls])
}

/// The name of the contacts' status array, which ParaView shows as its legend.
pub const STATUS_LEGEND: &str = "status: 0 open, 1 stick, 2 slide r_t=+mu r_n, 3 slide r_t=-mu r_n";

/// A `.vtu` file read back: points (x, y), cells, and its point and cell arrays as f64.
pub struct Grid {
    path: PathBuf,
    /// Point coordinates.
    pub points: Vec<glam::DVec2>,
    /// Cell connectivity.
    pub connectivity: Vec<u64>,
    /// End of each cell in the connectivity.
    pub offsets: Vec<u64>,
    /// Cell types.
    pub types: Vec<CellType>,
    point: Vec<(String, Vec<f64>)>,
    cell: Vec<(String, Vec<f64>)>,
}

impl Grid {
    fn array<'a>(&self, arrays: &'a [(String, Vec<f64>)], name: &str, kind: &str) -> Result<&'a [f64]> {
        let found = arrays.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_slice());
        found.ok_or_else(|| {
            anyhow::anyhow!("{}: no {kind} array {name:?} (is it a moreau output?)", self.path.display())
        })
    }

    /// The point array called `name`.
    pub fn point_array(&self, name: &str) -> Result<&[f64]> {
        self.array(&self.point, name, "point")
    }

    /// The cell array called `name`.
    pub fn cell_array(&self, name: &str) -> Result<&[f64]> {
        self.array(&self.cell, name, "cell")
    }

    /// Each cell's points, in order (points out of range are left out).
    pub fn cells(&self) -> impl Iterator<Item = Vec<glam::DVec2>> + '_ {
        (0..self.offsets.len()).map(|c| {
            let start = if c == 0 { 0 } else { self.offsets[c - 1] as usize };
            let end = (self.offsets[c] as usize).min(self.connectivity.len());
            self.connectivity[start.min(end)..end]
                .iter()
                .filter_map(|&i| self.points.get(i as usize).copied())
                .collect()
        })
    }
}

/// Reads an unstructured-grid `.vtu` file (one inline piece, as moreau writes them).
pub fn read_grid(path: &Path) -> Result<Grid> {
    use vtkio::model::Piece;
    // The file's own error first: vtkio words a missing file as an XML error.
    std::fs::File::open(path).with_context(|| path.display().to_string())?;
    if path.is_dir() {
        anyhow::bail!("{}: a folder, not a .vtu file", path.display());
    }
    let vtk = Vtk::import(path).map_err(|e| anyhow::anyhow!("{}: not a VTK file moreau reads: {e}", path.display()))?;
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        anyhow::bail!("{}: not an unstructured grid (.vtu)", path.display());
    };
    let Some(Piece::Inline(piece)) = pieces.into_iter().next() else {
        anyhow::bail!("{}: no inline piece", path.display());
    };
    let piece = *piece;
    let coords: Vec<f64> =
        piece.points.cast_into().ok_or_else(|| anyhow::anyhow!("{}: points are not numbers", path.display()))?;
    let points = coords.chunks_exact(3).map(|p| glam::DVec2::new(p[0], p[1])).collect();
    let (connectivity, offsets) = piece.cells.cell_verts.into_xml();
    let arrays = |attributes: Vec<Attribute>| -> Vec<(String, Vec<f64>)> {
        attributes
            .into_iter()
            .filter_map(|a| match a {
                Attribute::DataArray(d) => Some((d.name.clone(), d.data.cast_into::<f64>()?)),
                Attribute::Field { .. } => None,
            })
            .collect()
    };
    Ok(Grid {
        path: path.to_path_buf(),
        points,
        connectivity,
        offsets,
        types: piece.cells.types,
        point: arrays(piece.data.point),
        cell: arrays(piece.data.cell),
    })
}

/// The cell array `name` of a `.vtu` file (a contacts file's `normal_impulse`, say), as f64.
pub fn read_cell_array(path: &Path, name: &str) -> Result<Vec<f64>> {
    let grid = read_grid(path)?;
    let values = grid.cell_array(name).map_err(|_| {
        anyhow::anyhow!("{}: no cell array {name:?} (is it a moreau contacts_NNNNNN.vtu?)", path.display())
    })?;
    Ok(values.to_vec())
}

/// A ParaView collection (`.pvd`) of (time, file) pairs.
pub fn write_pvd(path: &Path, entries: &[(f64, PathBuf)]) -> Result<()> {
    let mut s =
        String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n");
    for (t, f) in entries {
        let name = f.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        s.push_str(&format!("    <DataSet timestep=\"{t:.9e}\" part=\"0\" file=\"{name}\"/>\n"));
    }
    s.push_str("  </Collection>\n</VTKFile>\n");
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}
