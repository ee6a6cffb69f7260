//! Plots for the report, drawn once as SVG (inlined in the HTML) and once as PNG, with plotters.
//! Text needs a TrueType font: the first of the usual system sans-serif fonts is registered at
//! run time (`fonts-dejavu-core` on Debian); without one, plots are not drawn and the report
//! says so.

use std::sync::OnceLock;

use glassbake_core::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

const SIZE: (u32, u32) = (720, 400);
const FONT_CANDIDATES: [&str; 5] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
];
const COLOURS: [RGBColor; 6] =
    [RGBColor(31, 119, 180), RGBColor(214, 39, 40), RGBColor(44, 160, 44), RGBColor(255, 127, 14), RGBColor(148, 103, 189), RGBColor(140, 86, 75)];

/// Registers a system font for plot text once; false when none was found.
pub fn font_available() -> bool {
    static FOUND: OnceLock<bool> = OnceLock::new();
    *FOUND.get_or_init(|| {
        let from_env = std::env::var("GLASSBAKE_FONT").ok();
        for path in from_env.iter().map(String::as_str).chain(FONT_CANDIDATES) {
            if let Ok(bytes) = std::fs::read(path) {
                // plotters keeps fonts for the life of the process; this happens once.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return true;
                }
            }
        }
        false
    })
}

/// A named polyline.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Dashed lines for the second series of a pair (validation beside training).
    pub dashed: bool,
}

pub struct Plot {
    pub svg: String,
    pub png: Vec<u8>,
}

fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::Internal(format!("drawing a plot: {e}"))
}

fn render(
    draw: impl Fn(&DrawingArea<SVGBackend, Shift>) -> Result<()>,
    draw_png: impl Fn(&DrawingArea<BitMapBackend, Shift>) -> Result<()>,
) -> Result<Option<Plot>> {
    if !font_available() {
        return Ok(None);
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        draw(&root)?;
        root.present().map_err(plot_error)?;
    }
    let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
        draw_png(&root)?;
        root.present().map_err(plot_error)?;
    }
    let mut png = Vec::new();
    image::RgbImage::from_raw(SIZE.0, SIZE.1, rgb)
        .expect("buffer of the plot's size")
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(plot_error)?;
    Ok(Some(Plot { svg, png }))
}

fn range_of(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        (0.0, 1.0)
    } else if lo == hi {
        (lo - 0.5, hi + 0.5)
    } else {
        (lo, hi)
    }
}

fn draw_lines<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<()> {
    root.fill(&WHITE).map_err(plot_error)?;
    let (x0, x1) = range_of(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let (y0, y1) = range_of(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let pad = 0.05 * (y1 - y0);
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0 - pad..y1 + pad)
        .map_err(plot_error)?;
    chart.configure_mesh().x_desc(x_label).y_desc(y_label).light_line_style(WHITE.mix(0.0)).draw().map_err(plot_error)?;
    // Solid/dashed pairs (training and validation of one model) share a colour.
    let paired = series.iter().any(|s| s.dashed);
    for (i, s) in series.iter().enumerate() {
        let colour = COLOURS[(if paired { i / 2 } else { i }) % COLOURS.len()];
        let style = ShapeStyle { color: colour.to_rgba(), filled: false, stroke_width: 2 };
        let points = s.points.iter().copied();
        if s.dashed {
            chart.draw_series(DashedLineSeries::new(points, 6, 4, style)).map_err(plot_error)?
        } else {
            chart.draw_series(LineSeries::new(points, style)).map_err(plot_error)?
        }
        .label(&s.name)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(plot_error)?;
    Ok(())
}

/// Line chart. When some series are dashed, series 2i and 2i + 1 are a pair drawn in one colour.
pub fn line_chart(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<Option<Plot>> {
    render(|r| draw_lines(r, title, x_label, y_label, series), |r| draw_lines(r, title, x_label, y_label, series))
}

/// The value axis of a bar chart: from a whole number a little below the smallest value (not
/// from 0, where 1-3 dB between models around 30 dB would be invisible slivers; the tick labels
/// say where it starts) to a little above the largest.
fn bar_axis(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let margin = (0.15 * (hi - lo)).max(0.5);
    let bottom = if lo >= 0.0 { (lo - margin).floor().max(0.0) } else { (lo - margin).floor() };
    (bottom, hi + margin)
}

fn draw_bars<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str, y_label: &str, groups: &[String], bars: &[(String, Vec<f64>)]) -> Result<()> {
    root.fill(&WHITE).map_err(plot_error)?;
    let (bottom, top) = bar_axis(bars.iter().flat_map(|b| b.1.iter().copied()));
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..groups.len() as f64, bottom..top)
        .map_err(plot_error)?;
    chart.configure_mesh().y_desc(y_label).x_labels(0).disable_x_mesh().light_line_style(WHITE.mix(0.0)).draw().map_err(plot_error)?;
    // Group i spans [i, i + 1); its name is written at its top left.
    chart.draw_series(groups.iter().enumerate().map(|(i, g)| Text::new(g.clone(), (i as f64 + 0.1, top * 0.99), ("sans-serif", 15)))).map_err(plot_error)?;
    let width = 0.8 / bars.len() as f64;
    for (b, (name, values)) in bars.iter().enumerate() {
        let colour = COLOURS[b % COLOURS.len()];
        let rects = values.iter().enumerate().filter(|(_, v)| v.is_finite()).map(|(g, &v)| {
            let x0 = g as f64 + 0.1 + b as f64 * width;
            Rectangle::new([(x0, bottom), (x0 + width, v)], colour.filled())
        });
        chart.draw_series(rects).map_err(plot_error)?.label(name).legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], colour.filled()));
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(plot_error)?;
    Ok(())
}

/// Grouped bar chart: one group per entry of `groups`, one bar per entry of `bars` in each.
pub fn bar_chart(title: &str, y_label: &str, groups: &[String], bars: &[(String, Vec<f64>)]) -> Result<Option<Plot>> {
    render(|r| draw_bars(r, title, y_label, groups, bars), |r| draw_bars(r, title, y_label, groups, bars))
}

#[cfg(test)]
mod tests {
    use super::bar_axis;

    #[test]
    fn bar_axis_makes_a_decibel_visible() {
        // GlassNet, naive and the noise floor around 30 dB.
        let (bottom, top) = bar_axis([28.9, 29.9, 33.4, f64::NAN].into_iter());
        assert!(bottom <= 28.9 && top >= 33.4, "{bottom}..{top}");
        assert_eq!(bottom, bottom.floor(), "ticks start at a whole number");
        assert!(1.0 / (top - bottom) > 0.15, "1 dB is {:.0}% of the axis", 100.0 / (top - bottom));
        // Values near zero never push a non-negative axis below zero; nothing finite -> a unit axis.
        assert_eq!(bar_axis([0.2, 0.3].into_iter()).0, 0.0);
        assert_eq!(bar_axis([f64::NAN].into_iter()), (0.0, 1.0));
        let (b, t) = bar_axis([-3.0, 2.0].into_iter());
        assert!(b <= -3.0 && t >= 2.0);
    }
}
