//! Grains read from a CSV file, as packings made by other codes are handed over: a header row
//! naming the columns (`x, y, r` required; `vx, vy, spin, tag, material, fixed` optional, the material by
//! its scene name; any order), one grain a row, `#` lines ignored. Errors name the line and the column.

use std::path::Path;

use glam::DVec2;

use crate::world::{BodySpec, World};

/// One grain of the file.
#[derive(Clone, Debug, PartialEq)]
pub struct GrainRow {
    /// Centre (m).
    pub center: DVec2,
    /// Radius (m).
    pub radius: f64,
    /// Velocity (0 when the column is absent).
    pub velocity: DVec2,
    /// Spin (0 when absent).
    pub spin: f64,
    /// Tag (0 when absent).
    pub tag: u32,
    /// Index of the material the row names among the scene's (None when the column is absent).
    pub material: Option<usize>,
    /// A fixed grain, moving only at its velocity and spin (`fixed` 1; 0 or absent: free).
    pub fixed: bool,
}

impl GrainRow {
    /// The row's disk as a body: of its own material if it names one, else of `material`.
    pub fn body(&self, material: usize) -> BodySpec {
        let mut spec = BodySpec::disk(self.center, self.radius, self.material.unwrap_or(material));
        (spec.velocity, spec.spin, spec.tag, spec.fixed) = (self.velocity, self.spin, self.tag, self.fixed);
        spec
    }
}

/// The columns a grains file may have, in the order `io::grains` writes them.
pub const COLUMNS: [&str; 9] = ["x", "y", "r", "vx", "vy", "spin", "tag", "material", "fixed"];
const MATERIAL: usize = 7;
const FIXED: usize = 8;

/// Reads at most `max_rows` grains from `path`; `materials` are the scene's material names.
pub fn read_grains(path: &Path, max_rows: usize, materials: &[String]) -> Result<Vec<GrainRow>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    parse_grains(&text, max_rows, materials).map_err(|e| format!("{}: {e}", path.display()))
}

/// Parses the text of a grains file (see the module doc).
pub fn parse_grains(text: &str, max_rows: usize, materials: &[String]) -> Result<Vec<GrainRow>, String> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.as_bytes());
    let mut records = reader.records();
    let header = match records.next() {
        Some(h) => h.map_err(|e| format!("header: {e}"))?,
        None => return Err("no header row (columns x, y, r and optionally vx, vy, spin, tag, material, fixed)".into()),
    };
    let line_of = |r: &csv::StringRecord| r.position().map(|p| p.line()).unwrap_or(0);
    // Where each known column is.
    let mut at = [None; COLUMNS.len()];
    for (c, name) in header.iter().enumerate() {
        let k = COLUMNS.iter().position(|n| n.eq_ignore_ascii_case(name)).ok_or_else(|| {
            format!(
                "line {}, column {}: unknown column {name:?} (known: {})",
                line_of(&header),
                c + 1,
                COLUMNS.join(", ")
            )
        })?;
        if at[k].is_some() {
            return Err(format!("line {}, column {}: column {name:?} appears twice", line_of(&header), c + 1));
        }
        at[k] = Some(c);
    }
    for k in 0..3 {
        if at[k].is_none() {
            return Err(format!("line {}: the header has no column {:?}", line_of(&header), COLUMNS[k]));
        }
    }
    let mut grains = Vec::new();
    for record in records {
        let record = record.map_err(|e| format!("{e}"))?;
        let line = line_of(&record);
        if grains.len() == max_rows {
            return Err(format!("line {line}: more than {max_rows} grains"));
        }
        if record.len() != header.len() {
            return Err(format!("line {line}: {} fields, the header has {}", record.len(), header.len()));
        }
        let value = |k: usize| -> Result<f64, String> {
            let Some(c) = at[k] else { return Ok(0.0) };
            let field = &record[c];
            let x: f64 = field
                .parse()
                .map_err(|_| format!("line {line}, column {} ({}): {field:?} is not a number", c + 1, COLUMNS[k]))?;
            if !x.is_finite() {
                return Err(format!("line {line}, column {} ({}): {field} is not finite", c + 1, COLUMNS[k]));
            }
            Ok(x)
        };
        let radius = value(2)?;
        if radius <= 0.0 {
            return Err(format!("line {line}, column {} (r): radius {radius} must be > 0", at[2].unwrap() + 1));
        }
        let material = match at[MATERIAL] {
            None => None,
            Some(c) => {
                let name = &record[c];
                let found = materials.iter().position(|m| m == name);
                Some(found.ok_or_else(|| {
                    format!(
                        "line {line}, column {} (material): {name:?} is not a material of the scene (known: {})",
                        c + 1,
                        materials.join(", ")
                    )
                })?)
            }
        };
        let tag = value(6)?;
        if tag < 0.0 || tag.fract() != 0.0 || tag > u32::MAX as f64 {
            return Err(format!("line {line}, column {} (tag): {tag} is not a whole number >= 0", at[6].unwrap() + 1));
        }
        let fixed = value(FIXED)?;
        if fixed != 0.0 && fixed != 1.0 {
            return Err(format!("line {line}, column {} (fixed): {fixed} is neither 0 nor 1", at[FIXED].unwrap() + 1));
        }
        grains.push(GrainRow {
            center: DVec2::new(value(0)?, value(1)?),
            radius,
            velocity: DVec2::new(value(3)?, value(4)?),
            spin: value(5)?,
            tag: tag as u32,
            material,
            fixed: fixed == 1.0,
        });
    }
    if grains.is_empty() {
        return Err("no grains after the header".into());
    }
    Ok(grains)
}

