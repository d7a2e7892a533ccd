//! Pictures of a granular state (plotters): grains coloured by a chosen quantity, walls, and the
//! force chains — a line between the centres of every loaded contact, its width proportional to
//! the normal force — with axes in metres, a scale bar, the time and a legend. A picture is
//! framed to the grains: a stray grain far away or the empty top of a tall box does not shrink
//! the pile. A [`Frame`] comes from a running simulation or from a run's saved VTK files
//! (`moreau picture DIR --step N`); a series of frames makes an animated GIF.
//!
//! Text needs a TrueType font (`io::plots::font_available`); without one the picture is drawn
//! without axes, legend or labels.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use anyhow::{anyhow, bail, Context, Result};
use glam::DVec2;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::detection::Antagonist;
use crate::stepping::Simulation;
use crate::world::BodyShape;

/// One grain as a picture sees it.
#[derive(Clone, Debug)]
pub struct Grain {
    /// Centre (m).
    pub position: DVec2,
    /// The disk's radius, or a polygon's or a clump's bounding radius.
    pub radius: f64,
    /// A polygon's vertices or a clump's outline in the world frame; `None` for a disk.
    pub outline: Option<Vec<DVec2>>,
    /// Velocity (m/s).
    pub velocity: DVec2,
    /// The body's tag.
    pub tag: u32,
}

impl Grain {
    /// Area of the disk or polygon.
    pub fn area(&self) -> f64 {
        match &self.outline {
            None => std::f64::consts::PI * self.radius * self.radius,
            Some(v) => 0.5 * (0..v.len()).map(|k| v[k].perp_dot(v[(k + 1) % v.len()])).sum::<f64>().abs(),
        }
    }
}

/// One contact: the force chain segment and the force on `body`.
#[derive(Clone, Debug)]
pub struct Chain {
    /// The body the force acts on.
    pub body: usize,
    /// The other grain, or `None` for a wall.
    pub other: Option<usize>,
    /// The chain's ends: the two centres, or the centre and the contact point for a wall.
    pub from: DVec2,
    /// See `from`.
    pub to: DVec2,
    /// Contact point.
    pub point: DVec2,
    /// Unit normal, towards `body`.
    pub normal: DVec2,
    /// Mean force of the step on `body` (N).
    pub force: DVec2,
}

impl Chain {
    /// The normal force, positive in compression.
    pub fn normal_force(&self) -> f64 {
        self.force.dot(self.normal)
    }
}

/// What one picture shows.
#[derive(Clone, Debug, Default)]
pub struct Frame {
    /// Step shown.
    pub step: usize,
    /// Simulated time, when known.
    pub time: Option<f64>,
    /// Every grain.
    pub grains: Vec<Grain>,
    /// Each wall's points: a segment's two ends, or a polygon's vertices.
    pub walls: Vec<Vec<DVec2>>,
    /// Every contact.
    pub chains: Vec<Chain>,
}

/// What colours the grains.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Colouring {
    /// The body's tag (layer, material group): a categorical palette.
    Tag,
    /// |v| in m/s.
    Speed,
    /// The grain's mean pressure from its contact forces (N/m in 2D): `p = −tr σ / 2` with
    /// `σ = Σ_c branch ⊗ f / area`.
    Pressure,
}

impl Colouring {
    /// The names the command line takes.
    pub const NAMES: [&'static str; 3] = ["tag", "speed", "pressure"];
}

impl FromStr for Colouring {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "tag" => Ok(Colouring::Tag),
            "speed" => Ok(Colouring::Speed),
            "pressure" => Ok(Colouring::Pressure),
            _ => Err(format!("unknown colouring {s:?} (one of {})", Colouring::NAMES.join(", "))),
        }
    }
}

