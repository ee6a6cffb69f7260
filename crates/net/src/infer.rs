//! Inference: load a model directory and turn one frame's buffers into an image, the
//! transparency buffers fed one at a time (for evaluation, `render` and the real-time path).

use std::path::Path;

use burn::prelude::*;
use burn::tensor::TensorData;

use glassbake_core::{layout, Error, PlanarImage, Result};

use crate::batch::{image_from_tensor, FrameRef, HostBatch};
use crate::config::{ModelKind, NetConfig};
use crate::model::{load_model, SceneModel};
use crate::model_dir::{read_weights, ModelFiles, Network};
use crate::super_sampler::{downsample_box2, SuperSampler};

/// A trained GlassNet (or baseline) ready to render on one device.
pub struct TrainedModel {
    pub net: Box<dyn SceneModel>,
    pub files: ModelFiles,
    pub device: Device,
}

impl TrainedModel {
    pub fn load(dir: &Path, device: &Device) -> Result<TrainedModel> {
        let files = ModelFiles::open(dir)?;
        let Network::Glassnet(config) = &files.config.network else {
            return Err(Error::bad_input(dir.display(), "network", "holds a super-sampler, not GlassNet or a baseline"));
        };
        let net = load_model(config, &files.weights_path(), device)?;
        Ok(TrainedModel { net, files, device: device.clone() })
    }

    /// A model from its `config.json` text and weights file bytes (a web page fetches them
    /// from `dir`, which names the files in errors).
    pub fn from_bytes(config_json: &str, weights: Vec<u8>, dir: &str, device: &Device) -> Result<TrainedModel> {
        let config_label = format!("{dir}/{}", crate::model_dir::CONFIG_FILE);
        let config = crate::model_dir::parse_config(config_json, &config_label)?;
        config.check(&config_label)?;
        let files = ModelFiles { dir: dir.into(), config };
        let Network::Glassnet(config) = &files.config.network else {
            return Err(Error::bad_input(dir, "network", "holds a super-sampler, not GlassNet or a baseline"));
        };
        let net = crate::model::load_model_from_bytes(config, weights, &files.weights_path().display().to_string(), device)?;
        Ok(TrainedModel { net, files, device: device.clone() })
    }

    pub fn config(&self) -> &NetConfig {
        self.net.config()
    }

    pub fn kind(&self) -> ModelKind {
        self.net.kind()
    }

    fn check_frame(&self, frame: &FrameRef) -> Result<()> {
        let (w, h) = (frame.gbuffer.width() as usize, frame.gbuffer.height() as usize);
        self.net.check_inputs(w, h, frame.transparent.len())?;
        if self.config().light_coverage && frame.light_coverage.is_none() {
            return Err(Error::Internal(format!("{} is composited with the light coverage, and the frame has none", self.files.dir.display())));
        }
        Ok(())
    }

    /// Renders one frame to tone-mapped linear RGB (channels R, G, B, values clamped to [0, 1]).
    /// `frame.gbuffer` must be the opaque G-buffer for GlassNet and concat, the naive one for
    /// naive and pixelgen ([`SceneModel::reads_naive_gbuffer`]).
    pub fn render(&self, frame: FrameRef) -> Result<PlanarImage> {
        self.check_frame(&frame)?;
        let batch = HostBatch::from_frames(&[FrameRef { ground_truth: None, ..frame }])?;
        let prediction = self.render_streaming(&batch, |k| Some(batch.transparent_tensor(k, &self.device)));
        image_from_tensor(&prediction.clamp(0.0, 1.0), 0)
    }

    /// Renders one frame at half its resolution, from its buffers 2x2-averaged: the image the
    /// x2 super-sampler brings up (train-sr trains on it, eval scores it). `frame.gbuffer` as
    /// for [`Self::render`]; the transparency buffers are dropped for the models that read none.
    pub fn render_half(&self, frame: FrameRef) -> Result<PlanarImage> {
        let gbuffer = downsample_box2(frame.gbuffer)?;
        // A light's coverage of the larger pixel is the mean of its four quarters', and so is
        // the light it sees (summed over the pixel, divided by its area).
        let light_coverage = frame.light_coverage.map(downsample_box2).transpose()?;
        let transparent =
            if self.net.reads_object_buffers() { frame.transparent.iter().map(downsample_object_buffer).collect::<Result<Vec<_>>>()? } else { Vec::new() };
        self.render(FrameRef {
            gbuffer: &gbuffer,
            light_coverage: light_coverage.as_ref(),
            transparent: &transparent,
            values: frame.values,
            ground_truth: None,
        })
    }

