//! The image driver: whole images from the path integrator (`integrator.rs`) and, for the
//! caustic estimator, the light tracer (`light_tracing.rs`) and photon merging's maps. It owns
//! settings and their validation, the tiles over rayon, deterministic per-pixel sampling, the
//! discarding of non-finite samples, more samples on the pixels that show glass when asked
//! (`TraceSettings::glass_spp`), adaptive sampling's pilot pass (`adaptive.rs`), stratified
//! sample values (`qmc.rs`), and the light paths (`render/light_passes.rs`), traced in chunks of their own streams and
//! summed in chunk order. Every pass is deterministic (per-pixel streams, results gathered in
//! tile order), so the image is bit-identical whatever the thread count.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;
use glassbake_core::camera::PrimaryRays;
use glassbake_core::layout::GROUND_TRUTH_CHANNELS;
use glassbake_core::{Camera, Error, PlanarImage, Result};
use glassbake_scene::Scene;
use rayon::prelude::*;

use crate::adaptive;
use crate::bsdf::MaterialModel;
use crate::caustic_paths::CausticPaths;
use crate::estimator::Estimator;
use crate::integrator::{PathHooks, PathScratch, PlainPaths};
use crate::light_tracing::{LightTracer, LightWalk, LIGHT_PATHS_PER_CAMERA_PATH};
use crate::path_class::PathFilter;
use crate::photon_merging::{merge_radius, MergingPath, PhotonMap, MAX_PHOTON_PATHS, PHOTON_PATHS_PER_CAMERA_SAMPLE};
use crate::prepared::{rays_cast, PathSettings, PreparedScene};
use crate::qmc::{self, StratifiedPixel};
use crate::rng::Pcg32;
use crate::triangle::Owner;

mod light_passes;

use light_passes::{trace_light, trace_photons, LightTraced};

/// Side of the square tiles rayon schedules. Tiles only decide who computes a pixel, never
/// what it computes.
const TILE: u32 = 16;

#[derive(Clone, Debug, PartialEq)]
pub struct TraceSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Samples per pixel on the pixels that show a transparent object in front of everything
    /// else (see [`glass_pixels`]), when more than `spp`. Which pixels those are follows from
    /// the geometry alone, never from the samples, so every pixel stays an unbiased mean; and
    /// as a pixel's samples are drawn from its own stream in order, each pixel is exactly the
    /// one a uniform render at its spp gives. A test image is thus converged where the
    /// transparent-pixel metrics measure it, at a fraction of the cost of a uniform render.
    pub glass_spp: Option<u32>,
    /// The image seed; for dataset sample `s` it is [`sample_trace_seed`]`(s)`.
    pub seed: u64,
    /// Longest path in segments (Mitsuba's convention: 1 = emitters only, 2 = direct light).
    pub max_depth: u32,
    /// Russian roulette applies to paths longer than this many segments.
    pub rr_depth: u32,
    /// Worker threads; `None` uses the current rayon pool. The image does not depend on it.
    pub threads: Option<usize>,
    pub material_model: MaterialModel,
    /// The estimator; its `Default` is the ground truth's (`caustic+adaptive+stratified`).
    pub estimator: Estimator,
    /// Count only some of the paths (an analysis tool; [`PathFilter::All`] otherwise).
    pub path_filter: PathFilter,
}

/// The largest image side the tracer accepts: its per-pixel sums (f64) of a 8192 x 8192 image
/// already take about 4 GB, and a larger request should be refused before it is allocated.
pub const MAX_SIDE: u32 = 8192;

impl TraceSettings {
    pub const DEFAULT_MAX_DEPTH: u32 = 64;
    pub const DEFAULT_RR_DEPTH: u32 = 5;

    pub fn new(width: u32, height: u32, spp: u32, seed: u64) -> Self {
        TraceSettings {
            width,
            height,
            spp,
            glass_spp: None,
            seed,
            max_depth: Self::DEFAULT_MAX_DEPTH,
            rr_depth: Self::DEFAULT_RR_DEPTH,
            threads: None,
            material_model: MaterialModel::Gltf,
            estimator: Estimator::default(),
            path_filter: PathFilter::All,
        }
    }

