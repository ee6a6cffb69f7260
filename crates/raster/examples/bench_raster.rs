//! Time per frame of the rasterizer: opaque G-buffer (with L_d and shadow maps) plus t = 0, 1, 2,
//! 4, 8 transparency buffers, at 256^2 and 512^2, on the adapter `Rasterizer::new` picks
//! (`WGPU_ADAPTER_NAME` to choose). The scene is CORNELLBOX8 keeping its first t transparent
//! objects, seen from the middle of its camera range.
//!
//! `cargo run --release -p glassbake-raster --example bench_raster [-- FRAMES]`
//!
//! Two numbers per row: "GPU" renders every buffer and waits for the GPU (the real-time path,
//! where the network reads the targets in place); "readback" also copies every buffer to the
//! host as planar f32 (the dataset path). The last column is "GPU" with shadows off.

use std::time::Instant;

use glassbake_raster::{Rasterizer, RasterizerOptions};
use glassbake_scene::builtin::builtin;

fn main() -> glassbake_core::Result<()> {
    let frames: usize = std::env::args().nth(1).map_or(10, |s| s.parse().expect("FRAMES is a number"));
    let mut r = Rasterizer::new(RasterizerOptions::default())?;
    let mut unshadowed = Rasterizer::new(RasterizerOptions { shadows: false, ..Default::default() })?;
    let info = r.adapter_info().clone();
    println!("adapter: {} ({:?}, driver {} {})", info.name, info.device_type, info.driver, info.driver_info);
    let base = builtin("cornellbox8").expect("built-in");
    let base = base.instantiate(&base.default_values())?;
    let camera = base.camera.middle();
    println!("| resolution | t | GPU ms/frame (median) | readback ms/frame (median) | GPU without shadows |");
    println!("|---|---|---|---|---|");
    for res in [256u32, 512] {
        for t in [0usize, 1, 2, 4, 8] {
            let mut scene = base.clone();
            let mut kept = 0;
            scene.objects.retain(|o| {
                if !o.transparent {
                    return true;
                }
                kept += 1;
                kept <= t
            });
            assert_eq!(scene.transparent_count(), t);
            let gpu = time(frames, || {
                let mut frame = r.begin_frame(&scene, &camera, res, res)?;
                for k in 0..t {
                    frame.render_transparent(k)?;
                }
                frame.wait()
            })?;
            let gpu_unshadowed = time(frames, || {
                let mut frame = unshadowed.begin_frame(&scene, &camera, res, res)?;
                for k in 0..t {
                    frame.render_transparent(k)?;
                }
                frame.wait()
            })?;
            let mut planes = vec![0.0f32; glassbake_core::layout::TRANSPARENT_CHANNELS * (res * res) as usize];
            let readback = time(frames, || {
                let mut frame = r.begin_frame(&scene, &camera, res, res)?;
                let _opaque = frame.opaque()?;
                for k in 0..t {
                    frame.transparent_into(k, &mut planes)?;
                }
                Ok(())
            })?;
            println!("| {res}^2 | {t} | {gpu:.1} | {readback:.1} | {gpu_unshadowed:.1} |");
        }
    }
    Ok(())
}

/// Median milliseconds per call after two warm-up calls (the median resists the noise of a
/// shared machine).
fn time(frames: usize, mut f: impl FnMut() -> glassbake_core::Result<()>) -> glassbake_core::Result<f64> {
    for _ in 0..2 {
        f()?;
    }
    let mut ms = Vec::with_capacity(frames);
    for _ in 0..frames.max(1) {
        let start = Instant::now();
        f()?;
        ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    Ok(ms[ms.len() / 2])
}
