//! Line charts (plotters) as SVG and PNG: work-precision curves, performance profiles, the
//! friction study. Text needs a TrueType font: DejaVu Sans is looked for where Debian
//! (fonts-dejavu-core) and other systems put it, or in $MOREAU_FONT; without one, no chart is
//! drawn and the caller says so (the CSV files carry the same data).

use std::path::Path;
use std::sync::OnceLock;

use anyhow::{anyhow, bail, Result};
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

const FONT_PATHS: [&str; 4] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/Library/Fonts/Arial.ttf",
];

/// Registers a font once; false when none was found.
pub fn font_available() -> bool {
    static FOUND: OnceLock<bool> = OnceLock::new();
    *FOUND.get_or_init(|| {
        let mut candidates: Vec<String> = std::env::var("MOREAU_FONT").into_iter().collect();
        candidates.extend(FONT_PATHS.iter().map(|s| s.to_string()));
        for path in candidates {
            if let Ok(bytes) = std::fs::read(&path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return true;
                }
            }
        }
        false
    })
}

/// A series: label and (x, y) points.
pub type Series = (String, Vec<(f64, f64)>);

/// A line chart, written as SVG and PNG.
pub struct Chart<'a> {
    /// Title.
    pub title: &'a str,
    /// Label of the x axis.
    pub x_label: &'a str,
    /// Label of the y axis.
    pub y_label: &'a str,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The curves: label and points.
    pub series: &'a [Series],
}

fn bounds(series: &[Series], log: bool, pick: fn(&(f64, f64)) -> f64) -> (f64, f64) {
    let values = series.iter().flat_map(|(_, p)| p.iter().map(pick)).filter(|v| v.is_finite() && (!log || *v > 0.0));
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (1.0, 10.0);
    }
    if log {
        // A span under a decade widens to show a labelled power of ten; a longer one is padded
        // by 5 % of its decades, as a linear axis by 5 % of its span: a curve at the extreme
        // value (the most accurate setting of a chart) must not lie hidden on the frame.
        if hi / lo < 10.0 {
            (lo / 3.0, hi * 3.0)
        } else {
            let pad = (hi / lo).powf(0.05);
            (lo / pad, hi * pad)
        }
    } else {
        let pad = ((hi - lo) * 0.05).max(1e-12);
        (lo - pad, hi + pad)
    }
}

/// Tick text: powers of ten only on a log axis (the others stay unlabelled, or they collide), and
/// no binary-fraction noise (0.30000000000000004) on a linear one.
fn tick_label(v: f64, log: bool) -> String {
    if log {
        let e = v.log10();
        return if (e - e.round()).abs() < 1e-9 { format!("1e{}", e.round() as i32) } else { String::new() };
    }
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e4).contains(&a) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

fn draw<DB: DrawingBackend, X, Y>(root: DrawingArea<DB, plotters::coord::Shift>, c: &Chart, x: X, y: Y) -> Result<()>
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e:?}");
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(c.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x, y)
        .map_err(e)?;
    let fmt = |log: bool| move |v: &f64| tick_label(*v, log);
    chart
        .configure_mesh()
        .x_desc(c.x_label)
        .y_desc(c.y_label)
        .x_label_formatter(&fmt(c.log_x))
        .y_label_formatter(&fmt(c.log_y))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    for (k, (label, points)) in c.series.iter().enumerate() {
        let color = Palette99::pick(k).to_rgba();
        let pts: Vec<(f64, f64)> = points
            .iter()
            .copied()
            .filter(|(x, y)| x.is_finite() && y.is_finite() && (!c.log_x || *x > 0.0) && (!c.log_y || *y > 0.0))
            .collect();
        chart
            .draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(e)?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

fn draw_any<DB: DrawingBackend>(root: DrawingArea<DB, plotters::coord::Shift>, c: &Chart) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let (x0, x1) = bounds(c.series, c.log_x, |p| p.0);
    let (y0, y1) = bounds(c.series, c.log_y, |p| p.1);
    match (c.log_x, c.log_y) {
        (true, true) => draw(root, c, (x0..x1).log_scale(), (y0..y1).log_scale()),
        (true, false) => draw(root, c, (x0..x1).log_scale(), y0..y1),
        (false, true) => draw(root, c, x0..x1, (y0..y1).log_scale()),
        (false, false) => draw(root, c, x0..x1, y0..y1),
    }
}

/// Writes `stem.svg` and `stem.png`.
pub fn write_chart(stem: &Path, c: &Chart) -> Result<()> {
    if !font_available() {
        bail!("no TrueType font found for chart text (install fonts-dejavu-core or set MOREAU_FONT)");
    }
    let svg = stem.with_extension("svg");
    draw_any(SVGBackend::new(&svg, (900, 600)).into_drawing_area(), c)?;
    let png = stem.with_extension("png");
    draw_any(BitMapBackend::new(&png, (900, 600)).into_drawing_area(), c)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every point lies strictly inside the axis, on log and linear axes alike.
    #[test]
    fn points_at_the_extremes_stay_off_the_frame() {
        let points = vec![(4.9, 5.4e-5), (8.9, 5.6e-2), (33.2, 5.4e-5)];
        let series = [("a".to_string(), points.clone())];
        for log in [true, false] {
            let (x0, x1) = bounds(&series, log, |p| p.0);
            let (y0, y1) = bounds(&series, log, |p| p.1);
            for &(x, y) in &points {
                assert!(x0 < x && x < x1 && y0 < y && y < y1, "log {log}: ({x}, {y}) in [{x0}, {x1}] × [{y0}, {y1}]");
            }
        }
        // Less than a decade on a log axis: widened threefold either side.
        let short = [("b".to_string(), vec![(2.0, 1.0), (4.0, 1.0)])];
        assert_eq!(bounds(&short, true, |p| p.0), (2.0 / 3.0, 12.0));
    }
}