    /// The unclamped prediction of one frame, [3, H, W] flattened: for exact comparisons
    /// (the order test), which clamping could hide.
    pub fn render_raw(&self, frame: FrameRef) -> Result<Vec<f32>> {
        self.check_frame(&frame)?;
        let batch = HostBatch::from_frames(&[FrameRef { ground_truth: None, ..frame }])?;
        let prediction = self.render_streaming(&batch, |k| Some(batch.transparent_tensor(k, &self.device)));
        prediction.into_data().try_to_vec::<f32>().map_err(|e| Error::Internal(format!("reading a prediction: {e:?}")))
    }

    /// Renders a batch, asking `buffer(k)` for transparency buffer k only when it is needed, so
    /// at most one is alive at a time (GlassNet). Returns the unclamped [N, 3, H, W] prediction.
    pub fn render_streaming(&self, batch: &HostBatch, mut buffer: impl FnMut(usize) -> Option<Tensor<4>>) -> Tensor<4> {
        let values = Tensor::from_data(TensorData::new(batch.values.clone(), [batch.frames, batch.variables]), &self.device);
        self.net.forward_streaming(batch.gbuffer_tensor(&self.device), batch.light_coverage_tensor(&self.device), values, batch.objects(), &mut buffer)
    }
}

/// A trained super-sampler.
pub struct TrainedSuperSampler {
    pub net: SuperSampler,
    pub files: ModelFiles,
    pub device: Device,
}

impl TrainedSuperSampler {
    pub fn load(dir: &Path, device: &Device) -> Result<TrainedSuperSampler> {
        let files = ModelFiles::open(dir)?;
        let Network::SuperSampler(config) = &files.config.network else {
            return Err(Error::bad_input(dir.display(), "network", "holds GlassNet, not a super-sampler"));
        };
        let mut net = SuperSampler::new(config, 0, device);
        read_weights(&mut net, &files.weights_path())?;
        Ok(TrainedSuperSampler { net, files, device: device.clone() })
    }

    /// Brings `low` (R, G, B at half the size of `gbuffer`, as [`TrainedModel::render`] gives
    /// it) up to the size of `gbuffer`, the opaque G-buffer at full resolution, composited
    /// with `light_coverage` (the G-buffer's) for a super-sampler trained with it; clamped to
    /// [0, 1] as `render` is.
    pub fn upsample(&self, low: &PlanarImage, gbuffer: &PlanarImage, light_coverage: Option<&PlanarImage>) -> Result<PlanarImage> {
        if self.net.config.light_coverage && light_coverage.is_none() {
            return Err(Error::Internal(format!("{} is composited with the light coverage, and the frame has none", self.files.dir.display())));
        }
        let (w, h) = (gbuffer.width() as usize, gbuffer.height() as usize);
        if low.width() as usize * 2 != w || low.height() as usize * 2 != h {
            return Err(Error::Internal(format!(
                "the super-sampler takes an image of half the G-buffer's size: {}x{} for a {w}x{h} G-buffer",
                low.width(),
                low.height()
            )));
        }
        let mut planes = Vec::with_capacity(3 * low.pixel_count());
        for name in glassbake_core::layout::GROUND_TRUTH_CHANNELS {
            planes.extend_from_slice(low.plane_by_name(name).ok_or_else(|| Error::Internal(format!("low-resolution image without channel {name}")))?);
        }
        let low = Tensor::from_data(TensorData::new(planes, [1, 3, h / 2, w / 2]), &self.device);
        let batch = HostBatch::from_frames(&[FrameRef { gbuffer, light_coverage, transparent: &[], values: &[], ground_truth: None }])?;
        let image = self.net.forward(low, batch.gbuffer_tensor(&self.device), batch.light_coverage_tensor(&self.device));
        image_from_tensor(&image.clamp(0.0, 1.0), 0)
    }
}

/// An object's buffer 2x2-averaged; a through buffer's screen offsets, in pixels, halve with
/// the pixels.
fn downsample_object_buffer(buffer: &PlanarImage) -> Result<PlanarImage> {
    let mut half = downsample_box2(buffer)?;
    if half.channels().len() == layout::TRANSPARENT_CHANNELS + layout::THROUGH_CHANNELS {
        for c in 0..2 {
            half.plane_mut(layout::TRANSPARENT_CHANNELS + layout::through::SCREEN_OFFSET + c).iter_mut().for_each(|v| *v *= 0.5);
        }
    }
    Ok(half)
}
