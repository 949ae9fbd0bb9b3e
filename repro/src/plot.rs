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

const COLOURS: [RGBColor; 7] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];

/// Render `panels` side by side into a PNG at `path` (written atomically).
pub fn write(path: &Path, panels: &[Panel]) -> AppResult<()> {
    static FONT: Once = Once::new();
    FONT.call_once(|| {
        // An embedded font: cannot fail for valid TTF bytes; a failure only loses text.
        let _ = register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
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
                .y_desc(p.y)
                .label_style(("sans-serif", 14))
                .draw()
                .map_err(|e| err(&e))?;
            for (i, s) in p.series.iter().enumerate() {
                let c = COLOURS[i % COLOURS.len()];
                chart
                    .draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(2)))
                    .map_err(|e| err(&e))?
                    .label(s.label.clone())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c));
                chart
                    .draw_series(s.points.iter().map(|&q| Circle::new(q, 3, c.filled())))
                    .map_err(|e| err(&e))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
    }
    crate::io::write_atomic(path, &crate::png::encode(w, h, &buf))
}