impl Frame {
    /// The current state of a simulation.
    pub fn of(sim: &Simulation) -> Frame {
        let world = &sim.world;
        let b = &world.bodies;
        let grains = (0..b.len())
            .map(|k| Grain {
                position: b.position[k],
                radius: b.radius_of(k),
                outline: (!matches!(b.shape[k], BodyShape::Disk { .. })).then(|| b.world_vertices(k)),
                velocity: b.velocity[k],
                tag: b.tag[k],
            })
            .collect();
        let h = sim.settings.h;
        let chains = sim
            .contacts()
            .iter()
            .map(|c| {
                let from = b.position[c.contact.i];
                let (other, to) = match c.contact.other {
                    Antagonist::Body(j) => (Some(j), b.position[j] + c.contact.image),
                    Antagonist::Wall(_) => (None, c.contact.point),
                };
                Chain {
                    body: c.contact.i,
                    other,
                    from,
                    to,
                    point: c.contact.point,
                    normal: c.contact.normal,
                    force: c.force(h),
                }
            })
            .collect();
        Frame {
            step: sim.steps_done(),
            time: Some(sim.time()),
            grains,
            walls: world.walls.iter().map(|w| w.world_points()).collect(),
            chains,
        }
    }

    /// Step `step` of a run's output directory: its `grains_`, `contacts_` and `walls_NNNNNN.vtu`
    /// files, and the time from `grains.pvd` when it is there.
    pub fn read(dir: &Path, step: usize) -> Result<Frame> {
        use super::vtk::read_grid;
        let file = |kind: &str| dir.join(format!("{kind}_{step:06}.vtu"));
        let g = read_grid(&file("grains"))?;
        let body_of_cell = g.cell_array("body")?;
        let n = g.types.iter().filter(|t| matches!(t, vtkio::model::CellType::Vertex)).count();
        let (radius, tag, velocity) = (g.point_array("radius")?, g.point_array("tag")?, g.point_array("velocity")?);
        if radius.len() < n || tag.len() < n || velocity.len() < 3 * n || g.points.len() < n {
            bail!("{}: fewer values than grains ({n})", file("grains").display());
        }
        let mut grains: Vec<Grain> = (0..n)
            .map(|k| Grain {
                position: g.points[k],
                radius: radius[k],
                outline: None,
                velocity: DVec2::new(velocity[3 * k], velocity[3 * k + 1]),
                tag: tag[k].max(0.0) as u32,
            })
            .collect();
        for (cell, points) in g.cells().enumerate() {
            if matches!(g.types[cell], vtkio::model::CellType::Polygon) {
                let k = body_of_cell.get(cell).map(|&b| b as usize).filter(|&k| k < n);
                let k = k.ok_or_else(|| anyhow!("{}: polygon cell {cell} names no grain", file("grains").display()))?;
                grains[k].outline = Some(points);
            }
        }

        let c = read_grid(&file("contacts"))?;
        let (point, normal, force) = (c.cell_array("contact_point")?, c.cell_array("normal")?, c.cell_array("force")?);
        let (body, other, is_wall) = (c.cell_array("body")?, c.cell_array("other")?, c.cell_array("other_is_wall")?);
        let m = c.types.len();
        if point.len() < 3 * m || normal.len() < 3 * m || force.len() < 3 * m || body.len() < m || other.len() < m {
            bail!("{}: fewer values than contacts ({m})", file("contacts").display());
        }
        let v = |a: &[f64], k: usize| DVec2::new(a[3 * k], a[3 * k + 1]);
        let chains = c
            .cells()
            .enumerate()
            .map(|(k, ends)| {
                if ends.len() != 2 {
                    bail!("{}: contact {k} is not a line", file("contacts").display());
                }
                Ok(Chain {
                    body: body[k] as usize,
                    other: (is_wall.get(k) != Some(&1.0)).then_some(other[k] as usize),
                    from: ends[0],
                    to: ends[1],
                    point: v(point, k),
                    normal: v(normal, k),
                    force: v(force, k),
                })
            })
            .collect::<Result<Vec<_>>>()?;

        let walls = read_grid(&file("walls"))?.cells().collect();
        Ok(Frame { step, time: series_time(&dir.join("grains.pvd"), &file("grains")), grains, walls, chains })
    }

    /// Mean pressure of each grain from the contact forces on it (0 for a grain with none).
    pub fn pressures(&self) -> Vec<f64> {
        let mut trace = vec![0.0; self.grains.len()];
        for c in &self.chains {
            // tr(branch ⊗ f) = branch · f, with f the force on the grain.
            // Branches from the chain's ends: `to` is the other grain's image across a periodic
            // boundary.
            if let Some(t) = trace.get_mut(c.body) {
                *t += (c.point - c.from).dot(c.force);
            }
            if let Some(j) = c.other.filter(|&j| j < self.grains.len()) {
                trace[j] += (c.point - c.to).dot(-c.force);
            }
        }
        self.grains.iter().zip(trace).map(|(g, t)| -0.5 * t / g.area().max(f64::MIN_POSITIVE)).collect()
    }

