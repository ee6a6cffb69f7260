//! The light paths of an image: the caustic estimator's light tracer (its pilot, its budget
//! against the camera samples, its splats in chunk order) and photon merging's photons, each
//! traced in chunks of their own random streams so that the sums do not depend on threads.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::{report, CameraSamples, PixelSums, Progress};
use crate::light_tracing::{balanced_light_paths, pilot_light_paths, LightPilot, LightTracer, LightWalk, Splat, PATHS_PER_CHUNK};
use crate::photon_merging::Photon;
use crate::prepared::rays_cast;
use crate::rng::Pcg32;

/// The light tracer's part of an image: per-pixel sums of `paths` light paths (empty when none
/// ran), the paths of its pilot, and the splats left out as not finite.
#[derive(Default)]
pub(super) struct LightTraced {
    pub(super) sums: Vec<[f64; 3]>,
    pub(super) paths: u64,
    pub(super) pilot_paths: u64,
    pub(super) discarded: u64,
}

/// Light tracing after the camera's passes (`done` of the work already reported). How many
/// light paths the image should have: a pilot of light paths, set aside (so that no light
/// path's value decides how many there are), measures their variance and cost against the
/// camera samples'. The budget depends on the camera samples, which are independent of the
/// light paths: each half stays unbiased.
pub(super) fn trace_light(tracer: &LightTracer, camera: &CameraSamples, image_seed: u64, done: u64, progress: Option<Progress>) -> LightTraced {
    let camera_samples = camera.main_spp.iter().map(|&s| s as u64).sum::<u64>();
    let pilot_paths = pilot_light_paths(camera_samples);
    let pilot = trace_light_pilot(tracer, pilot_paths, glassbake_core::seed::purpose_seed(image_seed, "light tracing pilot"));
    let paths = light_tracing_budget(&camera.sums, &pilot, camera_samples);
    let done = done + pilot_paths;
    let work = done + paths;
    report(progress, done, work);
    let seed = glassbake_core::seed::purpose_seed(image_seed, "light tracing");
    let (sums, discarded) = trace_light_paths(tracer, paths, seed, &|traced| report(progress, done + traced, work));
    LightTraced { sums, paths, pilot_paths, discarded }
}

/// Trace `paths` light paths of the stream `seed` and sum, per pixel, each path's
/// contribution and its square, and the rays they cast. Chunked and summed in chunk order as
/// [`trace_light_paths`] is, so the result does not depend on the thread count.
pub(super) fn trace_light_pilot(tracer: &LightTracer, paths: u64, seed: u64) -> LightPilot {
    let pixels = tracer.pixel_count();
    let mut pilot = LightPilot { paths, sum: vec![[0.0; 3]; pixels], sum_squares: vec![[0.0; 3]; pixels], rays: 0 };
    let chunks = light_chunks(0..paths.div_ceil(PATHS_PER_CHUNK), paths, seed, |rng, count| {
        let (mut path_splats, mut merged, mut hits): (Vec<Splat>, Vec<Splat>, _) = (Vec::new(), Vec::new(), Vec::new());
        let rays_before = rays_cast();
        for _ in 0..count {
            path_splats.clear();
            tracer.trace(rng, &mut path_splats, &mut hits);
            // One value per pixel and path: a path that reaches a pixel twice counts once.
            path_splats.sort_by_key(|s| s.pixel);
            let path_start = merged.len();
            for splat in &path_splats {
                let same_pixel = merged.len() > path_start && merged.last().is_some_and(|last| last.pixel == splat.pixel);
                match merged.last_mut() {
                    Some(last) if same_pixel => last.value += splat.value,
                    _ => merged.push(*splat),
                }
            }
        }
        (merged, rays_cast() - rays_before)
    });
    for (splats, rays) in chunks {
        pilot.rays += rays;
        for splat in splats {
            let (sum, squares) = (&mut pilot.sum[splat.pixel as usize], &mut pilot.sum_squares[splat.pixel as usize]);
            for (c, v) in splat.value.to_array().into_iter().enumerate() {
                sum[c] += v as f64;
                squares[c] += v as f64 * v as f64;
            }
        }
    }
    pilot
}

