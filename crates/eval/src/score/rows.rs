//! The rows of an evaluation, in table order: each model, the half-resolution rows of the
//! model the super-sampler brings up, the path-traced baseline's, the noise floor's. One
//! type holds what makes each row's image of a frame and the row's name, so the names and the
//! images cannot go out of step.

use std::time::Instant;

use glassbake_core::layout::{self, GROUND_TRUTH_CHANNELS};
use glassbake_core::seed::purpose_seed;
use glassbake_core::{Error, PlanarImage, Result};
use glassbake_dataset::{DatasetStore, Example, SampleRecord};
use glassbake_net::{FrameRef, TrainedModel, TrainedSuperSampler};
use glassbake_scene::Scene;
use glassbake_trace::TraceSettings;

use super::{half_resolution_rows, path_traced_rows};
use crate::denoise::{denoise, DenoiseInput};
use crate::RgbImage;

/// What an evaluation scores.
pub(super) struct Rows {
    /// The trained models, each with its row's name.
    pub models: Vec<(String, TrainedModel)>,
    /// One model also rendered at half resolution and brought up (two rows).
    pub half: Option<HalfResolution>,
    /// The path-traced baseline's spp and the scene it traces (two rows: traced, denoised).
    pub path_traced: Option<(u32, Scene)>,
    /// The noise floor's row name, where the split has one.
    pub noise_floor: Option<String>,
}

impl Rows {
    /// The rows' names, in the order [`Self::predict`] gives their images.
    pub fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.models.iter().map(|(name, _)| name.clone()).collect();
        if let Some(half) = &self.half {
            names.extend(half_resolution_rows(&self.models[half.model].0));
        }
        if let Some((spp, _)) = &self.path_traced {
            names.extend(path_traced_rows(*spp));
        }
        names.extend(self.noise_floor.clone());
        names
    }

    /// Every row's image of frame `e` of `store`, in the order of [`Self::names`].
    pub fn predict(&self, e: &Example, store: &DatasetStore) -> Result<Vec<Prediction>> {
        let mut predictions = Vec::new();
        for (_, model) in &self.models {
            let (gbuffer, light_coverage) = e.gbuffer(model.net.reads_naive_gbuffer());
            let transparent: &[PlanarImage] = if model.net.reads_object_buffers() { &e.transparent } else { &[] };
            let started = Instant::now();
            let image = model.render(FrameRef { gbuffer, light_coverage: Some(light_coverage), transparent, values: &e.values, ground_truth: None })?;
            predictions.push(Prediction { seconds: Some(started.elapsed().as_secs_f64()), image: RgbImage::from_planar(&image)? });
        }
        if let Some(half) = &self.half {
            let (gbuffer, light_coverage) = e.gbuffer(false);
            let frame = FrameRef { gbuffer, light_coverage: Some(light_coverage), transparent: &e.transparent, values: &e.values, ground_truth: None };
            predictions.extend(half.render(&self.models[half.model].1, frame)?);
        }
        if let Some((spp, scene)) = &self.path_traced {
            let sample = store
                .manifest
                .samples
                .iter()
                .find(|s| s.index == e.index)
                .ok_or_else(|| Error::Internal(format!("frame {} is not in the manifest", e.index)))?;
            let naive = e.naive.as_ref().expect("the loader was asked for naive buffers");
            predictions.extend(path_traced_baseline(scene, sample, naive, *spp)?);
        }
        if self.noise_floor.is_some() {
            let image = RgbImage::from_planar(&PlanarImage::read_exr(&store.train_spp_gt_path(e.index))?)?;
            predictions.push(Prediction { image, seconds: None });
        }
        Ok(predictions)
    }
}

/// A model rendering frames at half resolution ([`TrainedModel::render_half`]) and the
/// super-sampler that brings them up.
pub(super) struct HalfResolution {
    pub sampler: TrainedSuperSampler,
    /// Index of the model among the scored ones.
    pub model: usize,
}

/// One row's image of a frame and, for a row that renders it, the seconds that took.
pub(super) struct Prediction {
    pub image: RgbImage,
    pub seconds: Option<f64>,
}

impl HalfResolution {
    /// The frame super-sampled and bilinearly enlarged (rows [`half_resolution_rows`]), the
    /// half-resolution render counted in both times.
    fn render(&self, model: &TrainedModel, frame: FrameRef) -> Result<[Prediction; 2]> {
        let started = Instant::now();
        let low = model.render_half(frame)?;
        let gbuffer = frame.gbuffer;
        let low_seconds = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let super_sampled = RgbImage::from_planar(&self.sampler.upsample(&low, gbuffer, frame.light_coverage)?)?;
        let super_sampled_seconds = low_seconds + started.elapsed().as_secs_f64();
        let started = Instant::now();
        let bilinear = RgbImage::from_planar(&low)?.bilinear_x2();
        let bilinear_seconds = low_seconds + started.elapsed().as_secs_f64();
        Ok([Prediction { image: super_sampled, seconds: Some(super_sampled_seconds) }, Prediction { image: bilinear, seconds: Some(bilinear_seconds) }])
    }
}

/// Planes `first..first + 3` of `image` (an RGB or XYZ attribute).
fn three_planes(image: &PlanarImage, first: usize) -> [&[f32]; 3] {
    [image.plane(first), image.plane(first + 1), image.plane(first + 2)]
}

/// The path-traced baseline of one frame (rows [`path_traced_rows`]): `sample` of `scene`
/// traced at `spp` with the ground truth's default estimator (`TraceSettings::new`) and a
/// seed of its own (not the ground truth's), then the same denoised with the naive
/// G-buffer's first-surface albedo and normals as guides.
fn path_traced_baseline(scene: &Scene, sample: &SampleRecord, naive: &PlanarImage, spp: u32) -> Result<[Prediction; 2]> {
    let (w, h) = (naive.width(), naive.height());
    let instance = scene.instantiate(&sample.values)?;
    let settings = TraceSettings::new(w, h, spp, purpose_seed(sample.seed, "path-traced baseline"));
    let started = Instant::now();
    let traced = glassbake_trace::render(&instance, &sample.camera, &settings, None)?;
    let trace_seconds = started.elapsed().as_secs_f64();
    // OIDN reads interleaved RGB; the denoiser gets unclamped (HDR) radiance.
    let interleave = |planes: [&[f32]; 3]| -> Vec<f32> { (0..(w * h) as usize).flat_map(|i| planes.map(|p| p[i])).collect() };
    let color = interleave(GROUND_TRUTH_CHANNELS.map(|c| traced.image.plane_by_name(c).expect("the tracer writes R, G, B")));
    let albedo = interleave(three_planes(naive, layout::opaque::ALBEDO));
    let normal = interleave(three_planes(naive, layout::opaque::NORMAL));
    let started = Instant::now();
    let denoised = denoise(&DenoiseInput { width: w as usize, height: h as usize, color: &color, albedo: &albedo, normal: &normal })?;
    let denoise_seconds = started.elapsed().as_secs_f64();
    let rgb = |v: &[f32]| RgbImage::new(w as usize, h as usize, v.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect());
    Ok([
        Prediction { image: rgb(&color)?, seconds: Some(trace_seconds) },
        Prediction { image: rgb(&denoised)?, seconds: Some(trace_seconds + denoise_seconds) },
    ])
}