    /// The region a picture shows: the grains, leaving out strays (grains more than three
    /// diameters beyond the 0.2 % and 99.8 % quantiles of the grains' extents), with a margin of
    /// a diameter. Bodies four times the median radius or more (plates, pistons) are never left
    /// out. Without bodies, the walls.
    pub fn extent(&self) -> Option<(DVec2, DVec2)> {
        if self.grains.is_empty() {
            let points = self.walls.iter().flatten();
            let lo = points.clone().fold(DVec2::splat(f64::INFINITY), |a, &p| a.min(p));
            let hi = points.fold(DVec2::splat(f64::NEG_INFINITY), |a, &p| a.max(p));
            return lo.cmple(hi).all().then_some((lo, hi));
        }
        let median_radius = quantile(self.grains.iter().map(|g| g.radius).collect(), 0.5);
        let diameter = 2.0 * median_radius;
        let mut band = [(0.0, 0.0); 2];
        for (axis, b) in band.iter_mut().enumerate() {
            let lows = self.grains.iter().map(|g| g.position[axis] - g.radius).collect();
            let highs = self.grains.iter().map(|g| g.position[axis] + g.radius).collect();
            *b = (quantile(lows, 0.002) - 3.0 * diameter, quantile(highs, 0.998) + 3.0 * diameter);
        }
        let kept = self.grains.iter().filter(|g| {
            g.radius >= 4.0 * median_radius
                || (0..2).all(|axis| g.position[axis] >= band[axis].0 && g.position[axis] <= band[axis].1)
        });
        let (lo, hi) = kept.fold((DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)), |(lo, hi), g| {
            (lo.min(g.position - g.radius), hi.max(g.position + g.radius))
        });
        if !lo.is_finite() || !hi.is_finite() {
            return None;
        }
        let pad = diameter.max(0.01 * (hi - lo).max_element());
        Some((lo - pad, hi + pad))
    }
}

/// The value below which a share `q` of `values` lie (the nearest rank; `values` not empty).
fn quantile(mut values: Vec<f64>, q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * q).round() as usize]
}

/// The time of `file` in a `.pvd` series, if the series names it.
fn series_time(pvd: &Path, file: &Path) -> Option<f64> {
    let text = std::fs::read_to_string(pvd).ok()?;
    let name = file.file_name()?.to_str()?;
    let line = text.lines().find(|l| l.contains(&format!("file=\"{name}\"")))?;
    let start = line.find("timestep=\"")? + "timestep=\"".len();
    line[start..].split('"').next()?.parse().ok()
}

/// The steps of which `dir` holds VTK files (`grains_NNNNNN.vtu`), in order.
pub fn saved_steps(dir: &Path) -> Result<Vec<usize>> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))?;
    let mut steps: Vec<usize> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_str()?.to_string();
            name.strip_prefix("grains_")?.strip_suffix(".vtu")?.parse().ok()
        })
        .collect();
    steps.sort_unstable();
    if steps.is_empty() {
        bail!(
            "{}: no grains_NNNNNN.vtu (run the scene with VTK output: [output] vtk = true or --vtk-every N)",
            dir.display()
        );
    }
    Ok(steps)
}

const TAG_PALETTE: [RGBColor; 8] = [
    RGBColor(200, 200, 205),
    RGBColor(230, 205, 150),
    RGBColor(170, 200, 230),
    RGBColor(210, 170, 170),
    RGBColor(180, 215, 170),
    RGBColor(150, 130, 110),
    RGBColor(215, 180, 220),
    RGBColor(240, 235, 170),
];
const CHAIN_COLOUR: RGBColor = RGBColor(180, 30, 30);
const OUTLINE: RGBColor = RGBColor(110, 110, 120);
const LEGEND_WIDTH: u32 = 190;
const CAPTION: u32 = 34;
const X_LABELS: u32 = 45;
const Y_LABELS: u32 = 75;
const MARGIN: u32 = 12;

