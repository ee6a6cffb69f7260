//! The CPU through pass of one frame: every transparent object's through buffer at 256x256
//! for the first camera and variable values of the scene's sample set (seed 0), with each
//! object taken to cover every pixel, so that every pixel's centre, footprint and visibility
//! rays are cast (the real frame casts only the pixels an object covers). The opaque G-buffer
//! is left black: the pass reads only its L_d, which changes no ray.
//! `cargo bench -p glassbake-rays --bench through_pass`.

use criterion::{criterion_group, criterion_main, Criterion};
use glassbake_core::image::PlanarImage;
use glassbake_core::layout;
use glassbake_rays::through::{through_buffer, ThroughScene};
use glassbake_scene::builtin::builtin;

const RESOLUTION: u32 = 256;

fn through_pass(c: &mut Criterion) {
    for name in ["cornellbox8", "desk"] {
        let base = builtin(name).expect("a built-in scene");
        let sample = base.sample(0, 0);
        let scene = base.instantiate(&sample.values).expect("the sample's values are in range");
        let geometry = ThroughScene::build(&scene);
        let opaque_gbuffer = PlanarImage::new(RESOLUTION, RESOLUTION, layout::opaque_channel_names());
        let coverage = vec![1.0; (RESOLUTION * RESOLUTION) as usize];
        let mut group = c.benchmark_group(name);
        group.sample_size(10);
        group.bench_function(format!("{} objects, every pixel covered", geometry.object_count()), |bench| {
            bench.iter(|| {
                (0..geometry.object_count()).map(|k| through_buffer(&scene, &geometry, k, &sample.camera, &opaque_gbuffer, &coverage)).collect::<Vec<_>>()
            })
        });
        group.finish();
    }
}

criterion_group!(benches, through_pass);
criterion_main!(benches);