    /// An error naming the setting unless the settings describe an image that can be traced.
    pub fn validate(&self) -> Result<()> {
        const SOURCE: &str = "trace settings";
        if self.width == 0 || self.height == 0 {
            return Err(Error::bad_input(SOURCE, "resolution", format!("{}x{} has no pixels", self.width, self.height)));
        }
        if self.width > MAX_SIDE || self.height > MAX_SIDE {
            return Err(Error::bad_input(SOURCE, "resolution", format!("{}x{} is larger than {MAX_SIDE} px a side", self.width, self.height)));
        }
        if self.spp == 0 {
            return Err(Error::bad_input(SOURCE, "spp", "must be at least 1"));
        }
        if let Some(glass_spp) = self.glass_spp {
            if glass_spp < self.spp {
                return Err(Error::bad_input(SOURCE, "glass_spp", format!("{glass_spp} is below spp {}: glass pixels get at least spp samples", self.spp)));
            }
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
    /// Samples traced in all (pixels x spp, glass pixels at `glass_spp`; adaptive sampling's
    /// pilot included).
    pub samples: u64,
    /// Samples of the adaptive pilot pass (part of `samples`, set aside: see
    /// [`crate::adaptive`]); 0 when sampling uniformly.
    pub pilot_samples: u64,
    /// Rays the camera samples cast (closest hits and shadow rays, the pilot's included): a
    /// measure of their cost that, unlike seconds, does not depend on the machine's load.
    pub camera_rays: u64,
    /// Light paths the `caustic` estimator traced into the image (balanced per image,
    /// `light_tracing::balanced_light_paths`), and those of its pilot, set aside.
    pub light_paths: u64,
    pub light_pilot_paths: u64,
    /// Light paths traced for photon merging (`caustic+merging`): for the
    /// caustic map and for the global one (none without rough glass); the photons both keep
    /// and the merging radius. 0 without merging.
    pub photon_paths: u64,
    pub global_photon_paths: u64,
    pub photons: u64,
    pub merge_radius: f32,
    pub warnings: Vec<String>,
    /// Wall time of the render, BVH build included.
    pub elapsed: Duration,
}

impl TraceOutput {
    /// `image` from `samples` camera samples and nothing else: no pilot, light paths, photons
    /// or discarded samples. A scene without light (its `image` black), and the GPU tracer's
    /// plain estimator (which sets what it discarded).
    pub fn plain(image: PlanarImage, samples: u64, warnings: Vec<String>, elapsed: Duration) -> Self {
        TraceOutput {
            image,
            discarded_samples: 0,
            samples,
            pilot_samples: 0,
            camera_rays: 0,
            light_paths: 0,
            light_pilot_paths: 0,
            photon_paths: 0,
            global_photon_paths: 0,
            photons: 0,
            merge_radius: 0.0,
            warnings,
            elapsed,
        }
    }

    pub fn samples_per_second(&self) -> f64 {
        self.samples as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }

    /// What the light tracer and photon merging did, a line each, for the estimators that
    /// ran them.
    pub fn light_transport_summary(&self) -> Vec<String> {
        let mut lines = Vec::new();
        if self.light_paths > 0 {
            lines.push(format!(
                "light tracing: {} light paths ({:.3} per camera sample, balanced against the camera's noise; a pilot of {} set aside)",
                self.light_paths,
                self.light_paths as f64 / (self.samples - self.pilot_samples).max(1) as f64,
                self.light_pilot_paths
            ));
        }
        if self.photon_paths > 0 {
            let global = match self.global_photon_paths {
                0 => "no global ones (the background lights the scene too)".to_string(),
                paths => format!("{paths} global"),
            };
            lines.push(format!(
                "photon merging: {} photons of {} caustic light paths and {global}, radius {:.3e} (biased: a blur of about a pixel)",
                self.photons, self.photon_paths, self.merge_radius
            ));
        }
        lines
    }
}

/// The image seed of a dataset sample: `glassbake dataset` and `glassbake trace --sample`
/// both use it, so the two render the same ground truth.
pub fn sample_trace_seed(sample_seed: u64) -> u64 {
    glassbake_core::seed::purpose_seed(sample_seed, "trace")
}

/// The warning (also logged) for a scene that nothing lights, where tracing can be skipped:
/// the image is black. `no_emitters` is whether the light sampler found nothing to sample.
pub fn unlit_warning(scene: &Scene, no_emitters: bool) -> Option<String> {
    if !no_emitters || scene.background != Vec3::ZERO {
        return None;
    }
    let has_emissive = scene.rect_lights.iter().any(|l| l.radiance.max_element() > 0.0) || !scene.emissive_objects().is_empty();
    if has_emissive {
        return None;
    }
    let warning = format!("scene {}: no light (no rectangle light, no emissive mesh, black background): the image is black", scene.name);
    tracing::warn!("{warning}");
    Some(warning)
}

/// Progress callback: (work done, work in all), counting camera samples, light paths and
/// photon paths; the total grows once the light tracer's budget is set. Called from worker
/// threads.
pub type Progress<'a> = &'a (dyn Fn(u64, u64) + Sync);

/// Path trace `scene` as seen by `camera`.
pub fn render(scene: &Scene, camera: &Camera, settings: &TraceSettings, progress: Option<Progress>) -> Result<TraceOutput> {
    settings.validate()?;
    camera.check()?;
    match settings.threads {
        Some(threads) => {
            let pool =
                rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| Error::Internal(format!("cannot start {threads} threads: {e}")))?;
            pool.install(|| render_in_pool(scene, camera, settings, progress))
        }
        None => render_in_pool(scene, camera, settings, progress),
    }
}

/// A square of pixels that one rayon task computes. Tiles only decide who computes a pixel,
/// never what it computes.
struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Tile {
    /// The image's tiles, row-major.
    fn cover(width: u32, height: u32) -> Vec<Tile> {
        let mut tiles = Vec::new();
        for y0 in (0..height).step_by(TILE as usize) {
            for x0 in (0..width).step_by(TILE as usize) {
                tiles.push(Tile { x0, y0, x1: (x0 + TILE).min(width), y1: (y0 + TILE).min(height) });
            }
        }
        tiles
    }

    fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (self.y0..self.y1).flat_map(move |y| (self.x0..self.x1).map(move |x| (x, y)))
    }
}

