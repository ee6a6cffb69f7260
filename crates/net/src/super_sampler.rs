//! The x2 super-sampler (paper 3.4, 4.4): a small full-resolution CNN, trained after and apart
//! from GlassNet, from (GlassNet's image at R, the G-buffer at 2R) to the ground truth at 2R.
//! It predicts a residual over the nearest-neighbour up-sampled image, so an untrained one
//! already starts from a sensible answer; the cheap high-resolution G-buffer supplies the edges
//! and textures the low-resolution image lacks.

use burn::prelude::*;
use burn::tensor::TensorData;

use glassbake_core::layout::OPAQUE_CHANNELS;
use glassbake_core::{Error, PlanarImage, Result};

use crate::batch::HostBatch;
use crate::blocks::{positional_encoding, PlainCnn};
pub use crate::config::SuperSamplerConfig;
use crate::train::Trainable;

#[derive(Module, Debug)]
pub struct SuperSampler {
    pub network: PlainCnn,
    #[module(skip)]
    pub config: SuperSamplerConfig,
}

/// Nearest-neighbour x2 up-sampling by reshaping, so its backward pass (a sum) runs on every
/// backend.
pub fn upsample_nearest2(x: Tensor<4>) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    x.reshape([n, c, h, 1, w, 1]).expand([n, c, h, 2, w, 2]).reshape([n, c, 2 * h, 2 * w])
}

/// 2x2 box average, the low-resolution view of a high-resolution buffer.
pub fn downsample_box2(image: &PlanarImage) -> Result<PlanarImage> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    if w % 2 != 0 || h % 2 != 0 {
        return Err(Error::Internal(format!("box down-sampling needs even sides, got {w}x{h}")));
    }
    let (lw, lh) = (w / 2, h / 2);
    let mut data = Vec::with_capacity(image.channels().len() * lw * lh);
    for c in 0..image.channels().len() {
        let plane = image.plane(c);
        for y in 0..lh {
            for x in 0..lw {
                let at = |dx: usize, dy: usize| plane[(2 * y + dy) * w + 2 * x + dx];
                data.push(0.25 * (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)));
            }
        }
    }
    PlanarImage::from_planes(lw as u32, lh as u32, image.channels().to_vec(), data)
}

/// [`downsample_box2`] of a [n, c, h, w] tensor on its own device (the real-time frame's
/// light coverage, which stays on the GPU), adding the four texels in the same order, so the
/// two agree bit for bit.
pub fn downsample_box2_tensor(x: Tensor<4>) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    let quads = x.reshape([n * c * h / 2, 2, w / 2, 2]);
    let texel = |dx: usize, dy: usize| quads.clone().narrow(1, dy, 1).narrow(3, dx, 1);
    let sum = texel(0, 0) + texel(1, 0) + texel(0, 1) + texel(1, 1);
    sum.mul_scalar(0.25).reshape([n, c, h / 2, w / 2])
}

impl SuperSampler {
    /// A super-sampler with weights drawn from `seed` (see `init.rs`).
    pub fn new(config: &SuperSamplerConfig, seed: u64, device: &Device) -> SuperSampler {
        let inputs = 3 + OPAQUE_CHANNELS * (1 + 2 * config.encoding_frequencies);
        crate::init::initialize(SuperSampler { network: PlainCnn::new(inputs, &config.network, device), config: config.clone() }, seed)
    }

    /// `low`: [N, 3, H, W] tone-mapped image; `gbuffer`: [N, 17, 2H, 2W] -> [N, 3, 2H, 2W].
    /// `light_coverage`: [N, 4, 2H, 2W], the G-buffer's, which a super-sampler with
    /// [`SuperSamplerConfig::light_coverage`] composites over its image (and panics without).
    pub fn forward(&self, low: Tensor<4>, gbuffer: Tensor<4>, light_coverage: Option<Tensor<4>>) -> Tensor<4> {
        let up = upsample_nearest2(low);
        let encoded = positional_encoding(gbuffer, self.config.encoding_frequencies);
        let image = up.clone() + self.network.forward(Tensor::cat(vec![up, encoded], 1));
        if !self.config.light_coverage {
            return image;
        }
        let coverage = light_coverage.expect("a super-sampler composited with the light coverage is given the G-buffer's light coverage");
        crate::model::composite_light(image, coverage, None)
    }
}

impl Trainable for SuperSampler {
    fn predict(&self, batch: &HostBatch, device: &Device) -> Tensor<4> {
        let low = batch.low_res_image.as_ref().expect("super-sampler batches carry the low-resolution image");
        let low = Tensor::from_data(TensorData::new(low.clone(), [batch.frames, 3, batch.height / 2, batch.width / 2]), device);
        self.forward(low, batch.gbuffer_tensor(device), batch.light_coverage_tensor(device))
    }

    fn target(&self, batch: &HostBatch, device: &Device) -> Result<Tensor<4>> {
        batch.target(device).ok_or_else(|| Error::Internal("a training batch without ground truth".into()))
    }
}

#[cfg(test)]
mod box_tests {
    use super::*;

    #[test]
    fn the_tensor_box_filter_is_the_host_one_bit_for_bit() {
        let (w, h) = (6u32, 4u32);
        let names: Vec<String> = ["a", "b"].iter().map(|s| s.to_string()).collect();
        // Values whose sums round differently in another order.
        let data: Vec<f32> = (0..2 * w * h).map(|i| 1.0 / (1.0 + i as f32) + (i % 5) as f32 * 1e7).collect();
        let image = PlanarImage::from_planes(w, h, names, data.clone()).unwrap();
        let host = downsample_box2(&image).unwrap();
        let device = Device::flex();
        let tensor = Tensor::<4>::from_data(TensorData::new(data, [1, 2, h as usize, w as usize]), &device);
        let on_device = downsample_box2_tensor(tensor).into_data().try_to_vec::<f32>().unwrap();
        assert_eq!(on_device.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), host.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>());
    }
}
