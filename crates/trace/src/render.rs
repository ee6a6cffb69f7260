//! Whole images: settings, validation, tiles over rayon, deterministic per-pixel sampling,
//! and the discarding of non-finite samples.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;
use glassbake_core::layout::GROUND_TRUTH_CHANNELS;
use glassbake_core::{Camera, Error, PlanarImage, Result};
use glassbake_scene::Scene;
use rayon::prelude::*;

use crate::bsdf::MaterialModel;
use crate::integrator::{PathSettings, PreparedScene};
use crate::rng::Pcg32;

/// Side of the square tiles rayon schedules. Tiles only decide who computes a pixel, never
/// what it computes.
const TILE: u32 = 16;

#[derive(Clone, Debug, PartialEq)]
pub struct TraceSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// The image seed; for dataset sample `s` it is [`sample_trace_seed`]`(s)`.
    pub seed: u64,
    /// Longest path in segments (Mitsuba's convention: 1 = emitters only, 2 = direct light).
    pub max_depth: u32,
    /// Russian roulette applies to paths longer than this many segments.
    pub rr_depth: u32,
    /// Worker threads; `None` uses the current rayon pool. The image does not depend on it.
    pub threads: Option<usize>,
    pub material_model: MaterialModel,
}

impl TraceSettings {
    pub const DEFAULT_MAX_DEPTH: u32 = 64;
    pub const DEFAULT_RR_DEPTH: u32 = 5;

    pub fn new(width: u32, height: u32, spp: u32, seed: u64) -> Self {
        TraceSettings {
            width,
            height,
            spp,
            seed,
            max_depth: Self::DEFAULT_MAX_DEPTH,
            rr_depth: Self::DEFAULT_RR_DEPTH,
            threads: None,
            material_model: MaterialModel::Gltf,
        }
    }

    fn validate(&self) -> Result<()> {
        const SOURCE: &str = "trace settings";
        if self.width == 0 || self.height == 0 {
            return Err(Error::bad_input(SOURCE, "resolution", format!("{}x{} has no pixels", self.width, self.height)));
        }
        if self.spp == 0 {
            return Err(Error::bad_input(SOURCE, "spp", "must be at least 1"));
        }
        if self.max_depth == 0 {
            return Err(Error::bad_input(SOURCE, "max_depth", "must be at least 1 (1 = emitters seen directly)"));
        }
        if self.threads == Some(0) {
            return Err(Error::bad_input(SOURCE, "threads", "must be at least 1"));
        }
        Ok(())
    }
}

pub struct TraceOutput {
    /// Linear RGB radiance, channels `R`, `G`, `B` (`layout::GROUND_TRUTH_CHANNELS`). Each
    /// pixel is the mean of its finite samples.
    pub image: PlanarImage,
    /// Samples that came out NaN or infinite and were left out of their pixel's mean.
    pub discarded_samples: u64,
    /// Samples traced in all (pixels x spp).
    pub samples: u64,
    pub warnings: Vec<String>,
    /// Wall time of the render, BVH build included.
    pub elapsed: Duration,
}

impl TraceOutput {
    pub fn samples_per_second(&self) -> f64 {
        self.samples as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }
}

/// The image seed of a dataset sample: `glassbake dataset` and `glassbake trace --sample`
/// both use it, so the two render the same ground truth.
pub fn sample_trace_seed(sample_seed: u64) -> u64 {
    glassbake_core::seed::purpose_seed(sample_seed, "trace")
}

/// Progress callback: (pixels done, pixels in all). Called from worker threads.
pub type Progress<'a> = &'a (dyn Fn(u64, u64) + Sync);

/// Path trace `scene` as seen by `camera`.
pub fn render(scene: &Scene, camera: &Camera, settings: &TraceSettings, progress: Option<Progress>) -> Result<TraceOutput> {
    settings.validate()?;
    camera.check()?;
    match settings.threads {
        Some(threads) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| Error::Internal(format!("cannot start {threads} threads: {e}")))?;
            pool.install(|| render_in_pool(scene, camera, settings, progress))
        }
        None => render_in_pool(scene, camera, settings, progress),
    }
}

struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