/// Pixel sizes and the region shown, the same for every frame of an animation.
#[derive(Clone, Copy, Debug)]
struct Layout {
    lo: DVec2,
    hi: DVec2,
    width: u32,
    /// The canvas: the chart's height, or the legend's when that is taller.
    height: u32,
    chart_height: u32,
    /// Pixels per metre.
    scale: f64,
    text: bool,
}

impl Layout {
    /// Equal scales in x and y; a region too flat or too tall for the canvas grows along its
    /// short side.
    fn new((mut lo, mut hi): (DVec2, DVec2), width: u32, text: bool, legend_height: u32) -> Layout {
        let (left, right, top, bottom) = if text {
            (Y_LABELS + MARGIN, LEGEND_WIDTH + MARGIN, CAPTION, X_LABELS + MARGIN)
        } else {
            (MARGIN, MARGIN, MARGIN, MARGIN)
        };
        let plot_w = width.saturating_sub(left + right).max(50) as f64;
        let span = (hi - lo).max(DVec2::splat(1e-12));
        let plot_h = (plot_w * span.y / span.x).clamp(60.0, 1.5 * width as f64);
        let scale = (plot_w / span.x).min(plot_h / span.y);
        let grow = DVec2::new(plot_w, plot_h) / scale - span;
        lo -= 0.5 * grow;
        hi += 0.5 * grow;
        let chart_height = plot_h.round() as u32 + top + bottom;
        let height = if text { chart_height.max(legend_height) } else { chart_height };
        Layout { lo, hi, width, height, chart_height, scale, text }
    }
}

/// The legend's height in pixels (see [`draw_legend`]).
fn legend_height(colouring: Colouring, scale: &ColourScale) -> u32 {
    let colours = match colouring {
        Colouring::Tag => 26 + 20 * scale.tags.len().min(8) as u32 + if scale.tags.len() > 8 { 20 } else { 0 },
        Colouring::Speed | Colouring::Pressure => 26 + 150 + 12 + if scale.clipped { 18 } else { 0 },
    };
    CAPTION + 4 + colours + 16 + 26 + 3 * 22 + 18 + 16 + 26 + 5 + MARGIN
}

/// Writes one frame as a PNG, `width` pixels wide.
pub fn write_png(frame: &Frame, colouring: Colouring, width: u32, path: &Path) -> Result<()> {
    let extent = frame.extent().ok_or_else(|| anyhow!("step {}: nothing to draw (no grain, no wall)", frame.step))?;
    let scale = ColourScale::of(&[frame], colouring);
    let layout = Layout::new(extent, width, super::plots::font_available(), legend_height(colouring, &scale));
    let root = BitMapBackend::new(path, (layout.width, layout.height)).into_drawing_area();
    draw(&root, frame, colouring, &layout, &scale).with_context(|| format!("drawing {}", path.display()))?;
    root.present().map_err(|e| anyhow!("writing {}: {e:?}", path.display()))
}

/// Writes frames as an animated GIF, `delay_ms` between frames, all framed alike (the union of
/// their regions) and coloured on one scale.
pub fn write_gif(frames: &[Frame], colouring: Colouring, width: u32, delay_ms: u32, path: &Path) -> Result<()> {
    let extent = frames.iter().filter_map(Frame::extent).reduce(|(a, b), (c, d)| (a.min(c), b.max(d)));
    let extent = extent.ok_or_else(|| anyhow!("nothing to draw (no grain, no wall in any frame)"))?;
    let scale = ColourScale::of(&frames.iter().collect::<Vec<_>>(), colouring);
    let layout = Layout::new(extent, width, super::plots::font_available(), legend_height(colouring, &scale));
    let root = BitMapBackend::gif(path, (layout.width, layout.height), delay_ms)
        .map_err(|e| anyhow!("writing {}: {e:?}", path.display()))?
        .into_drawing_area();
    for frame in frames {
        draw(&root, frame, colouring, &layout, &scale).with_context(|| format!("drawing {}", path.display()))?;
        root.present().map_err(|e| anyhow!("writing {}: {e:?}", path.display()))?;
    }
    Ok(())
}

/// The value range a colouring maps onto Viridis (speed: 0 to the largest; pressure: 0 to the
/// 99th percentile, the rare larger ones shown at the top colour), and the chains' largest force.
struct ColourScale {
    top: f64,
    clipped: bool,
    tags: Vec<u32>,
    max_force: f64,
}

