//! Synthetic frames for the network tests: random buffers whose ground truth is a smooth,
//! learnable function of them, so tests can train without a dataset.

#![allow(dead_code)]

use glassbake_core::layout::{self, OPAQUE_CHANNELS, THROUGH_CHANNELS, TRANSPARENT_CHANNELS};
use glassbake_core::{PlanarImage, Result};
use glassbake_net::{FrameRef, HostBatch, TrainingData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub struct SyntheticFrame {
    pub opaque: PlanarImage,
    /// No light is seen directly (every L_d plane lies in [0.1, 0.9]): zeros.
    pub light_coverage: PlanarImage,
    /// Each transparency buffer followed by its through buffer.
    pub transparent: Vec<PlanarImage>,
    pub values: Vec<f32>,
    pub ground_truth: PlanarImage,
}

fn smooth_plane(rng: &mut ChaCha8Rng, size: usize) -> Vec<f32> {
    let (a, b, c) = (rng.random_range(-1.0..1.0f32), rng.random_range(-1.0..1.0f32), rng.random_range(0.0..6.0f32));
    (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f32 / size as f32, (i / size) as f32 / size as f32);
            0.5 + 0.4 * (a * x * 3.0 + b * y * 3.0 + c).sin()
        })
        .collect()
}

/// A frame of `size`^2 with `objects` transparency buffers and `variables` values.
pub fn frame(seed: u64, size: usize, objects: usize, variables: usize) -> SyntheticFrame {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let planes = |rng: &mut ChaCha8Rng, n: usize| (0..n).flat_map(|_| smooth_plane(rng, size)).collect::<Vec<f32>>();
    let opaque = PlanarImage::from_planes(size as u32, size as u32, layout::opaque_channel_names(), planes(&mut rng, OPAQUE_CHANNELS)).unwrap();
    let transparent: Vec<PlanarImage> = (0..objects)
        .map(|k| {
            let names = [layout::transparent_channel_names(k), layout::through_channel_names(k)].concat();
            let mut data = planes(&mut rng, TRANSPARENT_CHANNELS + THROUGH_CHANNELS);
            // As the through pass writes them: whole-pixel screen offsets and a 0/1 flag.
            let n = size * size;
            let screen = (TRANSPARENT_CHANNELS + layout::through::SCREEN_OFFSET) * n;
            for v in &mut data[screen..screen + 2 * n] {
                *v = ((*v - 0.5) * 6.0).round();
            }
            for v in &mut data[screen + 2 * n..screen + 3 * n] {
                *v = f32::from(u8::from(*v > 0.5));
            }
            PlanarImage::from_planes(size as u32, size as u32, names, data).unwrap()
        })
        .collect();
    let values: Vec<f32> = (0..variables).map(|_| rng.random_range(0.0..1.0)).collect();
    // Ground truth: albedo lit by L_d, tinted by the first transparency buffer's albedo.
    let mut gt = Vec::with_capacity(3 * size * size);
    for c in 0..3 {
        let albedo = opaque.plane(layout::opaque::ALBEDO + c);
        let light = opaque.plane(layout::opaque::LD + c);
        for i in 0..size * size {
            let tint = transparent.first().map_or(1.0, |t| 0.5 + 0.5 * t.plane(layout::transparent::ALBEDO + c)[i]);
            gt.push(albedo[i] * light[i] * tint);
        }
    }
    let ground_truth = PlanarImage::from_planes(size as u32, size as u32, vec!["B".into(), "G".into(), "R".into()], {
        // Channels alphabetically, as read_exr returns them: B, G, R.
        let n = size * size;
        [&gt[2 * n..], &gt[n..2 * n], &gt[..n]].concat()
    })
    .unwrap();
    let light_coverage = PlanarImage::new(size as u32, size as u32, layout::opaque_light_coverage_channel_names());
    SyntheticFrame { opaque, light_coverage, transparent, values, ground_truth }
}

pub fn frame_ref(f: &SyntheticFrame) -> FrameRef<'_> {
    FrameRef {
        gbuffer: &f.opaque,
        light_coverage: Some(&f.light_coverage),
        transparent: &f.transparent,
        values: &f.values,
        ground_truth: Some(&f.ground_truth),
    }
}

pub fn batch(frames: &[SyntheticFrame]) -> HostBatch {
    let refs: Vec<FrameRef> = frames.iter().map(frame_ref).collect();
    HostBatch::from_frames(&refs).unwrap()
}

/// A training set of `frames` synthetic frames in batches of `batch_size`, shuffled per epoch.
pub struct SyntheticData {
    pub frames: Vec<SyntheticFrame>,
    pub batch_size: usize,
    pub seed: u64,
    /// From this epoch on, ground truth is NaN (for the NaN guard test).
    pub poison_from_epoch: Option<u64>,
}