fn render_in_pool(scene: &Scene, camera: &Camera, settings: &TraceSettings, progress: Option<Progress>) -> Result<TraceOutput> {
    let start = Instant::now();
    let (width, height) = (settings.width, settings.height);
    let channels: Vec<String> = GROUND_TRUTH_CHANNELS.iter().map(|c| c.to_string()).collect();
    let mut image = PlanarImage::new(width, height, channels);
    let total_pixels = width as u64 * height as u64;
    let samples = total_pixels * settings.spp as u64;
    let mut warnings = Vec::new();

    let prepared = PreparedScene::new(scene);
    if prepared.lights.is_empty() && scene.background == Vec3::ZERO {
        let has_emissive = scene.rect_lights.iter().any(|l| l.radiance.max_element() > 0.0) || !scene.emissive_objects().is_empty();
        if !has_emissive {
            let warning = format!("scene {}: no light (no rectangle light, no emissive mesh, black background): the image is black", scene.name);
            tracing::warn!("{warning}");
            warnings.push(warning);
            if let Some(p) = progress {
                p(total_pixels, total_pixels);
            }
            return Ok(TraceOutput { image, discarded_samples: 0, samples, warnings, elapsed: start.elapsed() });
        }
    }

    let path_settings =
        PathSettings { max_depth: settings.max_depth, rr_depth: settings.rr_depth, material_model: settings.material_model };
    let mut tiles = Vec::new();
    for y0 in (0..height).step_by(TILE as usize) {
        for x0 in (0..width).step_by(TILE as usize) {
            tiles.push(Tile { x0, y0, x1: (x0 + TILE).min(width), y1: (y0 + TILE).min(height) });
        }
    }
    let done = AtomicU64::new(0);
    let results: Vec<(Vec<Vec3>, u64)> = tiles
        .par_iter()
        .map(|tile| {
            let mut pixels = Vec::with_capacity(((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize);
            let mut discarded = 0;
            let mut scratch = Vec::new();
            for y in tile.y0..tile.y1 {
                for x in tile.x0..tile.x1 {
                    let (value, bad) = render_pixel(&prepared, camera, settings, &path_settings, x, y, &mut scratch);
                    pixels.push(value);
                    discarded += bad;
                }
            }
            let finished = done.fetch_add(pixels.len() as u64, Ordering::Relaxed) + pixels.len() as u64;
            if let Some(p) = progress {
                p(finished, total_pixels);
            }
            (pixels, discarded)
        })
        .collect();

    let mut discarded_samples = 0;
    for (tile, (pixels, discarded)) in tiles.iter().zip(results) {
        discarded_samples += discarded;
        let mut values = pixels.into_iter();
        for y in tile.y0..tile.y1 {
            for x in tile.x0..tile.x1 {
                let v = values.next().expect("one value per tile pixel");
                for (channel, component) in v.to_array().into_iter().enumerate() {
                    image.set(channel, x, y, component);
                }
            }
        }
    }
    if discarded_samples > 0 {
        let warning = format!("{discarded_samples} of {samples} samples were NaN or infinite and were discarded");
        tracing::warn!("{warning}");
        warnings.push(warning);
    }
    Ok(TraceOutput { image, discarded_samples, samples, warnings, elapsed: start.elapsed() })
}

/// One pixel: its own random stream, its samples in a fixed order, a box filter over the
/// pixel. Returns the mean of the finite samples and how many were not finite.
fn render_pixel(
    prepared: &PreparedScene,
    camera: &Camera,
    settings: &TraceSettings,
    path_settings: &PathSettings,
    x: u32,
    y: u32,
    scratch: &mut Vec<crate::geometry::Hit>,
) -> (Vec3, u64) {
    let pixel_index = y as u64 * settings.width as u64 + x as u64;
    let mut rng = Pcg32::for_pixel(settings.seed, pixel_index);
    let mut sum = [0.0f64; 3];
    let mut finite = 0u32;
    for _ in 0..settings.spp {
        let jitter = rng.next_vec2();
        let ray = camera.ray(x as f32 + jitter.x, y as f32 + jitter.y, settings.width, settings.height);
        let radiance = prepared.trace_path(&ray, &mut rng, path_settings, scratch);
        if radiance.is_finite() {
            for (s, c) in sum.iter_mut().zip(radiance.to_array()) {
                *s += c as f64;
            }
            finite += 1;
        }
    }
    let discarded = (settings.spp - finite) as u64;
    if finite == 0 {
        return (Vec3::ZERO, discarded);
    }
    let n = finite as f64;
    (Vec3::new((sum[0] / n) as f32, (sum[1] / n) as f32, (sum[2] / n) as f32), discarded)
}
