//! Line plots for the reproduce reports (plotters, rendered into an RGB
//! buffer with an embedded DejaVu Sans, so no system font is needed, and
//! written with [`crate::png`]).

use crate::{AppError, AppResult};
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::path::Path;
use std::sync::Once;

/// One line: its label and its (x, y) points.
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points, in x order.
    pub points: Vec<(f64, f64)>,
}

/// One panel of a figure.
pub struct Panel<'a> {
    /// Title.
    pub title: &'a str,
    /// X axis label.
    pub x: &'a str,
    /// Y axis label.
    pub y: &'a str,
    /// Lines.
    pub series: Vec<Series>,
}

const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
];

/// Register the embedded font once.
fn font() {
    static FONT: Once = Once::new();
    FONT.call_once(|| {
        // An embedded font: cannot fail for valid TTF bytes; a failure only loses text.
        let _ = register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// One row of a bar chart over time: its label and its segments
/// (start, end, legend index), drawn in order.
pub struct Lane {
    /// Row label.
    pub label: String,
    /// Segments: [start, end) on the x axis and the legend entry they are.
    pub segments: Vec<(f64, f64, usize)>,
}

/// Render `lanes` as horizontal bars, one row each from the top, into a PNG
/// at `path` (written atomically); `legend` names the segment kinds.
pub fn write_lanes(
    path: &Path,
    title: &str,
    x: &str,
    legend: &[&str],
    lanes: &[Lane],
) -> AppResult<()> {
    font();
    let (w, h) = (1200u32, (120 + 14 * lanes.len()).clamp(240, 4000) as u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let err = |e: &dyn std::fmt::Display| AppError(format!("{}: plot: {e}", path.display()));
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let x1 = lanes
            .iter()
            .flat_map(|l| l.segments.iter().map(|s| s.1))
            .fold(1.0f64, f64::max);
        let n = lanes.len().max(1) as f64;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(150)
            .build_cartesian_2d(0.0..x1, (n - 0.5)..-0.5)
            .map_err(|e| err(&e))?;
        let label = |y: &f64| {
            lanes
                .get(y.round().max(0.0) as usize)
                .map_or_else(String::new, |l| l.label.clone())
        };
        chart
            .configure_mesh()
            .x_desc(x)
            .y_labels(lanes.len().min(60))
            .y_label_formatter(&label)
            .label_style(("sans-serif", 11))
            .draw()
            .map_err(|e| err(&e))?;
        for (k, name) in legend.iter().enumerate() {
            let c = COLOURS[k % COLOURS.len()];
            let bars = lanes.iter().enumerate().flat_map(|(row, l)| {
                l.segments.iter().filter(|s| s.2 == k).map(move |s| {
                    let y = row as f64;
                    Rectangle::new([(s.0, y - 0.35), (s.1, y + 0.35)], c.filled())
                })
            });
            chart
                .draw_series(bars)
                .map_err(|e| err(&e))?
                .label(*name)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], c.filled()));
        }
        legend_box(&mut chart).map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
    }
    crate::io::write_atomic(path, &crate::png::encode(w, h, &buf))
}

/// A chart of f64 axes on the bitmap.
type Chart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// The series' legend box, as every plot here draws it.
fn legend_box<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
) -> Result<(), DrawingAreaErrorKind<<BitMapBackend<'b> as DrawingBackend>::ErrorType>> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
}

/// The unit a y axis up to `y1` is drawn in (1 below 10^5, else the power
/// of ten of `y1`) and its label, `y` or `y (x1e7)`.
fn y_scale(y1: f64, y: &str) -> (f64, String) {
    if y1 < 1e5 || !y1.is_finite() {
        return (1.0, y.to_string());
    }
    let e = y1.log10().floor() as i32;
    (10f64.powi(e), format!("{y} (x1e{e})"))
}

/// Render `panels` side by side into a PNG at `path` (written atomically).
pub fn write(path: &Path, panels: &[Panel]) -> AppResult<()> {
    font();
    let (pw, h) = (640u32, 480u32);
    let w = pw * panels.len().max(1) as u32;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let err = |e: &dyn std::fmt::Display| AppError(format!("{}: plot: {e}", path.display()));
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let areas = root.split_evenly((1, panels.len().max(1)));
        for (p, area) in panels.iter().zip(areas) {
            let pts = p.series.iter().flat_map(|s| s.points.iter());
            let (mut x0, mut x1, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
            for &(x, y) in pts {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y1 = y1.max(y);
            }
            if !x0.is_finite() {
                (x0, x1) = (0.0, 1.0);
            }
            // Large values are drawn in units of a power of ten named on the
            // axis, so their labels fit the label area.
            let (scale, y_desc) = y_scale(y1, p.y);
            let y1 = y1 / scale;
            let y1 = if y1 > 0.0 { y1 * 1.15 } else { 1.0 };
            let mut chart = ChartBuilder::on(&area)
                .caption(p.title, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(x0..x1.max(x0 + 1e-9), 0.0..y1)
                .map_err(|e| err(&e))?;
            chart
                .configure_mesh()
                .x_desc(p.x)
                .y_desc(&y_desc)
                .label_style(("sans-serif", 14))
                .draw()
                .map_err(|e| err(&e))?;
            for (i, s) in p.series.iter().enumerate() {
                let c = COLOURS[i % COLOURS.len()];
                let pts: Vec<(f64, f64)> = s.points.iter().map(|&(x, y)| (x, y / scale)).collect();
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))
                    .map_err(|e| err(&e))?
                    .label(s.label.clone())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c));
                chart
                    .draw_series(pts.iter().map(|&q| Circle::new(q, 3, c.filled())))
                    .map_err(|e| err(&e))?;
            }
            legend_box(&mut chart).map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
    }
    crate::io::write_atomic(path, &crate::png::encode(w, h, &buf))
}

#[cfg(test)]
mod tests {
    use super::y_scale;

    #[test]
    fn large_axes_are_drawn_in_a_power_of_ten() {
        assert_eq!(y_scale(0.45, "CPI"), (1.0, "CPI".into()));
        assert_eq!(y_scale(99_999.0, "n"), (1.0, "n".into()));
        assert_eq!(y_scale(7.9e7, "cycles"), (1e7, "cycles (x1e7)".into()));
    }
}
