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
//! Per pixel, `coverage` is the share of it that sees a light and `light` the light seen,
//! summed over the pixel and divided by its area; an image p of everything else then becomes
//! [`composite`]: min(1, light + (1 - coverage) p), the box-filtered pixel the ground truth
//! holds. Two passes find it ([`CoverageMethod`]): where every emitter of a scene is a
//! rectangle light (every built-in scene), [`exact`] clips each light's projected outline to
//! each pixel of the frame's own G-buffer; where a scene has emissive meshes, [`sampled`]
//! rasterizes the G-buffer at `factor` x `factor` the resolution and counts the sub-samples
//! whose L_d alone reaches 1 in every channel.

pub(crate) mod exact;
pub(crate) mod sampled;

use glassbake_core::layout;
use glassbake_core::{Camera, Error, PlanarImage, Result};
use glassbake_scene::Scene;

use crate::{Frame, Rasterizer};

/// Sub-samples per pixel side of the sampled coverage, for the frame's buffers
/// ([`Rasterizer::render`]) and the real-time frame of a scene with emissive meshes: 16 per
/// pixel, the coverage in steps of 1/16 (tests/light_coverage.rs measures the error against
/// the exact area).
pub const LIGHT_COVERAGE_FACTOR: u32 = 4;

/// How a scene's light coverage is found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CoverageMethod {
    /// Each rectangle light's outline on the screen clipped to each pixel, where the frame's
    /// G-buffer does not hide the light at the pixel's centre: exact areas, at the frame's
    /// resolution.
    Exact,
    /// The G-buffer at `factor` x `factor` the frame's resolution, its sub-samples that see an
    /// emitter counted: any emitter, in steps of 1/factor^2.
    Sampled { factor: u32 },
}

impl CoverageMethod {
    /// Exact where every emitter of `scene` is a rectangle light, else sampled at `factor`
    /// sub-samples a side.
    pub fn for_scene(scene: &Scene, factor: u32) -> CoverageMethod {
        if exact::covers_every_emitter(scene) {
            CoverageMethod::Exact
        } else {
            CoverageMethod::Sampled { factor }
        }
    }
}

/// What a frame's coverage is reduced from: the sampled pass's factor (the frame is that much
/// finer than the coverage), or the lights' outlines for the exact pass (the frame is the
/// coverage's size).
pub(crate) enum Reduction {
    Sampled { factor: u32 },
    Exact { outlines: Vec<exact::LightOutline>, lights: usize },
}

impl Reduction {
    fn new(scene: &Scene, camera: &Camera, width: u32, height: u32, factor: u32) -> Result<Reduction> {
        if factor == 0 {
            return Err(Error::bad_input(&scene.name, "light coverage factor", "must be at least 1"));
        }
        Ok(match CoverageMethod::for_scene(scene, factor) {
            CoverageMethod::Exact => Reduction::Exact { outlines: exact::light_outlines(scene, camera, width, height), lights: scene.rect_lights.len() },
            CoverageMethod::Sampled { factor } => Reduction::Sampled { factor },
        })
    }

    /// How many times finer than the coverage its frame is drawn.
    pub(crate) fn factor(&self) -> u32 {
        match self {
            Reduction::Sampled { factor } => *factor,
            Reduction::Exact { .. } => 1,
        }
    }
}

/// The light coverage of one frame's opaque and naive G-buffers (layers
/// `layout::OPAQUE_LIGHT_COVERAGE_LAYER` and `layout::NAIVE_LIGHT_COVERAGE_LAYER`): the naive
/// one sees glass where glass is in front of a light, as the naive G-buffer does.
#[derive(Clone, Debug)]
pub struct LightCoverage {
    pub opaque: PlanarImage,
    pub naive: PlanarImage,
}

/// Per pixel of a `width` x `height` frame: the share of it that sees a light, and the light
/// seen ([`CoverageMethod::for_scene`]; `factor` sub-samples a side where it is sampled).
pub fn light_coverage(rasterizer: &mut Rasterizer, scene: &Scene, camera: &Camera, width: u32, height: u32, factor: u32) -> Result<LightCoverage> {
    let reduction = Reduction::new(scene, camera, width, height, factor)?;
    let mut frame = coverage_frame(rasterizer, scene, camera, width, height, &reduction)?;
    both_of_frame(&mut frame, &reduction)
}

