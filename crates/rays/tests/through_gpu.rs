//! The GPU through pass against the CPU's on built-in scenes: the same rays, surfaces, optics
//! and lobe points, so every channel agrees up to rounding, but for the few pixels where
//! rounding sends a ray on the other side of a triangle edge.

use glassbake_core::image::PlanarImage;
use glassbake_core::layout::{self, opaque, through, THROUGH_CHANNELS};
use glassbake_rays::through::{through_buffer, ThroughScene};
use glassbake_rays::through_gpu::GpuThroughPass;
use rand::{Rng, SeedableRng};

/// `.ci/run` sets GLASSBAKE_TEST_RESOURCES=required after installing the software Vulkan
/// driver: there the test must not skip for want of an adapter.
fn device() -> Option<(wgpu::Device, wgpu::Queue)> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor { backends: wgpu::Backends::VULKAN, ..wgpu::InstanceDescriptor::new_without_display_handle() });
    let adapter = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN)).into_iter().next();
    let Some(adapter) = adapter else {
        assert!(std::env::var("GLASSBAKE_TEST_RESOURCES").map_or(true, |v| v != "required"), "no Vulkan adapter");
        eprintln!("skipped: no Vulkan adapter");
        return None;
    };
    let descriptor = wgpu::DeviceDescriptor { required_limits: adapter.limits(), ..Default::default() };
    Some(pollster::block_on(adapter.request_device(&descriptor)).expect("a device on the adapter"))
}

/// The share of `k`'s pixels where the two passes disagree beyond rounding in some channel,
/// and the number of pixels cast.
fn disagreement(cpu: &PlanarImage, gpu: &PlanarImage) -> (f64, usize) {
    let (w, h) = (cpu.width(), cpu.height());
    let (mut differ, mut cast) = (0usize, 0usize);
    for y in 0..h {
        for x in 0..w {
            let cpu_at = |c| cpu.get(c, x, y);
            let gpu_at = |c| gpu.get(c, x, y);
            if cpu_at(through::TRANSMITTANCE) > 0.0 || gpu_at(through::TRANSMITTANCE) > 0.0 {
                cast += 1;
            }
            let same = (0..THROUGH_CHANNELS).all(|c| {
                let (a, b) = (cpu_at(c), gpu_at(c));
                (a - b).abs() <= 2e-3 * a.abs().max(b.abs()).max(1.0)
            });
            if !same {
                differ += 1;
            }
        }
    }
    (differ as f64 / (w * h) as f64, cast)
}

/// An opaque G-buffer whose direct light L_d (what the hits read where the camera sees them)
/// is random: any values will do.
fn random_direct_light(w: u32, h: u32, rng: &mut rand_chacha::ChaCha8Rng) -> PlanarImage {
    let mut gbuffer = PlanarImage::new(w, h, layout::opaque_channel_names());
    for c in opaque::LD..opaque::LD + 3 {
        for y in 0..h {
            for x in 0..w {
                gbuffer.set(c, x, y, rng.random::<f32>());
            }
        }
    }
    gbuffer
}

