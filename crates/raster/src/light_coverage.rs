//! Light coverage: how much of each pixel sees a light directly, and the light it sees there.
//!
//! The ground truth averages every pixel over its area (the path tracer jitters its camera
//! rays across the pixel), and a light is so much brighter than 1 that a pixel it covers by a
//! few percent is white after the tone map's clamp. The G-buffer samples only the pixel's
//! centre, so at a light's edge nothing tells a network how much of the pixel the light covers:
//! in the default cornellbox bake that one-pixel ring (0.5% of the pixels) held 87% of
//! GlassNet's squared error over the whole frame before the networks were given the coverage
//! (docs/history/benchmarks-2026-11.md).
//!
//! [`light_coverage`] rasterizes the opaque and naive G-buffers at `factor` x `factor` the
//! resolution and reduces each per pixel: `coverage` is the share of sub-samples whose L_d
//! alone reaches 1 in every channel (a light seen directly, or a surface lit so strongly that
//! the clamp makes it white), and `light` the L_d of
//! those sub-samples summed and divided by all `factor^2`. An image p of everything else then
//! becomes [`composite`]: min(1, light + (1 - coverage) p), the box-filtered pixel the ground
//! truth holds.

use glassbake_core::layout::{self, opaque};
use glassbake_core::{Camera, Error, PlanarImage, Result};
use glassbake_scene::Scene;

use crate::{Frame, Rasterizer};

/// Sub-samples per pixel side that the frame's buffers ([`Rasterizer::render`]) and the
/// real-time frame take their light coverage from: 16 per pixel, the coverage in steps of
/// 1/16 (tests/light_coverage.rs measures the error against the exact area).
pub const LIGHT_COVERAGE_FACTOR: u32 = 4;

/// The light coverage of one frame's opaque and naive G-buffers (layers
/// `layout::OPAQUE_LIGHT_COVERAGE_LAYER` and `layout::NAIVE_LIGHT_COVERAGE_LAYER`): the naive
/// one sees glass where glass is in front of a light, as the naive G-buffer does.
#[derive(Clone, Debug)]
pub struct LightCoverage {
    pub opaque: PlanarImage,
    pub naive: PlanarImage,
}

/// Per pixel of a `width` x `height` frame: the share of it that sees a light, and the
/// light seen, from the opaque and naive G-buffers rasterized at `factor` times the resolution.
pub fn light_coverage(rasterizer: &mut Rasterizer, scene: &Scene, camera: &Camera, width: u32, height: u32, factor: u32) -> Result<LightCoverage> {
    let mut frame = fine_frame(rasterizer, scene, camera, width, height, factor)?;
    let opaque = reduce(&frame.opaque()?, width, height, factor, layout::opaque_light_coverage_channel_names())?;
    let naive = reduce(&frame.naive()?, width, height, factor, layout::naive_light_coverage_channel_names())?;
    Ok(LightCoverage { opaque, naive })
}

/// [`light_coverage`] of one G-buffer only, the naive one if `naive`: what a real-time frame,
/// which runs one model, needs.
pub fn light_coverage_of(
    rasterizer: &mut Rasterizer,
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    factor: u32,
    naive: bool,
) -> Result<PlanarImage> {
    let mut frame = fine_frame(rasterizer, scene, camera, width, height, factor)?;
    if naive {
        reduce(&frame.naive()?, width, height, factor, layout::naive_light_coverage_channel_names())
    } else {
        reduce(&frame.opaque()?, width, height, factor, layout::opaque_light_coverage_channel_names())
    }
}

/// The frame at `factor` x `factor` the resolution that the coverage is reduced from.
fn fine_frame<'r>(rasterizer: &'r mut Rasterizer, scene: &Scene, camera: &Camera, width: u32, height: u32, factor: u32) -> Result<Frame<'r>> {
    if factor == 0 {
        return Err(Error::bad_input(&scene.name, "light coverage factor", "must be at least 1"));
    }
    let (fine_width, fine_height) = (width.checked_mul(factor), height.checked_mul(factor));
    let (Some(fine_width), Some(fine_height)) = (fine_width, fine_height) else {
        return Err(Error::bad_input(&scene.name, "light coverage factor", format!("{width}x{height} times {factor} overflows")));
    };
    rasterizer.begin_frame(scene, camera, fine_width, fine_height)
}

/// The largest factor up to [`LIGHT_COVERAGE_FACTOR`] at which `rasterizer` can draw a
/// `width` x `height` frame (a large real-time frame may not fit the device's limits 4x over).
pub fn coverage_factor(rasterizer: &Rasterizer, width: u32, height: u32) -> u32 {
    (1..=LIGHT_COVERAGE_FACTOR).rev().find(|&k| rasterizer.fits(width.saturating_mul(k), height.saturating_mul(k))).unwrap_or(1)
}

/// A G-buffer at `factor` x `factor` sub-samples per pixel reduced to the light coverage of
/// the `width` x `height` frame.
fn reduce(fine: &PlanarImage, width: u32, height: u32, factor: u32, names: Vec<String>) -> Result<PlanarImage> {
    let ld = [0, 1, 2].map(|c| fine.plane(opaque::LD + c));
    let (w, h, k) = (width as usize, height as usize, factor as usize);
    let fine_width = fine.width() as usize;
    let mut planes = vec![0.0f32; layout::LIGHT_COVERAGE_CHANNELS * w * h];
    let share = 1.0 / (k * k) as f32;
    for y in 0..h {
        for x in 0..w {
            let (mut covered, mut light) = (0.0f32, [0.0f32; 3]);
            for sy in 0..k {
                for sx in 0..k {
                    let at = (y * k + sy) * fine_width + x * k + sx;
                    let sample = ld.map(|plane| plane[at]);
                    if sample.iter().all(|&v| v >= 1.0) {
                        covered += share;
                        for c in 0..3 {
                            light[c] += sample[c] * share;
                        }
                    }
                }
            }
            let pixel = y * w + x;
            planes[layout::light_coverage::COVERAGE * w * h + pixel] = covered;
            for c in 0..3 {
                planes[(layout::light_coverage::LIGHT + c) * w * h + pixel] = light[c];
            }
        }
    }
    PlanarImage::from_planes(width, height, names, planes)
}

/// The pixel the ground truth holds, from a pixel's light coverage and light and the value
/// `rest` of everything else in it (all linear RGB, the result clamped to [0, 1]).
pub fn composite(coverage: f32, light: [f32; 3], rest: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|c| (light[c] + (1.0 - coverage) * rest[c]).clamp(0.0, 1.0))
}