impl ColourScale {
    fn of(frames: &[&Frame], colouring: Colouring) -> ColourScale {
        let mut values: Vec<f64> = match colouring {
            Colouring::Tag => vec![],
            Colouring::Speed => frames.iter().flat_map(|f| f.grains.iter().map(|g| g.velocity.length())).collect(),
            Colouring::Pressure => frames.iter().flat_map(|f| f.pressures()).collect(),
        };
        values.retain(|v| v.is_finite());
        let largest = values.iter().copied().reduce(f64::max).unwrap_or(0.0);
        let (top, clipped) = match colouring {
            Colouring::Pressure if !values.is_empty() => {
                let p99 = quantile(values, 0.99);
                (p99, p99 < largest)
            }
            _ => (largest, false),
        };
        let mut tags: Vec<u32> = frames.iter().flat_map(|f| f.grains.iter().map(|g| g.tag)).collect();
        tags.sort_unstable();
        tags.dedup();
        let max_force = frames
            .iter()
            .flat_map(|f| f.chains.iter().map(Chain::normal_force))
            .filter(|f| f.is_finite())
            .fold(0.0, f64::max);
        ColourScale { top: top.max(0.0), clipped, tags, max_force }
    }

    fn viridis(&self, v: f64) -> RGBColor {
        let t = if self.top > 0.0 { (v / self.top).clamp(0.0, 1.0) } else { 0.0 };
        ViridisRGB.get_color(t as f32)
    }
}

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("{e:?}")
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    frame: &Frame,
    colouring: Colouring,
    layout: &Layout,
    scale: &ColourScale,
) -> Result<()> {
    root.fill(&WHITE).map_err(plot_err)?;
    let (main, legend) = if layout.text {
        root.split_horizontally(layout.width - LEGEND_WIDTH)
    } else {
        root.split_horizontally(layout.width)
    };
    let (main, _) = main.split_vertically(layout.chart_height);
    let mut builder = ChartBuilder::on(&main);
    builder.margin(MARGIN);
    if layout.text {
        builder.margin_top(CAPTION).margin_right(0).x_label_area_size(X_LABELS).y_label_area_size(Y_LABELS);
    }
    let mut chart = builder.build_cartesian_2d(layout.lo.x..layout.hi.x, layout.lo.y..layout.hi.y).map_err(plot_err)?;
    let area = chart.plotting_area();

    let pressures = if colouring == Colouring::Pressure { frame.pressures() } else { vec![] };
    for (k, g) in frame.grains.iter().enumerate() {
        let fill = match colouring {
            Colouring::Tag => TAG_PALETTE[g.tag as usize % TAG_PALETTE.len()],
            Colouring::Speed => scale.viridis(g.velocity.length()),
            Colouring::Pressure => scale.viridis(pressures[k]),
        };
        let at = (g.position.x, g.position.y);
        match &g.outline {
            None => {
                let r = ((g.radius * layout.scale).round() as i32).max(1);
                area.draw(&Circle::new(at, r, fill.filled())).map_err(plot_err)?;
                if r >= 3 {
                    area.draw(&Circle::new(at, r, OUTLINE.stroke_width(1))).map_err(plot_err)?;
                }
            }
            Some(v) => {
                let pts: Vec<(f64, f64)> = v.iter().map(|p| (p.x, p.y)).collect();
                area.draw(&Polygon::new(pts.clone(), fill.filled())).map_err(plot_err)?;
                let closed: Vec<_> = pts.iter().chain(pts.first()).copied().collect();
                area.draw(&PathElement::new(closed, OUTLINE.stroke_width(1))).map_err(plot_err)?;
            }
        }
    }
    for w in &frame.walls {
        let mut pts: Vec<(f64, f64)> = w.iter().map(|p| (p.x, p.y)).collect();
        if pts.len() > 2 {
            pts.push(pts[0]);
        }
        area.draw(&PathElement::new(pts, BLACK.stroke_width(3))).map_err(plot_err)?;
    }
    let max_width = chain_max_width(frame, layout);
    if scale.max_force > 0.0 {
        for c in &frame.chains {
            let share = c.normal_force() / scale.max_force;
            if share < 0.02 {
                continue;
            }
            let w = ((share * max_width).round() as u32).max(1);
            let line = vec![(c.from.x, c.from.y), (c.to.x, c.to.y)];
            area.draw(&PathElement::new(line, CHAIN_COLOUR.stroke_width(w))).map_err(plot_err)?;
        }
    }
    if !layout.text {
        return Ok(());
    }

    // What was drawn past the plot (grains, walls) is covered before the axes go on.
    let (xs, ys) = area.get_pixel_range();
    let (w, h) = main.dim_in_pixel();
    let covers = [
        ((0, 0), (w as i32, ys.start)),
        ((0, ys.end), (w as i32, h as i32)),
        ((0, 0), (xs.start, h as i32)),
        ((xs.end, 0), (w as i32, h as i32)),
    ];
    for (a, b) in covers {
        main.draw(&Rectangle::new([a, b], WHITE.filled())).map_err(plot_err)?;
    }
    main.draw(&Rectangle::new([(xs.start, ys.start), (xs.end, ys.end)], BLACK.stroke_width(1))).map_err(plot_err)?;
    // Enough decimals to tell neighbouring ticks apart (about 8 along x, 6 along y).
    let decimals = |span: f64, ticks: f64| (-(span / ticks).log10()).ceil().max(0.0) as usize;
    let (dx, dy) = (decimals(layout.hi.x - layout.lo.x, 8.0), decimals(layout.hi.y - layout.lo.y, 6.0));
    let (x_tick, y_tick) = (move |v: &f64| format!("{v:.dx$}"), move |v: &f64| format!("{v:.dy$}"));
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .x_labels(8)
        .y_labels(6)
        .x_label_formatter(&x_tick)
        .y_label_formatter(&y_tick)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(plot_err)?;
    let caption = match frame.time {
        Some(t) => format!("step {}, t = {}", frame.step, seconds(t)),
        None => format!("step {}", frame.step),
    };
    main.draw(&Text::new(caption, (xs.start, 8), ("sans-serif", 18))).map_err(plot_err)?;
    draw_legend(&legend, colouring, scale, max_width, layout)
}