#[test]
fn gpu_and_cpu_through_passes_agree_on_builtin_scenes() {
    let Some((device, queue)) = device() else { return };
    let pass = GpuThroughPass::new(device, queue).unwrap();
    let (w, h) = (64, 48);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    // cornellbox8: solid, thin, rough and curved glass; desk: textured surfaces behind glass.
    for name in ["cornellbox8", "desk"] {
        let base = glassbake_scene::builtin::builtin(name).unwrap();
        let sample = base.sample(3, 1);
        let scene = base.instantiate(&sample.values).unwrap();
        let gbuffer = random_direct_light(w, h, &mut rng);
        // Every pixel cast: the rays through each object and past it.
        let coverage = vec![1.0; (w * h) as usize];
        let geometry = ThroughScene::build(&scene);
        let uploaded = pass.upload(&scene).unwrap();
        let (mut bent, mut lit_unseen) = (0, 0);
        for k in 0..geometry.object_count() {
            let cpu = through_buffer(&scene, &geometry, k, &sample.camera, &gbuffer, &coverage);
            let gpu = pass.through_buffer(&uploaded, k, &sample.camera, &gbuffer, &coverage).unwrap();
            assert_eq!(cpu.channels(), gpu.channels());
            let (share, cast) = disagreement(&cpu, &gpu);
            eprintln!("{name} object {k}: {cast} pixels cast, {:.3}% disagree", 100.0 * share);
            assert!(cast > (w * h) as usize / 2, "{name} object {k}: only {cast} pixels cast");
            assert!(share < 0.002, "{name} object {k}: {:.2}% of pixels disagree", 100.0 * share);
            // Refraction reached the comparison: some pixels see the scene displaced.
            bent += (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .filter(|&(x, y)| cpu.get(through::SCREEN_OFFSET, x, y).abs() + cpu.get(through::SCREEN_OFFSET + 1, x, y).abs() >= 2.0)
                .count();
            // The lights' direct light reached the comparison: hits the camera does not see
            // (whose L_d is not the G-buffer's) that are lit.
            lit_unseen += (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .filter(|&(x, y)| cpu.get(through::ON_SCREEN, x, y) == 0.0 && cpu.get(through::ALBEDO, x, y) > 0.0 && cpu.get(through::LD, x, y) > 0.0)
                .count();
        }
        assert!(bent > 20, "{name}: only {bent} pixels see through bent glass");
        assert!(lit_unseen > 20, "{name}: only {lit_unseen} lit pixels where the camera does not see the hit");
    }
}

/// A variable moves objects and a light: the next upload refits the BVHs it was handed and
/// casts what a fresh upload casts, but where a ray meets two triangles at the same distance
/// (an edge the two trees reach in another order).
#[test]
fn an_upload_refit_to_moved_objects_casts_what_a_fresh_upload_casts() {
    let Some((device, queue)) = device() else { return };
    let pass = GpuThroughPass::new(device, queue).unwrap();
    let (w, h) = (64, 48);
    let base = glassbake_scene::builtin::builtin("cornellbox8").unwrap();
    let (before, after) = (base.sample(5, 0), base.sample(5, 1));
    let moved = base.instantiate(&after.values).unwrap();
    let gbuffer = random_direct_light(w, h, &mut rand_chacha::ChaCha8Rng::seed_from_u64(11));
    let coverage = vec![1.0; (w * h) as usize];
    let first = pass.upload(&base.instantiate(&before.values).unwrap()).unwrap();
    assert_eq!(first.refits_since_build(), 0);
    let refit = pass.upload_reusing(&moved, Some(first)).unwrap();
    assert_eq!(refit.refits_since_build(), 1, "the same triangles, moved: refit, not built");
    let fresh = pass.upload(&moved).unwrap();
    for k in 0..moved.transparent_count() {
        let a = pass.through_buffer(&refit, k, &after.camera, &gbuffer, &coverage).unwrap();
        let b = pass.through_buffer(&fresh, k, &after.camera, &gbuffer, &coverage).unwrap();
        let (share, cast) = disagreement(&a, &b);
        let identical = a.data().iter().zip(b.data()).filter(|(x, y)| x.to_bits() == y.to_bits()).count();
        eprintln!("object {k}: {cast} pixels cast, {:.3}% disagree, {identical} of {} values identical", 100.0 * share, a.data().len());
        assert!(cast > (w * h) as usize / 2, "object {k}: only {cast} pixels cast");
        assert!(share < 0.001, "object {k}: {:.2}% of pixels disagree", 100.0 * share);
    }
    // An object gone from the scene changes the triangles: built again.
    let mut fewer = moved.clone();
    let gone = fewer.transparent_objects()[0];
    fewer.objects.remove(gone);
    let rebuilt = pass.upload_reusing(&fewer, Some(refit)).unwrap();
    assert_eq!(rebuilt.refits_since_build(), 0);
}
