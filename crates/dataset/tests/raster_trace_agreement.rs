//! The rasterizer and the path tracer agree to the pixel on the camera convention
//! (docs/design.md §2): the naive G-buffer (front-most surface of everything) at a pixel lies
//! where the tracer's primary ray through that pixel centre first hits.

use glassbake_core::layout::opaque;
use glassbake_raster::{Rasterizer, RasterizerOptions};
use glassbake_scene::builtin::builtin;
use glassbake_trace::PreparedScene;

#[test]
fn naive_gbuffer_positions_are_the_tracers_primary_hits() {
    let mut rasterizer = Rasterizer::new(RasterizerOptions::default()).unwrap();
    for name in ["cornellbox", "desk"] {
        let scene = builtin(name).unwrap();
        for i in 0..2 {
            let sample = scene.sample(11, i);
            let instance = scene.instantiate(&sample.values).unwrap();
            let (w, h) = (64, 48);
            let buffers = rasterizer.render(&instance, &sample.camera, w, h).unwrap();
            let traced = PreparedScene::new(&instance);
            let (mut agree, mut total) = (0, 0);
            for y in 0..h {
                for x in 0..w {
                    total += 1;
                    let depth = buffers.naive.get(opaque::DEPTH, x, y);
                    let hit = traced.intersect(&sample.camera.pixel_center_ray(x, y, w, h));
                    let same = match hit {
                        None => depth == 0.0,
                        Some(hit) => {
                            let p = glam::Vec3::new(
                                buffers.naive.get(opaque::POSITION, x, y),
                                buffers.naive.get(opaque::POSITION + 1, x, y),
                                buffers.naive.get(opaque::POSITION + 2, x, y),
                            );
                            (hit.distance - depth).abs() <= 1e-4 * depth.max(1.0) && (hit.position - p).length() <= 1e-4 * depth.max(1.0)
                        }
                    };
                    agree += same as u32;
                }
            }
            // Only exact ties (a pixel centre on a shared edge) may resolve differently.
            assert!(agree as f32 >= 0.995 * total as f32, "{name} sample {i}: {agree}/{total} pixels agree");
        }
    }
}