fn render_in_pool(scene: &Scene, camera: &Camera, settings: &TraceSettings, progress: Option<Progress>) -> Result<TraceOutput> {
    let start = Instant::now();
    let (width, height) = (settings.width, settings.height);
    let channels: Vec<String> = GROUND_TRUTH_CHANNELS.iter().map(|c| c.to_string()).collect();
    let mut image = PlanarImage::new(width, height, channels);
    let estimator = settings.estimator;
    let prepared = PreparedScene::for_transport(scene, estimator.transport);
    let budgets = pixel_budgets(&prepared, camera, settings);
    let budget: u64 = budgets.iter().map(|&s| s as u64).sum();
    if let Some(warning) = unlit_warning(scene, prepared.lights.is_empty()) {
        if let Some(p) = progress {
            p(budget, budget);
        }
        return Ok(TraceOutput::plain(image, budget, vec![warning], start.elapsed()));
    }

    let path_settings =
        PathSettings { max_depth: settings.max_depth, rr_depth: settings.rr_depth, material_model: settings.material_model, path_filter: settings.path_filter };
    // One tracer of light paths serves the light tracer's splats and photon merging's photons.
    let tracer = estimator.is_caustic().then(|| LightTracer::new(&prepared, camera, width, height, path_settings));
    // Light paths are all straight-view paths.
    let light_tracer = tracer.as_ref().filter(|t| settings.path_filter != PathFilter::BentView && t.has_work());
    // A first estimate, for the progress bar: the budget is balanced after the camera pass.
    let light_paths_estimate = if light_tracer.is_some() { ((budget as f64 * LIGHT_PATHS_PER_CAMERA_PATH).ceil() as u64).max(1) } else { 0 };
    // Photons first: every camera pass, the adaptive pilot's too, reads them.
    let photon_tracer = tracer.as_ref().filter(|t| estimator.photon_merging() && t.has_work());
    let photon_paths = if photon_tracer.is_some() { ((budget as f64 * PHOTON_PATHS_PER_CAMERA_SAMPLE).ceil() as u64).clamp(1, MAX_PHOTON_PATHS) } else { 0 };
    // Global photons carry the light of the emitters alone: where a background lights the
    // scene too, a gather would miss what of its light scattered before, so none is made.
    let global_photon_paths = if scene.background == Vec3::ZERO { photon_paths } else { 0 };
    let all_photon_paths = photon_paths + global_photon_paths;
    let work = budget + light_paths_estimate + all_photon_paths;
    let photons = photon_tracer.map(|t| trace_merge_photons(t, settings.seed, (photon_paths, global_photon_paths), &|done| report(progress, done, work)));

    let passes = CameraPasses {
        prepared: &prepared,
        camera,
        settings,
        path_settings,
        tiles: Tile::cover(width, height),
        hooks: estimator.is_caustic().then(|| CausticPaths { merging: photons.as_ref().map(|m| MergingPath::new(&m.caustic, m.global.as_ref())) }),
        progress,
        done_before: all_photon_paths,
        done: AtomicU64::new(0),
        work,
    };
    let camera_samples = passes.trace(budgets);
    let samples = camera_samples.pilot_samples + camera_samples.main_spp.iter().map(|&s| s as u64).sum::<u64>();
    let camera_rays = camera_samples.pilot_rays + camera_samples.sums.iter().map(|pixel| pixel.rays).sum::<u64>();

    let light = match light_tracer {
        Some(tracer) => trace_light(tracer, &camera_samples, settings.seed, all_photon_paths + samples, progress),
        None => LightTraced::default(),
    };
    let mut discarded_samples = light.discarded;
    for (index, pixel) in camera_samples.sums.iter().enumerate() {
        discarded_samples += pixel.discarded;
        let mut value = pixel.mean();
        if let Some(sum) = light.sums.get(index) {
            value += Vec3::new(sum[0] as f32, sum[1] as f32, sum[2] as f32) / light.paths as f32;
        }
        let (x, y) = (index as u32 % width, index as u32 / width);
        for (channel, component) in value.to_array().into_iter().enumerate() {
            image.set(channel, x, y, component);
        }
    }
    let mut warnings = Vec::new();
    if discarded_samples > 0 {
        let warning = format!("{discarded_samples} of {samples} samples were NaN or infinite and were discarded");
        tracing::warn!("{warning}");
        warnings.push(warning);
    }
    let (photon_paths, merge_radius) = photons.as_ref().map_or((0, 0.0), |m| (m.paths, m.caustic.radius()));
    Ok(TraceOutput {
        image,
        discarded_samples,
        samples,
        pilot_samples: camera_samples.pilot_samples,
        camera_rays,
        light_paths: light.paths,
        light_pilot_paths: light.pilot_paths,
        photon_paths,
        global_photon_paths,
        photons: photons.as_ref().map_or(0, |m| (m.caustic.len() + m.global.as_ref().map_or(0, PhotonMap::len)) as u64),
        merge_radius,
        warnings,
        elapsed: start.elapsed(),
    })
}

