//! Host-side batches: frames as planar f32 images (the dataset's and rasterizer's format)
//! stacked into NCHW arrays, moved to a device as [`NetInputs`], and images read back.

use burn::prelude::*;
use burn::tensor::TensorData;

use glassbake_core::layout::{self, LIGHT_COVERAGE_CHANNELS, OPAQUE_CHANNELS, THROUGH_CHANNELS, TRANSPARENT_CHANNELS};
use glassbake_core::{Error, PlanarImage, Result};

use crate::model::NetInputs;

/// One frame, borrowed: the G-buffer the model reads (opaque, or naive for the naive
/// baseline), its transparency buffers, normalised variable values and, for training and
/// evaluation, the ground truth (linear RGB).
#[derive(Clone, Copy, Debug)]
pub struct FrameRef<'a> {
    pub gbuffer: &'a PlanarImage,
    /// The light coverage of `gbuffer` (`layout::LIGHT_COVERAGE_ATTRIBUTES`), which the
    /// networks with `NetConfig::light_coverage` need.
    pub light_coverage: Option<&'a PlanarImage>,
    /// Each transparency buffer (`layout::transparent_channel_names(k)`), followed by its
    /// through buffer (`layout::through_channel_names(k)`) for the networks with
    /// `NetConfig::through`; networks without it read only the first channels.
    pub transparent: &'a [PlanarImage],
    pub values: &'a [f32],
    pub ground_truth: Option<&'a PlanarImage>,
}

/// A stack of frames of one size in NCHW order.
#[derive(Clone, Debug)]
pub struct HostBatch {
    pub frames: usize,
    pub width: usize,
    pub height: usize,
    pub variables: usize,
    pub gbuffer: Vec<f32>,
    /// The G-buffer's light coverage, when every frame has it.
    pub light_coverage: Option<Vec<f32>>,
    /// Per transparent object: that object's buffer for every frame.
    pub transparent: Vec<Vec<f32>>,
    /// Channels of each object's buffer: a transparency buffer, followed by its through buffer
    /// where the frames have one (`layout::THROUGH_ATTRIBUTES`).
    pub object_channels: usize,
    pub values: Vec<f32>,
    /// Linear RGB; the loss tone-maps it.
    pub ground_truth: Option<Vec<f32>>,
    /// For the super-sampler: GlassNet's tone-mapped image at half this batch's resolution.
    pub low_res_image: Option<Vec<f32>>,
}

impl HostBatch {
    pub fn from_frames(frames: &[FrameRef]) -> Result<HostBatch> {
        let first = frames.first().ok_or_else(|| Error::Internal("an empty batch".into()))?;
        let (width, height) = (first.gbuffer.width() as usize, first.gbuffer.height() as usize);
        let (objects, variables) = (first.transparent.len(), first.values.len());
        let with_truth = first.ground_truth.is_some();
        let with_coverage = first.light_coverage.is_some();
        let object_channels = first.transparent.first().map_or(TRANSPARENT_CHANNELS, |b| b.channels().len());
        if object_channels != TRANSPARENT_CHANNELS && object_channels != TRANSPARENT_CHANNELS + THROUGH_CHANNELS {
            return Err(Error::Internal(format!(
                "a transparency buffer has {object_channels} channels: {TRANSPARENT_CHANNELS}, or {} with its through buffer",
                TRANSPARENT_CHANNELS + THROUGH_CHANNELS
            )));
        }
        let mut batch = HostBatch {
            frames: frames.len(),
            width,
            height,
            variables,
            gbuffer: Vec::with_capacity(frames.len() * OPAQUE_CHANNELS * width * height),
            light_coverage: with_coverage.then(|| Vec::with_capacity(frames.len() * LIGHT_COVERAGE_CHANNELS * width * height)),
            transparent: vec![Vec::with_capacity(frames.len() * object_channels * width * height); objects],
            object_channels,
            values: Vec::with_capacity(frames.len() * variables),
            ground_truth: with_truth.then(Vec::new),
            low_res_image: None,
        };
        let check = |image: &PlanarImage, channels: usize, what: &str| -> Result<()> {
            if image.width() as usize != width || image.height() as usize != height || image.channels().len() != channels {
                return Err(Error::Internal(format!(
                    "batch frame {what} is {}x{}x{}, expected {width}x{height}x{channels}",
                    image.width(),
                    image.height(),
                    image.channels().len()
                )));
            }
            Ok(())
        };
        for frame in frames {
            check(frame.gbuffer, OPAQUE_CHANNELS, "G-buffer")?;
            if frame.transparent.len() != objects
                || frame.values.len() != variables
                || frame.ground_truth.is_some() != with_truth
                || frame.light_coverage.is_some() != with_coverage
            {
                return Err(Error::Internal("batch frames differ in objects, variables, light coverage or ground truth".into()));
            }
            batch.gbuffer.extend_from_slice(frame.gbuffer.data());
            if let (Some(coverage), Some(out)) = (frame.light_coverage, batch.light_coverage.as_mut()) {
                check(coverage, LIGHT_COVERAGE_CHANNELS, "light coverage")?;
                out.extend_from_slice(coverage.data());
            }
            for (k, buffer) in frame.transparent.iter().enumerate() {
                check(buffer, object_channels, "transparency buffer")?;
                batch.transparent[k].extend_from_slice(buffer.data());
            }
            batch.values.extend_from_slice(frame.values);
            if let (Some(truth), Some(out)) = (frame.ground_truth, batch.ground_truth.as_mut()) {
                check(truth, 3, "ground truth")?;
                for name in layout::GROUND_TRUTH_CHANNELS {
                    let plane = truth.plane_by_name(name).ok_or_else(|| Error::Internal(format!("ground truth has no channel {name}")))?;
                    out.extend_from_slice(plane);
                }
            }
        }
        Ok(batch)
    }

