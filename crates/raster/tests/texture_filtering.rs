//! The opaque G-buffer's albedo is what the pixel's footprint averages (the path tracer's
//! box-filtered pixel sees the texture that way), not a blur of it: against the same frame
//! rasterized at 8x the resolution and averaged over each 8x8 block, on DESK, whose page of
//! text the camera sees at grazing angles.

mod common;

use glassbake_core::layout::opaque;

const SCALE: u32 = 8;
const SIDE: u32 = 96;

struct Errors {
    /// RMS albedo error over interior pixels whose footprint shows texture detail.
    detailed: f64,
    /// The same pixels' albedo spread within the footprint (RMS about the block's mean).
    detail: f64,
    pixels: usize,
}

fn albedo_errors(samples: &[u64]) -> Errors {
    let base = glassbake_scene::builtin::builtin("desk").unwrap();
    let mut r = common::rasterizer();
    let (mut squared, mut spread, mut pixels) = (0.0f64, 0.0f64, 0usize);
    for &index in samples {
        let sample = base.sample(7, index);
        let scene = base.instantiate(&sample.values).unwrap();
        let low = r.begin_frame(&scene, &sample.camera, SIDE, SIDE).unwrap().opaque().unwrap();
        let high = r.begin_frame(&scene, &sample.camera, SIDE * SCALE, SIDE * SCALE).unwrap().opaque().unwrap();
        for y in 0..SIDE {
            for x in 0..SIDE {
                let block = |channel: usize| -> Vec<f32> {
                    let mut v = Vec::with_capacity((SCALE * SCALE) as usize);
                    for j in 0..SCALE {
                        for i in 0..SCALE {
                            v.push(high.get(channel, x * SCALE + i, y * SCALE + j));
                        }
                    }
                    v
                };
                // Interior pixels only: one surface over the whole footprint (its depths
                // within 2% of each other), so that a silhouette's choice of side is not counted.
                let depths = block(opaque::DEPTH);
                let (lo, hi) = depths.iter().fold((f32::MAX, f32::MIN), |(a, b), &d| (a.min(d), b.max(d)));
                if !(lo > 0.0 && hi < lo * 1.02) {
                    continue;
                }
                let (mut error, mut within) = (0.0f64, 0.0f64);
                for c in 0..3 {
                    let values = block(opaque::ALBEDO + c);
                    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64;
                    within += values.iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>() / values.len() as f64;
                    error += (low.get(opaque::ALBEDO + c, x, y) as f64 - mean).powi(2);
                }
                if within.sqrt() > 0.05 {
                    squared += error;
                    spread += within;
                    pixels += 1;
                }
            }
        }
    }
    Errors { detailed: (squared / (3 * pixels.max(1)) as f64).sqrt(), detail: (spread / (3 * pixels.max(1)) as f64).sqrt(), pixels }
}

#[test]
fn the_albedo_is_the_footprints_mean_on_desk() {
    let e = albedo_errors(&[0, 1, 2, 3, 4, 5]);
    println!("desk: {} detailed pixels, albedo RMS error {:.4} against a footprint spread of {:.4}", e.pixels, e.detailed, e.detail);
    assert!(e.pixels > 500, "too few textured pixels to judge: {}", e.pixels);
    // Measured on lavapipe: 0.23 of the spread with the 4x4 footprint lookups; 0.34 with one
    // anisotropic lookup a pixel, the filter before them; reading a mip level and a half too
    // coarse, 0.62.
    assert!(e.detailed < 0.28 * e.detail, "RMS error {:.4}, spread {:.4}", e.detailed, e.detail);
}