fn report(progress: Option<Progress>, done: u64, work: u64) {
    if let Some(p) = progress {
        p(done, work);
    }
}

/// Samples of each pixel, row-major: `spp`, or `glass_spp` where glass shows.
fn pixel_budgets(prepared: &PreparedScene, camera: &Camera, settings: &TraceSettings) -> Vec<u32> {
    let (width, height) = (settings.width, settings.height);
    match settings.glass_spp {
        Some(glass_spp) if glass_spp > settings.spp => {
            glass_pixels(prepared, camera, width, height).into_iter().map(|glass| if glass { glass_spp } else { settings.spp }).collect()
        }
        _ => vec![settings.spp; width as usize * height as usize],
    }
}

/// Photon merging's maps: the caustic one of `paths.0` light paths and, where `paths.1` is
/// not 0, the global one. `progress(done)` counts the light paths traced.
fn trace_merge_photons(
    tracer: &LightTracer,
    image_seed: u64,
    (photon_paths, global_photon_paths): (u64, u64),
    progress: &(dyn Fn(u64) + Sync),
) -> MergePhotons {
    let radius = merge_radius(tracer.pixel_footprint_at_glass().unwrap_or(0.0), photon_paths);
    let photon_map = |walk: LightWalk, paths: u64, purpose: &str, done: u64| {
        let seed = glassbake_core::seed::purpose_seed(image_seed, purpose);
        let photons = trace_photons(tracer, walk, paths, seed, &|traced| progress(done + traced));
        tracing::debug!("{purpose}: {} photons of {paths} light paths, radius {radius}", photons.len());
        PhotonMap::new(photons, paths, radius)
    };
    let caustic = photon_map(LightWalk::Caustic, photon_paths, "caustic photons", 0);
    let global = (global_photon_paths > 0).then(|| photon_map(LightWalk::Global, global_photon_paths, "global photons", photon_paths));
    MergePhotons { paths: photon_paths, caustic, global }
}

