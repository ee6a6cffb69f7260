//! Opening a trained scene for real-time frames: the models loaded on the device asked for,
//! their scene found, and the frame pipeline built on one shared GPU device where it can be.

use std::path::PathBuf;

use glassbake_core::{Error, Result};
use glassbake_net::{select_device, DeviceChoice, TrainedModel, TrainedSuperSampler};
use glassbake_raster::light_coverage::LIGHT_COVERAGE_FACTOR;
use glassbake_raster::RasterizerOptions;

use crate::gpu_handover::open_shared;
use crate::{scene_of_model, FramePipeline, ThroughRays};

/// A trained GlassNet and its optional companions, and how to run them.
#[derive(Clone, Debug)]
pub struct PipelineRequest {
    /// The GlassNet model directory.
    pub model: PathBuf,
    /// A naive baseline to switch to.
    pub naive: Option<PathBuf>,
    /// A x2 super-sampler: the network runs at half the resolution.
    pub super_sampler: Option<PathBuf>,
    /// The scene, when the model's training dataset is not at hand (the same scene).
    pub scene: Option<String>,
    pub device: DeviceChoice,
    /// With `DeviceChoice::Wgpu`: separate devices, buffers through host memory.
    pub host_copy: bool,
    /// Samples per pixel side of the lights' coverage (1 to 4).
    pub light_coverage_samples: u32,
    /// Where the through rays are cast (`None`: the pipeline's choice for its adapter).
    pub through_rays: Option<ThroughRays>,
}

impl PipelineRequest {
    /// The GlassNet in `model` on `device`, as a bake evaluates it.
    pub fn new(model: impl Into<PathBuf>, device: DeviceChoice) -> PipelineRequest {
        PipelineRequest {
            model: model.into(),
            naive: None,
            super_sampler: None,
            scene: None,
            device,
            host_copy: false,
            light_coverage_samples: LIGHT_COVERAGE_FACTOR,
            through_rays: None,
        }
    }
}

/// A frame pipeline ready to render.
pub struct OpenedPipeline {
    pub pipeline: FramePipeline,
    /// The seed of the model's dataset samples (sample i is its frame i).
    pub dataset_seed: u64,
    /// Where the networks run, in words.
    pub device: String,
}

/// Loads the models of `request` and builds their frame pipeline.
pub fn open_pipeline(request: &PipelineRequest) -> Result<OpenedPipeline> {
    if !(1..=LIGHT_COVERAGE_FACTOR).contains(&request.light_coverage_samples) {
        return Err(Error::bad_input("--light-coverage-samples", "light_coverage_samples", format!("must be in 1..={LIGHT_COVERAGE_FACTOR}")));
    }
    let wgpu = request.device == DeviceChoice::Wgpu;
    let shared = if wgpu && !request.host_copy { Some(open_shared(RasterizerOptions::default())?) } else { None };
    let device = match &shared {
        Some(s) => s.device.clone(),
        None => select_device(request.device, 0, false),
    };
    let glassnet = TrainedModel::load(&request.model, &device)?;
    let scene = scene_of_model(&glassnet, request.scene.as_deref())?;
    let naive = request.naive.as_deref().map(|d| TrainedModel::load(d, &device)).transpose()?;
    let sr = request.super_sampler.as_deref().map(|d| TrainedSuperSampler::load(d, &device)).transpose()?;
    let (mut pipeline, name) = match shared {
        Some(s) => (FramePipeline::with_rasterizer(scene.scene, glassnet, naive, sr, s.rasterizer, true)?, "wgpu, shared with the rasterizer (no host copies)"),
        None => (
            FramePipeline::new(scene.scene, glassnet, naive, sr, RasterizerOptions::default())?,
            if wgpu { "wgpu, buffers through host memory" } else { request.device.name() },
        ),
    };
    pipeline.light_coverage_factor = request.light_coverage_samples;
    if let Some(rays) = request.through_rays {
        pipeline.set_through_rays(rays);
    }
    Ok(OpenedPipeline { pipeline, dataset_seed: scene.dataset_seed, device: name.to_string() })
}