/// The balanced number of light paths for an image whose camera samples summed to `sums`
/// (`light_tracing::balanced_light_paths`). Variances are summed over the pixels' channels
/// that stay at or below 1: above, every metric clamps the value and its noise is invisible.
pub(super) fn light_tracing_budget(sums: &[PixelSums], pilot: &LightPilot, camera_samples: u64) -> u64 {
    let m = pilot.paths.max(1) as f64;
    let (mut camera_variance, mut light_variance, mut camera_rays) = (0.0f64, 0.0f64, 0u64);
    for (sums, (light_sum, light_squares)) in sums.iter().zip(pilot.sum.iter().zip(&pilot.sum_squares)) {
        camera_rays += sums.rays;
        let n = sums.finite as f64;
        for c in 0..3 {
            let camera_mean = if n > 0.0 { sums.all_sum[c] / n } else { 0.0 };
            let light_mean = light_sum[c] / m;
            if camera_mean + light_mean > 1.0 {
                continue;
            }
            if n >= 2.0 {
                camera_variance += ((sums.all_sum_squares[c] - sums.all_sum[c] * camera_mean) / (n - 1.0)).max(0.0) / n;
            }
            light_variance += (light_squares[c] / m - light_mean * light_mean).max(0.0);
        }
    }
    balanced_light_paths(camera_variance, light_variance, camera_rays as f64, pilot.rays as f64 / m, camera_samples)
}

/// The photons of `paths` light paths of the stream `seed` traced as `walk` says, in the
/// order traced: chunk `k` of [`PATHS_PER_CHUNK`] paths draws from its own stream and chunks
/// are concatenated in order, so the photons do not depend on the thread count.
pub(super) fn trace_photons(tracer: &LightTracer, walk: LightWalk, paths: u64, seed: u64, progress: &(dyn Fn(u64) + Sync)) -> Vec<Photon> {
    let done = AtomicU64::new(0);
    let chunks = light_chunks(0..paths.div_ceil(PATHS_PER_CHUNK), paths, seed, |rng, count| {
        let (mut photons, mut hits) = (Vec::new(), Vec::new());
        for _ in 0..count {
            tracer.trace_photons(rng, walk, &mut photons, &mut hits);
        }
        progress(done.fetch_add(count, Ordering::Relaxed) + count);
        photons
    });
    chunks.concat()
}

/// `trace_chunk(stream, paths)` for each chunk of `chunks` (of [`PATHS_PER_CHUNK`] light
/// paths, the last of `paths` short), in parallel, results in chunk order: chunk `k` draws
/// from its own stream `(seed, k)`, so the results do not depend on the thread count.
pub(super) fn light_chunks<T: Send>(chunks: std::ops::Range<u64>, paths: u64, seed: u64, trace_chunk: impl Fn(&mut Pcg32, u64) -> T + Sync) -> Vec<T> {
    chunks
        .into_par_iter()
        .map(|chunk| {
            let mut rng = Pcg32::for_pixel(seed, chunk);
            trace_chunk(&mut rng, PATHS_PER_CHUNK.min(paths - chunk * PATHS_PER_CHUNK))
        })
        .collect()
}

/// Chunks of light paths traced between two gatherings of their splats: bounds the splats
/// held in memory.
pub(super) const CHUNKS_PER_BATCH: u64 = 64;

/// Trace `paths` light paths and sum their splats per pixel (f64, row-major), plus the count
/// of splats left out as not finite. Chunk `k` of [`PATHS_PER_CHUNK`] paths draws from its
/// own stream and chunks are summed in order, so the sums do not depend on the thread count.
pub(super) fn trace_light_paths(tracer: &LightTracer, paths: u64, seed: u64, progress: &(dyn Fn(u64) + Sync)) -> (Vec<[f64; 3]>, u64) {
    let mut sums = vec![[0.0f64; 3]; tracer.pixel_count()];
    let mut discarded = 0;
    let chunks = paths.div_ceil(PATHS_PER_CHUNK);
    let done = AtomicU64::new(0);
    for batch_start in (0..chunks).step_by(CHUNKS_PER_BATCH as usize) {
        let batch = light_chunks(batch_start..(batch_start + CHUNKS_PER_BATCH).min(chunks), paths, seed, |rng, count| {
            let (mut splats, mut hits) = (Vec::new(), Vec::new());
            let mut discarded = 0;
            for _ in 0..count {
                discarded += tracer.trace(rng, &mut splats, &mut hits);
            }
            progress(done.fetch_add(count, Ordering::Relaxed) + count);
            (splats, discarded)
        });
        for (splats, chunk_discarded) in batch {
            discarded += chunk_discarded;
            for splat in splats {
                let sum = &mut sums[splat.pixel as usize];
                for (s, v) in sum.iter_mut().zip(splat.value.to_array()) {
                    *s += v as f64;
                }
            }
        }
    }
    (sums, discarded)
}