/// The widest chain (pixels): half a mean grain radius, between 1 and 12.
fn chain_max_width(frame: &Frame, layout: &Layout) -> f64 {
    let n = frame.grains.len().max(1) as f64;
    let mean_radius = frame.grains.iter().map(|g| g.radius).sum::<f64>() / n;
    (0.5 * mean_radius * layout.scale).clamp(1.0, 12.0)
}

/// Four significant digits, plainly between 0.01 and 10⁵, else in scientific notation.
fn number(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-2..1e5).contains(&v.abs()) {
        let decimals = (3 - v.abs().log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.3e}")
    }
}

/// A time in seconds with the digits that matter.
fn seconds(t: f64) -> String {
    if t == 0.0 || (1e-3..1e4).contains(&t.abs()) {
        format!("{t:.4} s")
    } else {
        format!("{t:.3e} s")
    }
}

/// A length with its unit: 2 m, 50 cm, 5 mm, 200 µm.
fn length_label(l: f64) -> String {
    let trim = |v: f64| format!("{}", (v * 1e6).round() / 1e6);
    if l >= 1.0 {
        format!("{} m", trim(l))
    } else if l >= 1e-2 {
        format!("{} cm", trim(l * 1e2))
    } else if l >= 1e-3 {
        format!("{} mm", trim(l * 1e3))
    } else {
        format!("{} µm", trim(l * 1e6))
    }
}

/// The longest of 1, 2, 5 × 10^k that fits in `max`.
fn nice_length(max: f64) -> f64 {
    let decade = 10f64.powf(max.log10().floor());
    [5.0, 2.0, 1.0].into_iter().map(|m| m * decade).find(|&l| l <= max).unwrap_or(decade)
}