impl TrainingData for SyntheticData {
    fn batches_per_epoch(&self) -> usize {
        self.frames.len().div_ceil(self.batch_size)
    }

    fn epoch(&mut self, epoch: u64, skip: usize) -> Box<dyn Iterator<Item = Result<HostBatch>> + '_> {
        let mut order: Vec<usize> = (0..self.frames.len()).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ epoch.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        rand::seq::SliceRandom::shuffle(order.as_mut_slice(), &mut rng);
        let poison = self.poison_from_epoch.is_some_and(|e| epoch >= e);
        let chunks: Vec<Vec<usize>> = order.chunks(self.batch_size).map(|c| c.to_vec()).collect();
        Box::new(chunks.into_iter().skip(skip).map(move |chunk| {
            let frames: Vec<&SyntheticFrame> = chunk.iter().map(|&i| &self.frames[i]).collect();
            let refs: Vec<FrameRef> = frames.iter().map(|f| frame_ref(f)).collect();
            let mut batch = HostBatch::from_frames(&refs)?;
            if poison {
                batch.ground_truth.as_mut().unwrap()[0] = f32::NAN;
            }
            Ok(batch)
        }))
    }

    fn validation(&mut self) -> Result<Vec<HostBatch>> {
        Ok(vec![batch(&self.frames[..1])])
    }
}

/// The data source recorded for models trained on synthetic frames.
pub fn synthetic_source() -> glassbake_net::DataSource {
    glassbake_net::DataSource {
        dataset: "synthetic".into(),
        scene: "none".into(),
        scene_hash: "0".into(),
        resolution: 16,
        scene_argument: None,
        sample_seed: None,
        dataset_sha256: None,
    }
}

/// `kind` of the smallest network (`NetShape::smallest`) for `variables` variables and `objects` transparent objects.
pub fn small_net(kind: glassbake_net::ModelKind, variables: usize, objects: usize) -> glassbake_net::NetConfig {
    glassbake_net::NetConfig::new(&glassbake_net::NetShape::smallest(), "small", kind, variables, objects).unwrap()
}

/// A few steps of whole frames, two at a time, validated and checkpointed every 10 steps.
pub fn small_training() -> glassbake_net::TrainConfig {
    glassbake_net::TrainConfig {
        steps: 40,
        batch_size: 2,
        crop: None,
        learning_rate: 1e-3,
        weight_decay: 1e-4,
        warmup_steps: 5,
        final_lr_fraction: 0.05,
        ssim_weight: 1.0,
        validate_every: 10,
        checkpoint_every: 10,
        validation_frames: Some(2),
        seed: 0,
    }
}

pub fn small_super_sampler() -> glassbake_net::SuperSamplerConfig {
    glassbake_net::SuperSamplerConfig {
        preset: "small".into(),
        encoding_frequencies: 1,
        network: glassbake_net::config::CnnConfig { width: 4, layers: 1, out_channels: 3 },
        light_coverage: true,
    }
}

/// Whether a wgpu adapter exists (burn's wgpu runtime panics without one), probed with the same
/// wgpu; where none does, the test says it skipped, or fails with
/// GLASSBAKE_TEST_RESOURCES=required.
pub fn wgpu_adapter_exists() -> bool {
    let instance = glassbake_net::burn::tensor::wgpu::wgpu::Instance::default();
    if pollster_block_on(instance.request_adapter(&Default::default())).is_ok() {
        return true;
    }
    assert!(!resources_required(), "no wgpu adapter, and GLASSBAKE_TEST_RESOURCES=required");
    eprintln!("SKIPPED: no wgpu adapter on this machine");
    false
}

fn pollster_block_on<F: std::future::Future>(future: F) -> F::Output {
    // A tiny executor: request_adapter completes without real waiting on native backends.
    use std::task::{Context, Poll, RawWaker, RawWakerVTable, Waker};
    fn noop(_: *const ()) {}
    fn clone(p: *const ()) -> RawWaker {
        RawWaker::new(p, &VTABLE)
    }
    static VTABLE: RawWakerVTable = RawWakerVTable::new(clone, noop, noop, noop);
    let waker = unsafe { Waker::from_raw(RawWaker::new(std::ptr::null(), &VTABLE)) };
    let mut cx = Context::from_waker(&waker);
    let mut future = std::pin::pin!(future);
    loop {
        if let Poll::Ready(v) = future.as_mut().poll(&mut cx) {
            return v;
        }
        std::thread::yield_now();
    }
}

/// `.ci/run` sets GLASSBAKE_TEST_RESOURCES=required after installing what the tests need:
/// there a test must not skip for want of it.
fn resources_required() -> bool {
    std::env::var("GLASSBAKE_TEST_RESOURCES").is_ok_and(|v| v == "required")
}