    pub fn objects(&self) -> usize {
        self.transparent.len()
    }

    /// Whether transparent object `k` covers a pixel of any frame of the batch: its coverage
    /// plane is not 0 everywhere.
    pub fn shows_object(&self, k: usize) -> bool {
        let pixels = self.width * self.height;
        let coverage = layout::transparent::COVERAGE * pixels..(layout::transparent::COVERAGE + 1) * pixels;
        self.transparent[k].chunks_exact(self.object_channels * pixels).any(|frame| frame[coverage.clone()].iter().any(|&c| c != 0.0))
    }

    pub fn values_tensor(&self, device: &Device) -> Tensor<2> {
        Tensor::from_data(TensorData::new(self.values.clone(), [self.frames, self.variables]), device)
    }

    fn tensor(&self, data: &[f32], channels: usize, device: &Device) -> Tensor<4> {
        Tensor::from_data(TensorData::new(data.to_vec(), [self.frames, channels, self.height, self.width]), device)
    }

    pub fn gbuffer_tensor(&self, device: &Device) -> Tensor<4> {
        self.tensor(&self.gbuffer, OPAQUE_CHANNELS, device)
    }

    pub fn light_coverage_tensor(&self, device: &Device) -> Option<Tensor<4>> {
        self.light_coverage.as_ref().map(|c| self.tensor(c, LIGHT_COVERAGE_CHANNELS, device))
    }

    /// The network inputs on `device`.
    pub fn inputs(&self, device: &Device) -> NetInputs {
        NetInputs {
            gbuffer: self.tensor(&self.gbuffer, OPAQUE_CHANNELS, device),
            light_coverage: self.light_coverage_tensor(device),
            transparent: self.transparent.iter().map(|b| self.tensor(b, self.object_channels, device)).collect(),
            values: self.values_tensor(device),
        }
    }

    /// Tone-mapped ground truth on `device`.
    pub fn target(&self, device: &Device) -> Option<Tensor<4>> {
        self.ground_truth.as_ref().map(|t| crate::loss::tonemap(self.tensor(t, 3, device)))
    }

    /// Transparency buffer `k` of every frame, for streaming.
    pub fn transparent_tensor(&self, k: usize, device: &Device) -> Tensor<4> {
        self.tensor(&self.transparent[k], self.object_channels, device)
    }

    /// The batch cut into `parts` consecutive runs of frames, as equal as they can be (the
    /// first ones a frame larger); a part of no frames is left out.
    pub fn split(&self, parts: usize) -> Vec<HostBatch> {
        if self.frames == 0 {
            return vec![self.clone()];
        }
        let parts = parts.clamp(1, self.frames.max(1));
        let (base, extra) = (self.frames / parts, self.frames % parts);
        let mut start = 0;
        (0..parts)
            .map(|p| {
                let frames = base + usize::from(p < extra);
                let range = start..start + frames;
                start += frames;
                self.frames_in(range)
            })
            .collect()
    }

    /// Frames `range` of the batch.
    fn frames_in(&self, range: std::ops::Range<usize>) -> HostBatch {
        let pixels = self.width * self.height;
        // Each array holds its frames one after another, `len / frames` values each.
        let cut = |data: &[f32]| {
            let per_frame = data.len() / self.frames;
            data[range.start * per_frame..range.end * per_frame].to_vec()
        };
        debug_assert_eq!(self.gbuffer.len(), self.frames * OPAQUE_CHANNELS * pixels);
        HostBatch {
            frames: range.len(),
            width: self.width,
            height: self.height,
            variables: self.variables,
            gbuffer: cut(&self.gbuffer),
            light_coverage: self.light_coverage.as_deref().map(cut),
            transparent: self.transparent.iter().map(|b| cut(b)).collect(),
            object_channels: self.object_channels,
            values: cut(&self.values),
            ground_truth: self.ground_truth.as_deref().map(cut),
            low_res_image: self.low_res_image.as_deref().map(cut),
        }
    }
}

/// Frame `index` of an [N, 3, H, W] prediction as a linear RGB image (channels R, G, B).
pub fn image_from_tensor(prediction: &Tensor<4>, index: usize) -> Result<PlanarImage> {
    let [_, channels, h, w] = prediction.dims();
    let frame = prediction.clone().narrow(0, index, 1);
    let data = frame.into_data().try_to_vec::<f32>().map_err(|e| Error::Internal(format!("reading the prediction back: {e:?}")))?;
    let names =
        if channels == 3 { layout::GROUND_TRUTH_CHANNELS.iter().map(|s| s.to_string()).collect() } else { (0..channels).map(|c| format!("c{c}")).collect() };
    PlanarImage::from_planes(w as u32, h as u32, names, data)
}