fn draw_legend<DB: DrawingBackend>(
    legend: &DrawingArea<DB, Shift>,
    colouring: Colouring,
    scale: &ColourScale,
    max_width: f64,
    layout: &Layout,
) -> Result<()> {
    let text = |s: String, at: (i32, i32), size: i32| legend.draw(&Text::new(s, at, ("sans-serif", size)));
    let mut y = CAPTION as i32 + 4;
    match colouring {
        Colouring::Tag => {
            text("grains by tag".into(), (10, y), 16).map_err(plot_err)?;
            y += 26;
            for &t in scale.tags.iter().take(8) {
                let c = TAG_PALETTE[t as usize % TAG_PALETTE.len()];
                legend.draw(&Circle::new((20, y + 7), 7, c.filled())).map_err(plot_err)?;
                legend.draw(&Circle::new((20, y + 7), 7, OUTLINE.stroke_width(1))).map_err(plot_err)?;
                text(format!("tag {t}"), (34, y), 14).map_err(plot_err)?;
                y += 20;
            }
            if scale.tags.len() > 8 {
                text(format!("… {} tags, colours repeat", scale.tags.len()), (10, y), 13).map_err(plot_err)?;
                y += 20;
            }
        }
        Colouring::Speed | Colouring::Pressure => {
            let title = if colouring == Colouring::Speed { "speed (m/s)" } else { "pressure (N/m)" };
            text(title.into(), (10, y), 16).map_err(plot_err)?;
            y += 26;
            let bar = 150;
            for k in 0..bar {
                let c = scale.viridis(scale.top * (1.0 - k as f64 / (bar - 1) as f64));
                legend.draw(&Rectangle::new([(12, y + k), (34, y + k + 1)], c.filled())).map_err(plot_err)?;
            }
            legend.draw(&Rectangle::new([(12, y), (34, y + bar)], BLACK.stroke_width(1))).map_err(plot_err)?;
            let top = format!("{}{}", if scale.clipped { "≥ " } else { "" }, number(scale.top));
            text(top, (40, y - 6), 14).map_err(plot_err)?;
            text(number(0.5 * scale.top), (40, y + bar / 2 - 7), 14).map_err(plot_err)?;
            text("0".into(), (40, y + bar - 8), 14).map_err(plot_err)?;
            y += bar + 12;
            if scale.clipped {
                text("(top 1 % clipped)".into(), (10, y), 13).map_err(plot_err)?;
                y += 18;
            }
        }
    }
    y += 16;
    text("normal force (N)".into(), (10, y), 16).map_err(plot_err)?;
    y += 26;
    if scale.max_force > 0.0 {
        let mut last_width = 0;
        for share in [1.0, 0.5, 0.25] {
            let w = ((share * max_width).round() as u32).max(1);
            if w == last_width {
                break; // thin chains all look alike
            }
            last_width = w;
            legend
                .draw(&PathElement::new(vec![(10, y + 7), (50, y + 7)], CHAIN_COLOUR.stroke_width(w)))
                .map_err(plot_err)?;
            text(number(share * scale.max_force), (58, y), 14).map_err(plot_err)?;
            y += 22;
        }
        text("(below 2 % not drawn)".into(), (10, y), 13).map_err(plot_err)?;
        y += 18;
    } else {
        text("no loaded contact".into(), (10, y), 14).map_err(plot_err)?;
        y += 20;
    }
    // The scale bar: the longest 1, 2 or 5 × 10^k that fits in the panel.
    y += 16;
    let length = nice_length(150.0 / layout.scale);
    let px = (length * layout.scale).round() as i32;
    text(format!("scale: {}", length_label(length)), (10, y), 16).map_err(plot_err)?;
    y += 26;
    legend.draw(&Rectangle::new([(10, y), (10 + px, y + 5)], BLACK.filled())).map_err(plot_err)?;
    Ok(())
}