/// Both G-buffers' coverage of `frame`, drawn at `reduction.factor()` times the coverage.
pub(crate) fn both_of_frame(frame: &mut Frame<'_>, reduction: &Reduction) -> Result<LightCoverage> {
    let opaque = frame.light_coverage(false, reduction, layout::opaque_light_coverage_channel_names())?;
    let naive = frame.light_coverage(true, reduction, layout::naive_light_coverage_channel_names())?;
    Ok(LightCoverage { opaque, naive })
}

/// The coverage of `frame`'s own pixels ([`CoverageMethod::Exact`]) when `scene`'s emitters
/// allow it: a frame drawn anyway then needs no second one.
pub(crate) fn exact_of_frame(frame: &mut Frame<'_>, scene: &Scene, camera: &Camera) -> Result<Option<LightCoverage>> {
    match Reduction::new(scene, camera, frame.width(), frame.height(), 1)? {
        reduction @ Reduction::Exact { .. } => both_of_frame(frame, &reduction).map(Some),
        Reduction::Sampled { .. } => Ok(None),
    }
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
    let reduction = Reduction::new(scene, camera, width, height, factor)?;
    let mut frame = coverage_frame(rasterizer, scene, camera, width, height, &reduction)?;
    let names = if naive { layout::naive_light_coverage_channel_names() } else { layout::opaque_light_coverage_channel_names() };
    frame.light_coverage(naive, &reduction, names)
}

/// [`light_coverage_of`] written into `out` from `byte_offset` on (a network input tensor's
/// storage on the rasterizer's device), on the GPU: nothing is read back or waited for.
#[allow(clippy::too_many_arguments)]
pub fn light_coverage_into(
    rasterizer: &mut Rasterizer,
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    factor: u32,
    naive: bool,
    out: &wgpu::Buffer,
    byte_offset: u64,
) -> Result<()> {
    let reduction = Reduction::new(scene, camera, width, height, factor)?;
    coverage_frame(rasterizer, scene, camera, width, height, &reduction)?.light_coverage_to_buffer(naive, &reduction, out, byte_offset)
}

/// [`light_coverage_of`] from `frame`'s own G-buffer (the frame at the coverage's size), where
/// `scene`'s emitters are all rectangle lights: the exact pass then needs no frame of its own.
/// `None` where the scene needs the sampled pass.
pub fn exact_light_coverage_of_frame(frame: &mut Frame<'_>, scene: &Scene, camera: &Camera, naive: bool) -> Result<Option<PlanarImage>> {
    match Reduction::new(scene, camera, frame.width(), frame.height(), 1)? {
        reduction @ Reduction::Exact { .. } => {
            let names = if naive { layout::naive_light_coverage_channel_names() } else { layout::opaque_light_coverage_channel_names() };
            frame.light_coverage(naive, &reduction, names).map(Some)
        }
        Reduction::Sampled { .. } => Ok(None),
    }
}

/// [`exact_light_coverage_of_frame`] written into `out` from `byte_offset` on, on the GPU
/// (nothing read back or waited for). Whether it was: false where the scene needs the sampled
/// pass.
pub fn exact_light_coverage_into_frame(
    frame: &mut Frame<'_>,
    scene: &Scene,
    camera: &Camera,
    naive: bool,
    out: &wgpu::Buffer,
    byte_offset: u64,
) -> Result<bool> {
    match Reduction::new(scene, camera, frame.width(), frame.height(), 1)? {
        reduction @ Reduction::Exact { .. } => frame.light_coverage_to_buffer(naive, &reduction, out, byte_offset).map(|()| true),
        Reduction::Sampled { .. } => Ok(false),
    }
}

/// The frame, at `reduction.factor()` times the resolution, that the coverage is reduced from.
fn coverage_frame<'r>(rasterizer: &'r mut Rasterizer, scene: &Scene, camera: &Camera, width: u32, height: u32, reduction: &Reduction) -> Result<Frame<'r>> {
    let factor = reduction.factor();
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

/// The pixel the ground truth holds, from a pixel's light coverage and light and the value
/// `rest` of everything else in it (all linear RGB, the result clamped to [0, 1]).
pub fn composite(coverage: f32, light: [f32; 3], rest: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|c| (light[c] + (1.0 - coverage) * rest[c]).clamp(0.0, 1.0))
}
