//! The through buffer's albedo is what the pixel's footprint sees through the glass, averaged:
//! against 8x8 rays a pixel through the centres of its sub-pixels, each reading the
//! full-size texture at one point, averaged (weighted by what each path lets through), on
//! DESK, whose lenses spread a pixel over the printed page and the wood behind them.

use glassbake_core::camera::Camera;
use glassbake_core::image::PlanarImage;
use glassbake_core::layout::{self, through, transparent};
use glassbake_rays::through::{through_buffer, trace_through, ThroughHit, ThroughScene};
use glassbake_scene::Scene;
use rayon::prelude::*;

const SCALE: u32 = 8;
const SIDE: u32 = 96;

fn cast(scene: &Scene, geometry: &ThroughScene, k: usize, camera: &Camera, side: u32) -> PlanarImage {
    let mut coverage = PlanarImage::new(side, side, layout::transparent_channel_names(k));
    coverage.plane_mut(transparent::COVERAGE).fill(1.0);
    let gbuffer = PlanarImage::new(side, side, layout::opaque_channel_names());
    through_buffer(scene, geometry, k, camera, &gbuffer, coverage.plane(transparent::COVERAGE))
}

struct Errors {
    /// RMS albedo error over pixels the object covers whole whose footprint shows detail.
    detailed: f64,
    /// The same pixels' albedo spread within the footprint (RMS about the block's mean).
    detail: f64,
    pixels: usize,
}

fn albedo_errors(samples: &[u64]) -> Errors {
    let base = glassbake_scene::builtin::builtin("desk").unwrap();
    let (mut squared, mut spread, mut pixels) = (0.0f64, 0.0f64, 0usize);
    for &index in samples {
        let sample = base.sample(7, index);
        let scene = base.instantiate(&sample.values).unwrap();
        let geometry = ThroughScene::build(&scene);
        for k in 0..geometry.object_count() {
            let low = cast(&scene, &geometry, k, &sample.camera, SIDE);
            let side = SIDE * SCALE;
            let rays = sample.camera.primary_rays(side, side);
            let high: Vec<Option<ThroughHit>> = (0..side * side)
                .into_par_iter()
                .map(|i| {
                    let ray = rays.ray((i % side) as f32 + 0.5, (i / side) as f32 + 0.5);
                    trace_through(&scene, &geometry, k, ray.origin, ray.direction)
                })
                .collect();
            let high_at = |u: u32, v: u32| high[(v * side + u) as usize].as_ref();
            for y in 0..SIDE {
                for x in 0..SIDE {
                    let at = |i: u32, j: u32| (x * SCALE + i, y * SCALE + j);
                    let block: Vec<(u32, u32)> = (0..SCALE).flat_map(|j| (0..SCALE).map(move |i| (i, j))).map(|(i, j)| at(i, j)).collect();
                    // Pixels the glass covers whole: every path of the block crossed it.
                    let crossed = |h: Option<&ThroughHit>| h.is_some_and(|h| h.transmittance > 0.0 && h.length > 0.0);
                    let through_glass = low.get(through::TRANSMITTANCE, x, y) > 0.0 && low.get(through::LENGTH, x, y) > 0.0;
                    if !through_glass || block.iter().any(|&(u, v)| !crossed(high_at(u, v))) {
                        continue;
                    }
                    let hits: Vec<&ThroughHit> = block.iter().map(|&(u, v)| high_at(u, v).unwrap()).collect();
                    let weight: f64 = hits.iter().map(|h| h.transmittance as f64).sum();
                    let (mut error, mut within) = (0.0f64, 0.0f64);
                    for c in 0..3 {
                        let mean = hits.iter().map(|h| (h.albedo[c] * h.transmittance) as f64).sum::<f64>() / weight;
                        within += hits.iter().map(|h| (h.albedo[c] as f64 - mean).powi(2)).sum::<f64>() / hits.len() as f64;
                        error += (low.get(through::ALBEDO + c, x, y) as f64 - mean).powi(2);
                    }
                    if within.sqrt() > 0.05 {
                        squared += error;
                        spread += within;
                        pixels += 1;
                    }
                }
            }
        }
    }
    Errors { detailed: (squared / (3 * pixels.max(1)) as f64).sqrt(), detail: (spread / (3 * pixels.max(1)) as f64).sqrt(), pixels }
}

#[test]
fn the_through_albedo_is_the_footprints_mean_on_desk() {
    let e = albedo_errors(&[0, 1, 2, 3, 4, 5]);
    println!("desk through: {} detailed pixels, albedo RMS error {:.4} against a footprint spread of {:.4}", e.pixels, e.detailed, e.detail);
    assert!(e.pixels > 200, "too few textured pixels to judge: {}", e.pixels);
    // Four point samples of the full-size texture a pixel measured 0.39 of the spread; one
    // lookup at the level of each one's share of the footprint, 0.21; four lookups over each
    // one's quarter with half their cell's gradients, 0.18 (with a whole cell's, 0.19).
    assert!(e.detailed < 0.2 * e.detail, "RMS error {:.4}, spread {:.4}", e.detailed, e.detail);
}