/// The picture files `moreau picture` writes for `dir`: `state_NNNNNN.png` or `run.gif` in `dir`.
pub fn default_path(dir: &Path, step: Option<usize>) -> PathBuf {
    match step {
        Some(s) => dir.join(format!("state_{s:06}.png")),
        None => dir.join("run.gif"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disk(x: f64, y: f64, r: f64, v: DVec2) -> Grain {
        Grain { position: DVec2::new(x, y), radius: r, outline: None, velocity: v, tag: 0 }
    }

    #[test]
    fn the_frame_leaves_out_a_stray_grain_and_an_empty_box_top() {
        let mut frame = Frame::default();
        for k in 0..400 {
            frame.grains.push(disk((k % 20) as f64 * 0.1, (k / 20) as f64 * 0.1, 0.05, DVec2::ZERO));
        }
        // A 10 m tall box around a 2 m pile, and one grain flung 100 m away.
        frame.walls = vec![vec![DVec2::new(-0.05, -0.05), DVec2::new(-0.05, 10.0)]];
        frame.grains.push(disk(100.0, 0.0, 0.05, DVec2::ZERO));
        let (lo, hi) = frame.extent().unwrap();
        assert!(lo.x > -0.3 && lo.y > -0.3 && hi.x < 2.3 && hi.y < 2.3, "{lo} {hi}");
        assert!(lo.x < -0.05 && hi.y > 1.95, "the pile itself is in: {lo} {hi}");
        // A plate (a piston) far above the pile is part of the picture.
        frame.grains.push(disk(1.0, 5.0, 1.0, DVec2::ZERO));
        let (_, hi) = frame.extent().unwrap();
        assert!(hi.y > 6.0 && hi.x < 2.3, "{hi}");
    }

    #[test]
    fn a_disk_squeezed_by_two_opposite_forces_has_pressure_f_over_pi_r() {
        let (r, f) = (0.5, 3.0);
        let mut frame = Frame::default();
        frame.grains.push(disk(0.0, 0.0, r, DVec2::ZERO));
        for side in [-1.0, 1.0] {
            // The force on the grain pushes it away from the contact, along the normal.
            let normal = DVec2::new(-side, 0.0);
            frame.chains.push(Chain {
                body: 0,
                other: None,
                from: DVec2::ZERO,
                to: DVec2::new(side * r, 0.0),
                point: DVec2::new(side * r, 0.0),
                normal,
                force: f * normal,
            });
        }
        let p = frame.pressures()[0];
        assert!((p - f / (std::f64::consts::PI * r)).abs() < 1e-12, "{p}");
        assert!(frame.chains.iter().all(|c| (c.normal_force() - f).abs() < 1e-12));
    }

    /// Counts the pixels of each colour in a PNG.
    fn colour_counts(path: &Path) -> (u32, u32, std::collections::HashMap<[u8; 3], usize>) {
        let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        let mut counts = std::collections::HashMap::new();
        for px in buf[..info.buffer_size()].chunks_exact(3) {
            *counts.entry([px[0], px[1], px[2]]).or_insert(0) += 1;
        }
        (info.width, info.height, counts)
    }

    #[test]
    fn grains_are_coloured_by_speed_on_one_scale() {
        let mut frame = Frame { step: 3, time: Some(0.25), ..Frame::default() };
        frame.grains.push(disk(0.0, 0.0, 1.0, DVec2::ZERO));
        frame.grains.push(disk(4.0, 0.0, 1.0, DVec2::new(3.0, 4.0)));
        frame.grains.push(disk(8.0, 0.0, 1.0, DVec2::new(0.0, 2.5)));
        let path = std::env::temp_dir().join(format!("moreau-picture-{}.png", std::process::id()));
        write_png(&frame, Colouring::Speed, 800, &path).unwrap();
        let (width, _, counts) = colour_counts(&path);
        assert_eq!(width, 800);
        let scale = ColourScale::of(&[&frame], Colouring::Speed);
        assert_eq!(scale.top, 5.0);
        // Each disk is about π (r · pixels per metre)² pixels of its own colour.
        let layout = Layout::new(frame.extent().unwrap(), 800, super::super::plots::font_available(), 0);
        let area = std::f64::consts::PI * layout.scale * layout.scale;
        for speed in [0.0, 5.0, 2.5] {
            let c = scale.viridis(speed);
            let n = counts.get(&[c.0, c.1, c.2]).copied().unwrap_or(0) as f64;
            assert!(n > 0.7 * area && n < 1.1 * area, "speed {speed}: {n} pixels of {c:?}, disk area {area}");
        }
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn labels_name_their_units() {
        assert_eq!(length_label(nice_length(0.037)), "2 cm");
        assert_eq!(length_label(nice_length(7.0)), "5 m");
        assert_eq!(length_label(nice_length(0.0011)), "1 mm");
        assert_eq!(length_label(nice_length(3e-4)), "200 µm");
        assert_eq!(number(26.0512), "26.05");
        assert_eq!(number(3790.4), "3790");
        assert_eq!(number(2.5e6), "2.500e6");
        assert_eq!(seconds(0.25), "0.2500 s");
    }
}
