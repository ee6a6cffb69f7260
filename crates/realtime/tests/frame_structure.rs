//! The zero-copy frame is a fixed set of GPU work: once warm, a frame of GlassNet (light
//! coverage, through rays on the GPU, and the super-sampler when there is one) creates no wgpu
//! object in glassbake's passes, waits on the host once (for its image), and leaves no more
//! objects alive on the device than it found, for 1, 2, 4 and 8 transparent objects; and its
//! image is the host-copy frame's on the CPU network within 1/255. The viewer's frame, shown
//! from the GPU, does not wait at all.
//!
//! This file holds one test: the counts are process-wide, and another test running beside it
//! would add its own.

mod common;

use std::path::Path;

use glassbake_net::init::initialize;
use glassbake_net::model_dir::write_weights;
use glassbake_net::{select_device, DeviceChoice, GlassNet, ModelFiles, Network, SuperSampler, TrainedModel, TrainedSuperSampler};
use glassbake_raster::display::DisplayTexture;
use glassbake_raster::RasterizerOptions;
use glassbake_rays::gpu_stats::GpuStats;
use glassbake_realtime::gpu_handover::{open_shared, with_buffer};
use glassbake_realtime::synth::with_transparent_count;
use glassbake_realtime::{FramePipeline, Output, ThroughRays};
use glassbake_scene::builtin::builtin;
use glassbake_scene::Scene;

const RES: u32 = 32;

/// A small GlassNet (through buffers and light coverage) and a super-sampler, every weight
/// drawn at random so that each input shows in the image.
fn write_models(scene: &Scene, glassnet_dir: &Path, sampler_dir: &Path) {
    let device = select_device(DeviceChoice::Cpu, 0, false);
    let config = common::small_glassnet(scene);
    assert!(config.through && config.light_coverage, "the small GlassNet reads through buffers and the light coverage");
    let files = ModelFiles::prepare(glassnet_dir, common::untrained(scene, Network::Glassnet(config.clone()), RES)).unwrap();
    write_weights(&initialize(GlassNet::new(&config, 0, &device).unwrap(), 1), &files, 0).unwrap();
    let sampler = common::small_super_sampler();
    let files = ModelFiles::prepare(sampler_dir, common::untrained(scene, Network::SuperSampler(sampler.clone()), RES)).unwrap();
    write_weights(&initialize(SuperSampler::new(&sampler, 0, &device), 2), &files, 0).unwrap();
}

#[test]
fn a_warm_zero_copy_frame_creates_nothing_and_waits_once() {
    let scene = builtin("cornellbox").expect("a built-in scene");
    let dirs = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    write_models(&scene, dirs.0.path(), dirs.1.path());

    let shared = open_shared(RasterizerOptions::default()).expect("a Vulkan adapter");
    let gpu = shared.device.clone();
    let glassnet = TrainedModel::load(dirs.0.path(), &gpu).unwrap();
    let mut zero_copy = FramePipeline::with_rasterizer(scene.clone(), glassnet, None, None, shared.rasterizer, true).unwrap();
    // On a CPU adapter the pipeline casts through rays on the CPU by default, off the GPU path.
    zero_copy.set_through_rays(ThroughRays::Gpu);
    assert!(zero_copy.glassnet_frames_zero_copy());
    let cpu = select_device(DeviceChoice::Cpu, 0, false);
    let mut host_copy = FramePipeline::new(scene.clone(), TrainedModel::load(dirs.0.path(), &cpu).unwrap(), None, None, RasterizerOptions::default()).unwrap();
    host_copy.set_through_rays(ThroughRays::Gpu);

    for super_sampled in [false, true] {
        if super_sampled {
            zero_copy.super_sampler = Some(TrainedSuperSampler::load(dirs.1.path(), &gpu).unwrap());
            host_copy.super_sampler = Some(TrainedSuperSampler::load(dirs.1.path(), &cpu).unwrap());
        }
        for objects in [1, 2, 4, 8] {
            let synthetic = with_transparent_count(&scene, objects).unwrap();
            zero_copy.set_scene(synthetic.clone());
            host_copy.set_scene(synthetic.clone());
            let what = format!("{objects} objects{}", if super_sampled { ", super-sampled" } else { "" });
            // Two warm-up frames at other cameras and values, then two counted.
            for i in 0..4u64 {
                let sample = synthetic.sample(7, i);
                let (before, live_before) = (GpuStats::now(), zero_copy.live_gpu_objects());
                let (image, _) = zero_copy.render(&sample.camera, &sample.values, RES, RES, &Output::GlassNet).unwrap();
                let (done, live_after) = (GpuStats::now().since(&before), zero_copy.live_gpu_objects());
                if i >= 2 {
                    assert_eq!(done.objects(), 0, "{what}, frame {i}: glassbake's passes created {done:?}");
                    assert!(done.host_waits <= 1, "{what}, frame {i}: {} host waits", done.host_waits);
                    assert!(live_after <= live_before, "{what}, frame {i}: {live_before} live wgpu objects became {live_after}");
                }
                let (reference, _) = host_copy.render(&sample.camera, &sample.values, RES, RES, &Output::GlassNet).unwrap();
                let worst = image.data().iter().zip(reference.data()).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
                assert!(worst <= 1.0 / 255.0, "{what}, frame {i}: the zero-copy frame is {worst} from the host-copy one");
            }
        }
    }

    // The viewer's frame: the image stays on the device and goes into the display texture,
    // so a warm frame creates nothing and does not wait at all.
    let (_, _, device, queue) = zero_copy.wgpu_handles();
    let mut display = DisplayTexture::new(&device, &queue);
    for i in 0..4u64 {
        let sample = scene.sample(9, i);
        let before = GpuStats::now();
        let (image, _) = zero_copy.render_on_device(&sample.camera, &sample.values, RES, RES, false).unwrap();
        with_buffer(&image, |buffer, offset| display.show(buffer, offset, RES, RES)).unwrap();
        let done = GpuStats::now().since(&before);
        if i >= 2 {
            assert_eq!(done.objects(), 0, "shown frame {i}: glassbake's passes created {done:?}");
            assert_eq!(done.host_waits, 0, "shown frame {i}: the host waited for the GPU");
        }
    }
}
