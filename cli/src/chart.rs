//! Line charts written as SVG and PNG side by side, one or more panels in a
//! row, each with named series. Drawn with plotters; text uses the bundled
//! DejaVu Sans through ab_glyph, so no system font library is needed.

use std::path::{Path, PathBuf};
use std::sync::Once;

use anyhow::{anyhow, Context, Result};
pub use plotters::chart::SeriesLabelPosition;
use plotters::coord::Shift;
use plotters::prelude::*;

/// One named curve: (x, y) points in order.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Points.
    pub points: Vec<(f64, f64)>,
}

/// One panel: a title, axis names and its curves.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Caption above the panel.
    pub title: String,
    /// X axis name.
    pub x_label: String,
    /// Y axis name.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Where the legend goes (clear of the curves).
    pub legend: SeriesLabelPosition,
}

/// Series colors: dark enough to read on white, far apart in hue.
const COLORS: [(u8, u8, u8); 10] = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (148, 103, 189),
    (255, 127, 14),
    (23, 130, 140),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
];

/// Pixels per panel.
const PANEL: (u32, u32) = (640, 480);

static FONT: Once = Once::new();

/// Makes the bundled font the one text is drawn with (once per process).
pub fn register_font() {
    FONT.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../assets/DejaVuSans.ttf");
        // The font is bundled and known good; should it fail, text is left out rather than the chart.
        if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_err() {
            tracing::warn!("the bundled chart font did not load");
        }
    });
}

/// Writes `stem.svg` and `stem.png` with `panels` side by side; returns both paths.
pub fn write(stem: &Path, panels: &[Panel]) -> Result<[PathBuf; 2]> {
    register_font();
    let size = (PANEL.0 * panels.len().max(1) as u32, PANEL.1);
    let svg = stem.with_extension("svg");
    let png = stem.with_extension("png");
    draw(SVGBackend::new(&svg, size).into_drawing_area(), panels)
        .map_err(|e| anyhow!("{e}"))
        .with_context(|| format!("drawing {}", svg.display()))?;
    let mut rgb = vec![255u8; size.0 as usize * size.1 as usize * 3];
    draw(BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(), panels)
        .map_err(|e| anyhow!("{e}"))
        .with_context(|| format!("drawing {}", png.display()))?;
    image::RgbImage::from_raw(size.0, size.1, rgb)
        .context("chart buffer size")?
        .save(&png)
        .with_context(|| format!("writing {}", png.display()))?;
    Ok([svg, png])
}

/// The range of `values` with a margin, never empty.
fn span(values: impl Iterator<Item = f64>, from_zero: bool) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(v), h.max(v)));
    if lo > hi {
        return (0.0, 1.0);
    }
    let lo = if from_zero { lo.min(0.0) } else { lo };
    let pad = ((hi - lo) * 0.08).max(hi.abs() * 1e-3).max(1e-9);
    (if from_zero && lo >= 0.0 { lo } else { lo - pad }, hi + pad)
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    panels: &[Panel],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    for (area, p) in root.split_evenly((1, panels.len().max(1))).iter().zip(panels) {
        let points = || p.series.iter().flat_map(|s| s.points.iter());
        let (x0, x1) = span(points().map(|q| q.0), false);
        let (y0, y1) = span(points().map(|q| q.1), true);
        let mut chart = ChartBuilder::on(area)
            .caption(&p.title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(62)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .x_desc(&p.x_label)
            .y_desc(&p.y_label)
            .label_style(("sans-serif", 13))
            .light_line_style(RGBColor(238, 238, 238))
            .draw()?;
        for (k, s) in p.series.iter().enumerate() {
            let (r, g, b) = COLORS[k % COLORS.len()];
            let color = RGBColor(r, g, b).to_rgba();
            chart
                .draw_series(LineSeries::new(s.points.iter().copied(), color.stroke_width(2)))?
                .label(s.name.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
            chart.draw_series(s.points.iter().map(|&q| Circle::new(q, 3, color.filled())))?;
        }
        chart
            .configure_series_labels()
            .position(p.legend.clone())
            .label_font(("sans-serif", 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn charts_come_out_as_svg_with_text_and_a_png_with_the_curves() {
        let dir = tempfile::tempdir().unwrap();
        let panel = |title: &str| Panel {
            title: title.to_string(),
            x_label: "x".into(),
            y_label: "y".into(),
            legend: SeriesLabelPosition::UpperLeft,
            series: vec![
                Series {
                    name: "rising".into(),
                    points: vec![(0.0, 0.0), (1.0, 2.0), (2.0, 4.0)],
                },
                Series {
                    name: "flat".into(),
                    points: vec![(0.0, 1.0), (2.0, 1.0)],
                },
            ],
        };
        let [svg, png] = write(&dir.path().join("c"), &[panel("left"), panel("right")]).unwrap();
        let text = std::fs::read_to_string(svg).unwrap();
        for word in ["left", "right", "rising", "flat"] {
            assert!(text.contains(word), "{word} missing from the SVG");
        }
        let img = image::open(png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (2 * PANEL.0, PANEL.1));
        // Curves in two palette colors, text and axes in black: far from a blank page.
        let inked = img.pixels().filter(|p| p.0 != [255, 255, 255]).count();
        assert!(inked > 5_000, "{inked} pixels drawn");
        let colored = img
            .pixels()
            .filter(|p| {
                let [r, g, b] = p.0.map(i32::from);
                (r - g).abs() + (g - b).abs() + (r - b).abs() > 90
            })
            .count();
        assert!(colored > 500, "{colored} colored pixels");
    }
}