/// How a file's grains are numbered as bodies (`[[grains]] order`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GrainOrder {
    /// The file's order when its grains lie together ([`lies_in_space`]), else [`GrainOrder::Space`].
    #[default]
    Auto,
    /// In rows across the packing ([`space_order`]).
    Space,
    /// The file's order.
    File,
}

impl GrainOrder {
    /// The order named `name` (auto, space, file).
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "auto" => Ok(Self::Auto),
            "space" => Ok(Self::Space),
            "file" => Ok(Self::File),
            other => Err(format!(
                "unknown order {other:?} (auto: the file's when its grains lie together, else in rows; space: in \
                 rows across the packing; file: as in the file)"
            )),
        }
    }

    /// What `Auto` comes to for these rows (`File` when they lie together, else `Space`); the
    /// other orders as they are.
    pub fn resolved(self, rows: &[GrainRow]) -> Self {
        match self {
            Self::Auto if lies_in_space(rows) => Self::File,
            Self::Auto => Self::Space,
            other => other,
        }
    }

    /// The file's rows in the order the bodies take them.
    pub fn numbering(self, rows: &[GrainRow]) -> Vec<usize> {
        match self.resolved(rows) {
            Self::Space => space_order(rows),
            _ => (0..rows.len()).collect(),
        }
    }
}

/// Adds the disks of the grains file `path` to `world` (a host's world built in code), each of
/// `material` unless its row names one, numbered as `order` says; returns each row's body index,
/// in the file's order. Nothing is added when a row is refused.
pub fn add_grains(world: &mut World, path: &Path, material: &str, order: GrainOrder) -> Result<Vec<usize>, String> {
    let material = world.material_named(material).map_err(|e| e.to_string())?;
    let rows = read_grains(path, super::file::MAX_GENERATED, &world.materials.names)?;
    let mut added = world.clone();
    let mut body_of = vec![0; rows.len()];
    for n in order.numbering(&rows) {
        body_of[n] =
            added.add_body(&rows[n].body(material)).map_err(|e| format!("{}: grain {}: {e}", path.display(), n + 1))?;
    }
    *world = added;
    Ok(body_of)
}

/// Whether the file's order already keeps grains together: cut into 16 runs of consecutive
/// grains, the runs' bounding boxes cover a quarter of the packing's on average or less (bands, or
/// columns, as a deposition or moreau's own `--save-grains` leaves them; a shuffled file's runs
/// each span the whole packing).
pub fn lies_in_space(rows: &[GrainRow]) -> bool {
    let area = |g: &[GrainRow]| {
        let (lo, hi) = bounds(g, |g| g.radius);
        (hi - lo).x * (hi - lo).y
    };
    let runs = rows.chunks(rows.len().div_ceil(16).max(1));
    let mean = runs.clone().map(area).sum::<f64>() / runs.len() as f64;
    mean <= 0.25 * area(rows)
}

/// The corners of the box holding the grains' centres, each widened by `margin` of it.
fn bounds(rows: &[GrainRow], margin: impl Fn(&GrainRow) -> f64) -> (DVec2, DVec2) {
    rows.iter().fold((DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)), |(lo, hi), g| {
        (lo.min(g.center - margin(g)), hi.max(g.center + margin(g)))
    })
}