/// The camera's passes over the image: the adaptive pilot, when sampling adaptively, then
/// the main pass.
struct CameraPasses<'a> {
    prepared: &'a PreparedScene<'a>,
    camera: &'a Camera,
    settings: &'a TraceSettings,
    path_settings: PathSettings,
    tiles: Vec<Tile>,
    /// The caustic estimator's hooks; `None` traces plain paths.
    hooks: Option<CausticPaths<'a>>,
    progress: Option<Progress<'a>>,
    /// Work reported done before the passes, samples traced by them since, and all the work.
    done_before: u64,
    done: AtomicU64,
    work: u64,
}

/// What the camera's passes traced.
struct CameraSamples {
    /// The main pass's sums per pixel, row-major.
    sums: Vec<PixelSums>,
    /// Samples of each pixel in the main pass (the budgets, or adaptive sampling's allocation).
    main_spp: Vec<u32>,
    /// Samples and rays of the adaptive pilot, set aside.
    pilot_samples: u64,
    pilot_rays: u64,
}

impl CameraPasses<'_> {
    fn trace(&self, budgets: Vec<u32>) -> CameraSamples {
        let width = self.settings.width;
        let (mut pilot_samples, mut pilot_rays, mut main_spp) = (0, 0, budgets);
        // Adaptive sampling: a pilot of its own streams, set aside once it has told where the
        // noise is; the main pass then draws each pixel's count from the pixel's usual stream.
        if self.settings.estimator.adaptive && main_spp.iter().any(|&budget| adaptive::pilot_spp(budget) > 0) {
            let pilot_seed = glassbake_core::seed::purpose_seed(self.settings.seed, "adaptive pilot");
            let pilot = self.pass(&|x, y| adaptive::pilot_spp(main_spp[(y * width + x) as usize]), pilot_seed);
            pilot_samples = pilot.iter().map(|sums| sums.finite + sums.discarded).sum();
            pilot_rays = pilot.iter().map(|sums| sums.rays).sum();
            main_spp = self.allocate_by_noise(&pilot, &main_spp);
        }
        let sums = self.pass(&|x, y| main_spp[(y * width + x) as usize], self.settings.seed);
        CameraSamples { sums, main_spp, pilot_samples, pilot_rays }
    }

    /// The budgets spread by the noise the pilot measured (`adaptive.rs`).
    fn allocate_by_noise(&self, pilot: &[PixelSums], budgets: &[u32]) -> Vec<u32> {
        let (width, height) = (self.settings.width, self.settings.height);
        // The whole image's light whatever the filter, so that a filtered image's samples are
        // spread as the full image's are.
        let stats: Vec<_> =
            pilot.iter().map(|sums| adaptive::PilotStats { sum: sums.all_sum, sum_squares: sums.all_sum_squares, count: sums.finite }).collect();
        let weights = adaptive::noise_weights(&stats, budgets, width, height);
        let weights = adaptive::pool_by_object(&weights, &transparent_object_per_pixel(self.prepared, self.camera, width, height));
        adaptive::allocate(budgets, &weights)
    }

    /// One pass: `spp_of(x, y)` samples of each pixel from the streams of `seed`; the sums
    /// per pixel, row-major.
    fn pass(&self, spp_of: &(dyn Fn(u32, u32) -> u32 + Sync), seed: u64) -> Vec<PixelSums> {
        let tiles = match self.hooks {
            Some(hooks) => self.pass_with(spp_of, seed, hooks),
            None => self.pass_with(spp_of, seed, PlainPaths),
        };
        let width = self.settings.width as usize;
        let mut sums = vec![PixelSums::default(); width * self.settings.height as usize];
        for (tile, pixels) in self.tiles.iter().zip(tiles) {
            for ((x, y), pixel) in tile.pixels().zip(pixels) {
                sums[y as usize * width + x as usize] = pixel;
            }
        }
        sums
    }

    fn pass_with<H: PathHooks + Sync>(&self, spp_of: &(dyn Fn(u32, u32) -> u32 + Sync), seed: u64, hooks: H) -> Vec<Vec<PixelSums>> {
        let (width, height) = (self.settings.width, self.settings.height);
        let pass = PixelPass { rays: self.camera.primary_rays(width, height), width, seed, stratified: self.settings.estimator.stratified };
        self.tiles
            .par_iter()
            .map(|tile| {
                let mut scratch = PathScratch::default();
                let mut tile_samples = 0u64;
                let pixels = tile
                    .pixels()
                    .map(|(x, y)| {
                        let spp = spp_of(x, y);
                        tile_samples += spp as u64;
                        render_pixel(self.prepared, &pass, &self.path_settings, (x, y, spp), hooks, &mut scratch)
                    })
                    .collect();
                let finished = self.done_before + self.done.fetch_add(tile_samples, Ordering::Relaxed) + tile_samples;
                report(self.progress, finished, self.work);
                pixels
            })
            .collect()
    }
}

