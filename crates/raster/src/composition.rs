//! How much of a frame's glass covers textured detail: the share of pixels inside any
//! transparency buffer's coverage whose opaque albedo (what lies behind the glass) has local
//! contrast. The paper's claim is about exactly those pixels (text, taps, wood seen through
//! glass), so a scene whose glass stands in front of plain walls cannot show it.

use glam::Vec3;
use glassbake_core::color::luminance;
use glassbake_core::layout::{opaque, transparent};
use glassbake_core::PlanarImage;

use crate::FrameBuffers;

/// Half the side of the square window in which local contrast is measured (5x5 pixels).
pub const DETAIL_WINDOW_RADIUS: usize = 2;
/// Albedo luminance range within the window above which a pixel counts as detailed. Printed
/// text (0.03 on 0.7), tile grout and box edges against the walls are far above it, smooth
/// shading-free plain surfaces are at 0.
pub const DETAIL_CONTRAST: f32 = 0.1;

/// Coverage above which a pixel belongs to a transparent object.
const COVERED: f32 = 0.5;

/// Glass pixels of one frame, and how many of them have detail behind them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DetailBehindGlass {
    pub glass_pixels: usize,
    pub detailed_pixels: usize,
}

impl std::ops::Add for DetailBehindGlass {
    type Output = DetailBehindGlass;

    /// The counts of two frames together.
    fn add(self, other: DetailBehindGlass) -> DetailBehindGlass {
        DetailBehindGlass { glass_pixels: self.glass_pixels + other.glass_pixels, detailed_pixels: self.detailed_pixels + other.detailed_pixels }
    }
}

impl DetailBehindGlass {
    /// Share of glass pixels with detail behind them (0 when there is no glass).
    pub fn share(&self) -> f64 {
        if self.glass_pixels == 0 {
            0.0
        } else {
            self.detailed_pixels as f64 / self.glass_pixels as f64
        }
    }
}

/// Luminance of the opaque albedo, per pixel.
fn albedo_luminance(opaque_buffer: &PlanarImage) -> Vec<f32> {
    let [r, g, b] = [0, 1, 2].map(|c| opaque_buffer.plane(opaque::ALBEDO + c));
    r.iter().zip(g).zip(b).map(|((&r, &g), &b)| luminance(Vec3::new(r, g, b))).collect()
}

/// Counts the glass pixels of `frame` and those with albedo contrast behind them.
pub fn detail_behind_glass(frame: &FrameBuffers) -> DetailBehindGlass {
    let (w, h) = (frame.opaque.width() as usize, frame.opaque.height() as usize);
    let luminance = albedo_luminance(&frame.opaque);
    let mut counts = DetailBehindGlass::default();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !frame.transparent.iter().any(|t| t.plane(transparent::COVERAGE)[i] > COVERED) {
                continue;
            }
            counts.glass_pixels += 1;
            let r = DETAIL_WINDOW_RADIUS;
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                    let l = luminance[yy * w + xx];
                    lo = lo.min(l);
                    hi = hi.max(l);
                }
            }
            if hi - lo > DETAIL_CONTRAST {
                counts.detailed_pixels += 1;
            }
        }
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light_coverage::LightCoverage;
    use glassbake_core::layout::{self, opaque_channel_names, transparent_channel_names};

    /// A `side` x `side` frame: opaque albedo from `albedo(x, y)`, one glass object covering
    /// the pixels where `glass(x, y)`.
    fn frame(side: u32, albedo: impl Fn(usize, usize) -> f32, glass: impl Fn(usize, usize) -> bool) -> FrameBuffers {
        let n = (side * side) as usize;
        let mut opaque_buffer = PlanarImage::new(side, side, opaque_channel_names());
        let mut glass_buffer = PlanarImage::new(side, side, transparent_channel_names(0));
        for i in 0..n {
            let (x, y) = (i % side as usize, i / side as usize);
            for c in 0..3 {
                opaque_buffer.plane_mut(opaque::ALBEDO + c)[i] = albedo(x, y);
            }
            glass_buffer.plane_mut(transparent::COVERAGE)[i] = if glass(x, y) { 1.0 } else { 0.0 };
        }
        let no_light = |names| PlanarImage::new(side, side, names);
        let light_coverage =
            LightCoverage { opaque: no_light(layout::opaque_light_coverage_channel_names()), naive: no_light(layout::naive_light_coverage_channel_names()) };
        FrameBuffers { naive: opaque_buffer.clone(), opaque: opaque_buffer, transparent: vec![glass_buffer], light_coverage, through: Vec::new() }
    }

    #[test]
    fn plain_wall_behind_glass_has_no_detail() {
        let counts = detail_behind_glass(&frame(16, |_, _| 0.7, |x, _| x < 8));
        assert_eq!(counts, DetailBehindGlass { glass_pixels: 128, detailed_pixels: 0 });
        assert_eq!(counts.share(), 0.0);
    }

    #[test]
    fn text_behind_glass_counts_within_the_window() {
        // One dark glyph column at x = 10 on a white wall; glass covers x in 4..16.
        let counts = detail_behind_glass(&frame(16, |x, _| if x == 10 { 0.03 } else { 0.7 }, |x, _| x >= 4));
        assert_eq!(counts.glass_pixels, 12 * 16);
        // Pixels within 2 columns of the glyph: x in 8..=12.
        assert_eq!(counts.detailed_pixels, 5 * 16);
        // Faint variation below the threshold does not count.
        let faint = detail_behind_glass(&frame(16, |x, _| 0.7 + 0.01 * (x % 2) as f32, |_, _| true));
        assert_eq!(faint.detailed_pixels, 0);
        assert!(((counts + faint).share() - 80.0 / (192.0 + 256.0)).abs() < 1e-12);
    }
}