/// The order in which to number the grains in space: rows one largest diameter high across the
/// packing's longer side (centred on its lowest grain's, so that a lattice's rows are its own),
/// each row along it. The solvers cut the contacts, numbered by their bodies, into blocks for
/// threads and for the GPU's block sweeps: a block must be a region of the packing, which a file
/// in no spatial order (a shuffled packing) would not give. Ties keep the file's order.
pub fn space_order(rows: &[GrainRow]) -> Vec<usize> {
    let (lo, hi) = bounds(rows, |_| 0.0);
    let span = hi - lo;
    let height = 2.0 * rows.iter().fold(0.0f64, |m, g| m.max(g.radius));
    // (across the rows, along them): rows stack along the shorter side.
    let axes = |c: DVec2| if span.x >= span.y { (c.y - lo.y, c.x) } else { (c.x - lo.x, c.y) };
    let mut order: Vec<usize> = (0..rows.len()).collect();
    order.sort_by(|&a, &b| {
        let ((ra, la), (rb, lb)) = (axes(rows[a].center), axes(rows[b].center));
        (ra / height).round().total_cmp(&(rb / height).round()).then(la.total_cmp(&lb))
    });
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_in_any_order_with_optional_ones() {
        let g = parse_grains("# a packing\nr, y, x, vx\n0.5, 2, 1, -3\n0.25,4,3,0\n", 10, &[]).unwrap();
        assert_eq!(g.len(), 2);
        assert_eq!(g[0].center, DVec2::new(1.0, 2.0));
        assert_eq!((g[0].radius, g[0].velocity.x, g[0].spin), (0.5, -3.0, 0.0));
    }

    #[test]
    fn grains_are_numbered_in_rows_across_the_longer_side() {
        let row = |x: f64, y: f64| format!("{x},{y},0.5\n");
        // A wide packing (rows stack along y), given in no order: two rows of three.
        let text = [
            "x,y,r\n".to_string(),
            row(2.0, 1.0),
            row(0.0, 0.0),
            row(1.0, 1.2),
            row(2.0, 0.1),
            row(0.0, 1.1),
            row(1.0, 0.0),
        ]
        .concat();
        let g = parse_grains(&text, 10, &[]).unwrap();
        assert_eq!(space_order(&g), vec![1, 5, 3, 4, 2, 0]);
        // A tall one (rows stack along x): each column bottom to top.
        let tall: Vec<GrainRow> =
            g.iter().map(|r| GrainRow { center: DVec2::new(r.center.y, 3.0 * r.center.x), ..r.clone() }).collect();
        assert_eq!(space_order(&tall), vec![1, 5, 3, 4, 2, 0]);
    }

    #[test]
    fn a_file_in_rows_or_columns_lies_in_space_and_a_shuffled_one_does_not() {
        let lattice = |column_major: bool| -> Vec<GrainRow> {
            (0..40 * 20)
                .map(|k| {
                    let (i, j) = if column_major { (k % 20, k / 20) } else { (k / 40, k % 40) };
                    let row = format!("x,y,r\n{},{},0.5\n", j as f64, i as f64);
                    parse_grains(&row, 1, &[]).unwrap().remove(0)
                })
                .collect()
        };
        assert!(lies_in_space(&lattice(false)) && lies_in_space(&lattice(true)));
        let mut shuffled = lattice(false);
        let n = shuffled.len();
        for k in 0..n {
            shuffled.swap(k, (k * 7919 + 13) % n);
        }
        assert!(!lies_in_space(&shuffled));
        // Numbered in rows, it lies in space again.
        let ordered: Vec<GrainRow> = space_order(&shuffled).into_iter().map(|k| shuffled[k].clone()).collect();
        assert!(lies_in_space(&ordered));
    }

    #[test]
    fn errors_name_line_and_column() {
        let e = parse_grains("x,y,r\n0,0,1\n1,zz,1\n", 10, &[]).unwrap_err();
        assert!(e.contains("line 3, column 2 (y)") && e.contains("\"zz\""), "{e}");
        let e = parse_grains("x,y,r\n0,0,-1\n", 10, &[]).unwrap_err();
        assert!(e.contains("line 2, column 3 (r)"), "{e}");
        let e = parse_grains("x,y,radius\n", 10, &[]).unwrap_err();
        assert!(e.contains("line 1, column 3") && e.contains("radius"), "{e}");
        let e = parse_grains("x,y\n0,0\n", 10, &[]).unwrap_err();
        assert!(e.contains("no column \"r\""), "{e}");
        let e = parse_grains("x,y,r\n0,0,1,4\n", 10, &[]).unwrap_err();
        assert!(e.contains("line 2: 4 fields"), "{e}");
        let e = parse_grains("x,y,r\n0,0,1\n1,1,1\n", 1, &[]).unwrap_err();
        assert!(e.contains("line 3: more than 1 grains"), "{e}");
        let e = parse_grains("x,y,r\n0,inf,1\n", 10, &[]).unwrap_err();
        assert!(e.contains("line 2, column 2 (y)"), "{e}");
        let e = parse_grains("fixed,x,y,r\n1,0,0,1\n2,1,0,1\n", 10, &[]).unwrap_err();
        assert!(e.contains("line 3, column 1 (fixed): 2 is neither 0 nor 1"), "{e}");
        let sand = ["sand".to_string(), "steel".to_string()];
        let g = parse_grains("x,y,r,material\n0,0,1,steel\n1,0,1,sand\n", 10, &sand).unwrap();
        assert_eq!((g[0].material, g[1].material), (Some(1), Some(0)));
        let e = parse_grains("x,y,r,material\n0,0,1,steel\n1,0,1,glass\n", 10, &sand).unwrap_err();
        assert!(
            e.contains("line 3, column 4 (material): \"glass\" is not a material") && e.contains("sand, steel"),
            "{e}"
        );
    }
}