/// Sub-pixel positions per side at which [`glass_pixels`] looks.
const GLASS_PROBES: u32 = 3;

/// Which pixels show a transparent object (`Object::transparent`, the objects that get a
/// transparency buffer) in front of everything else: a camera ray through any of a 3x3 grid
/// of points in the pixel meets one first. Row-major, `width` x `height`. The rasterizer's
/// coverage of the transparency buffers marks the same pixels (up to the sub-pixel grid),
/// and it is what the evaluation's transparent-pixel metrics read.
pub fn glass_pixels(prepared: &PreparedScene, camera: &Camera, width: u32, height: u32) -> Vec<bool> {
    let rays = camera.primary_rays(width, height);
    (0..width * height)
        .into_par_iter()
        .map(|index| {
            let (x, y) = (index % width, index / width);
            (0..GLASS_PROBES * GLASS_PROBES).any(|probe| {
                let offset = |i: u32| (i as f32 + 0.5) / GLASS_PROBES as f32;
                let ray = rays.ray(x as f32 + offset(probe % GLASS_PROBES), y as f32 + offset(probe / GLASS_PROBES));
                first_transparent_object(prepared, &ray).is_some()
            })
        })
        .collect()
}

/// The transparent object (one that gets a transparency buffer) that a ray through each
/// pixel's centre meets first, if any; row-major.
pub fn transparent_object_per_pixel(prepared: &PreparedScene, camera: &Camera, width: u32, height: u32) -> Vec<Option<u32>> {
    let rays = camera.primary_rays(width, height);
    (0..width * height)
        .into_par_iter()
        .map(|index| {
            let ray = rays.ray((index % width) as f32 + 0.5, (index / width) as f32 + 0.5);
            first_transparent_object(prepared, &ray)
        })
        .collect()
}

/// The object `ray` meets first, if it is a transparent one (one that gets a transparency
/// buffer, `Object::transparent`).
fn first_transparent_object(prepared: &PreparedScene, ray: &glassbake_core::Ray) -> Option<u32> {
    match prepared.intersect(ray)?.owner {
        Owner::Object { object, .. } if prepared.scene.objects[object as usize].transparent => Some(object),
        _ => None,
    }
}

/// Photon merging's photons: of `paths` caustic light paths, and of as many light paths of
/// all light where the background is black.
struct MergePhotons {
    paths: u64,
    caustic: PhotonMap,
    global: Option<PhotonMap>,
}

/// A pixel's finite samples summed in f64 (and their squares, which adaptive sampling's pilot
/// reads), and how many samples were not finite.
#[derive(Clone, Default)]
struct PixelSums {
    sum: [f64; 3],
    sum_squares: [f64; 3],
    finite: u64,
    discarded: u64,
    /// Rays cast for these samples.
    rays: u64,
    /// The same sums over all the paths' light, whatever `TraceSettings::path_filter` counts:
    /// the light tracer's budget follows the whole image's noise.
    all_sum: [f64; 3],
    all_sum_squares: [f64; 3],
}

impl PixelSums {
    fn mean(&self) -> Vec3 {
        if self.finite == 0 {
            return Vec3::ZERO;
        }
        let n = self.finite as f64;
        Vec3::new((self.sum[0] / n) as f32, (self.sum[1] / n) as f32, (self.sum[2] / n) as f32)
    }
}

/// What every pixel of a pass shares: the camera's rays, the image width (pixels are numbered
/// row by row), the pass's seed, and whether sample values are stratified.
struct PixelPass {
    rays: PrimaryRays,
    width: u32,
    seed: u64,
    stratified: bool,
}

/// One pixel `(x, y)`, `spp` samples: its own random stream, its samples in a fixed order, a
/// box filter over the pixel.
fn render_pixel<H: PathHooks>(
    prepared: &PreparedScene,
    pass: &PixelPass,
    path_settings: &PathSettings,
    (x, y, spp): (u32, u32, u32),
    hooks: H,
    scratch: &mut PathScratch,
) -> PixelSums {
    let PixelPass { rays, width, seed, stratified } = *pass;
    let pixel_index = y as u64 * width as u64 + x as u64;
    let mut rng = Pcg32::for_pixel(seed, pixel_index);
    let mut sums = PixelSums::default();
    let rays_before = rays_cast();
    let stratified = stratified.then(|| StratifiedPixel::new(seed, pixel_index));
    for index in 0..spp {
        let stratified_sample = stratified.as_ref().map(|pixel| pixel.sample(index));
        let jitter = match &stratified_sample {
            Some(sample) => sample.get_2d(qmc::PIXEL_DIMENSION),
            None => rng.next_vec2(),
        };
        let ray = rays.ray(x as f32 + jitter.x, y as f32 + jitter.y);
        let path = prepared.trace_path(&ray, &mut rng, stratified_sample.as_ref(), path_settings, hooks, scratch);
        if path.all.is_finite() {
            for (c, (counted, all)) in path.counted.to_array().into_iter().zip(path.all.to_array()).enumerate() {
                sums.sum[c] += counted as f64;
                sums.sum_squares[c] += (counted as f64) * (counted as f64);
                sums.all_sum[c] += all as f64;
                sums.all_sum_squares[c] += (all as f64) * (all as f64);
            }
            sums.finite += 1;
        } else {
            sums.discarded += 1;
        }
    }
    sums.rays = rays_cast() - rays_before;
    sums
}
