//! The layer types GlassNet is built from: a 3x3 convolution + activation, the U-Net of F and
//! B, the plain CNN of h, the rendering network R and NeRF positional encoding.

use burn::nn::conv::{Conv2d, Conv2dConfig, ConvTranspose2d, ConvTranspose2dConfig};
use burn::nn::PaddingConfig2d;
use burn::prelude::*;
use burn::tensor::{DType, TensorData};

use crate::config::{CnnConfig, PixelGeneratorConfig, RendererConfig, UNetConfig};
pub use crate::convolution::apply_conv;
use crate::convolution::apply_conv_transpose;
use crate::device::is_cpu;
#[cfg(not(target_arch = "wasm32"))]
use crate::flex_ops::leaky_relu;
#[cfg(target_arch = "wasm32")]
use burn::tensor::activation::leaky_relu;

/// Leaky slope of every hidden activation: small nets lose too many units to plain ReLU.
const LEAK: f64 = 0.1;

fn conv(in_channels: usize, out_channels: usize, kernel: usize, device: &Device) -> Conv2d {
    Conv2dConfig::new([in_channels, out_channels], [kernel, kernel]).with_padding(PaddingConfig2d::Same).init(device)
}

/// Convolution followed by a leaky ReLU.
#[derive(Module, Debug)]
pub struct ConvAct {
    pub conv: Conv2d,
}

impl ConvAct {
    pub fn new(in_channels: usize, out_channels: usize, kernel: usize, device: &Device) -> Self {
        ConvAct { conv: conv(in_channels, out_channels, kernel, device) }
    }

    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        leaky_relu(apply_conv(&self.conv, x), LEAK)
    }
}

/// Two 3x3 convolutions, the unit of every U-Net level.
#[derive(Module, Debug)]
pub struct DoubleConv {
    pub first: ConvAct,
    pub second: ConvAct,
}

impl DoubleConv {
    pub fn new(in_channels: usize, out_channels: usize, device: &Device) -> Self {
        DoubleConv { first: ConvAct::new(in_channels, out_channels, 3, device), second: ConvAct::new(out_channels, out_channels, 3, device) }
    }

    /// The input level of a network fed encoded buffers: a 1x1 projection of the wide
    /// positional encoding (9-13 channels per input channel) before the 3x3 convolution, which
    /// would otherwise cost most of the network's time.
    pub fn new_stem(in_channels: usize, out_channels: usize, device: &Device) -> Self {
        DoubleConv { first: ConvAct::new(in_channels, out_channels, 1, device), second: ConvAct::new(out_channels, out_channels, 3, device) }
    }

    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        self.second.forward(self.first.forward(x))
    }
}

/// U-Net (Ronneberger et al. 2015) with strided-convolution down-sampling and
/// transposed-convolution up-sampling; the first convolution is 1x1 (see
/// [`DoubleConv::new_stem`]) and a 1x1 head maps to the output channels.
#[derive(Module, Debug)]
pub struct UNet {
    /// One per level, top to bottom (the last is the bottleneck).
    pub encoder: Vec<DoubleConv>,
    /// Stride-2 3x3 convolutions between encoder levels.
    pub down: Vec<ConvAct>,
    /// 2x2 stride-2 transposed convolutions, bottom to top.
    pub up: Vec<ConvTranspose2d>,
    /// One per level above the bottleneck, bottom to top; reads (up-sampled, skip).
    pub decoder: Vec<DoubleConv>,
    pub head: Conv2d,
}

impl UNet {
    pub fn new(in_channels: usize, config: &UNetConfig, device: &Device) -> Self {
        let width = |level: usize| config.base_width << level;
        let mut encoder = Vec::new();
        let mut down = Vec::new();
        for level in 0..config.levels {
            encoder.push(if level == 0 { DoubleConv::new_stem(in_channels, width(0), device) } else { DoubleConv::new(width(level), width(level), device) });
            if level + 1 < config.levels {
                down.push(ConvAct {
                    conv: Conv2dConfig::new([width(level), width(level + 1)], [3, 3])
                        .with_stride([2, 2])
                        .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                        .init(device),
                });
            }
        }
        let mut up = Vec::new();
        let mut decoder = Vec::new();
        for level in (0..config.levels.saturating_sub(1)).rev() {
            up.push(ConvTranspose2dConfig::new([width(level + 1), width(level)], [2, 2]).with_stride([2, 2]).init(device));
            decoder.push(DoubleConv::new(2 * width(level), width(level), device));
        }
        UNet { encoder, down, up, decoder, head: conv(width(0), config.out_channels, 1, device) }
    }

    /// `x` must have sides divisible by 2^(levels-1).
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let mut skips = Vec::with_capacity(self.encoder.len());
        let mut x = x;
        for (level, block) in self.encoder.iter().enumerate() {
            x = block.forward(x);
            if let Some(down) = self.down.get(level) {
                skips.push(x.clone());
                x = down.forward(x);
            }
        }
        for (up, block) in self.up.iter().zip(&self.decoder) {
            let skip = skips.pop().expect("one skip per decoder level");
            x = block.forward(Tensor::cat(vec![apply_conv_transpose(up, x), skip], 1));
        }
        apply_conv(&self.head, x)
    }
}

/// Plain CNN at full resolution: a 1x1 input projection, 3x3 layers, then a 1x1 head.
#[derive(Module, Debug)]
pub struct PlainCnn {
    pub layers: Vec<ConvAct>,
    pub head: Conv2d,
}

impl PlainCnn {
    pub fn new(in_channels: usize, config: &CnnConfig, device: &Device) -> Self {
        let layers = (0..config.layers)
            .map(|i| if i == 0 { ConvAct::new(in_channels, config.width, 1, device) } else { ConvAct::new(config.width, config.width, 3, device) })
            .collect();
        let last = if config.layers == 0 { in_channels } else { config.width };
        PlainCnn { layers, head: conv(last, config.out_channels, 1, device) }
    }

    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let x = self.layers.iter().fold(x, |x, layer| layer.forward(x));
        apply_conv(&self.head, x)
    }
}

/// The rendering network R: a large-kernel layer (blur-like global effects), 3x3 layers, then
/// 1x1 layers and a 1x1 projection to RGB, so no late layer can smear shapes.
#[derive(Module, Debug)]
pub struct Renderer {
    pub large: ConvAct,
    pub layers: Vec<ConvAct>,
    pub pointwise: Vec<ConvAct>,
    pub head: Conv2d,
}

impl Renderer {
    pub fn new(in_channels: usize, config: &RendererConfig, out_channels: usize, device: &Device) -> Self {
        let w = config.width;
        Renderer {
            large: ConvAct::new(in_channels, w, config.large_kernel, device),
            layers: (0..config.layers).map(|_| ConvAct::new(w, w, 3, device)).collect(),
            pointwise: (0..config.pointwise_layers).map(|_| ConvAct::new(w, w, 1, device)).collect(),
            head: conv(w, out_channels, 1, device),
        }
    }

    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let x = self.large.forward(x);
        let x = self.layers.iter().fold(x, |x, layer| layer.forward(x));
        let x = self.pointwise.iter().fold(x, |x, layer| layer.forward(x));
        apply_conv(&self.head, x)
    }
}

/// The `pixelgen` baseline's per-pixel MLP (Diolatzis et al. 2022, "Active Exploration for
/// Neural Global Illumination of Variable Scenes"): 1x1 convolutions only, so every pixel is
/// computed from its own G-buffer texel; the encoded input joins the hidden state again at
/// layer `skip_at`, then a 1x1 projection to RGB.
#[derive(Module, Debug)]
pub struct PixelGenerator {
    pub layers: Vec<ConvAct>,
    pub head: Conv2d,
    #[module(skip)]
    pub skip_at: usize,
}

impl PixelGenerator {
    pub fn new(in_channels: usize, config: &PixelGeneratorConfig, out_channels: usize, device: &Device) -> Self {
        let w = config.width;
        let layers = (0..config.layers)
            .map(|i| match i {
                0 => ConvAct::new(in_channels, w, 1, device),
                i if i == config.skip_at => ConvAct::new(w + in_channels, w, 1, device),
                _ => ConvAct::new(w, w, 1, device),
            })
            .collect();
        PixelGenerator { layers, head: conv(w, out_channels, 1, device), skip_at: config.skip_at }
    }

    pub fn forward(&self, input: Tensor<4>) -> Tensor<4> {
        let mut x = input.clone();
        for (i, layer) in self.layers.iter().enumerate() {
            if i == self.skip_at {
                x = Tensor::cat(vec![x, input.clone()], 1);
            }
            x = layer.forward(x);
        }
        apply_conv(&self.head, x)
    }
}

/// NeRF positional encoding (Mildenhall et al. 2020, eq. 4), per channel:
/// x -> (x, sin(2^0 pi x), cos(2^0 pi x), ..., sin(2^(L-1) pi x), cos(2^(L-1) pi x)),
/// laid out as [x | sin/cos of frequency 0 for every channel | ... ].
///
/// The encoded buffers are data, never trained, so on the CPU backend the encoding is one
/// pass over host memory ([`positional_encoding_on_host`]): as tensor operations it was a
/// sine and a cosine per frequency plus a copy per part, a fifth of a GlassNet training step.
pub fn positional_encoding(x: Tensor<4>, frequencies: usize) -> Tensor<4> {
    if frequencies == 0 {
        return x;
    }
    if !x.is_require_grad() && x.dtype() == DType::F32 && is_cpu(x.device()) {
        let device = x.device();
        let [n, c, h, w] = x.dims();
        let values = x.into_data().convert::<f32>().try_into_vec::<f32>().expect("converted to f32");
        let encoded = positional_encoding_on_host(&values, [n, c, h * w], frequencies);
        return Tensor::from_data(TensorData::new(encoded, [n, c * (1 + 2 * frequencies), h, w]), &device);
    }
    let mut parts = Vec::with_capacity(1 + 2 * frequencies);
    parts.push(x.clone());
    for k in 0..frequencies {
        let scaled = x.clone().mul_scalar(std::f64::consts::PI * (1u64 << k) as f64);
        parts.push(scaled.clone().sin());
        parts.push(scaled.cos());
    }
    Tensor::cat(parts, 1)
}

/// [`positional_encoding`] of `values` laid out [batch, channels, pixels], in the same layout.
/// Only frequency 0 calls sine and cosine; each higher one follows by the double-angle
/// identities sin 2a = 2 sin a cos a, cos 2a = 1 - 2 sin^2 a, whose rounding error doubles
/// with each frequency as the error of the rounded argument 2^k pi x does.
pub fn positional_encoding_on_host(values: &[f32], [n, c, pixels]: [usize; 3], frequencies: usize) -> Vec<f32> {
    use rayon::prelude::*;
    assert_eq!(values.len(), n * c * pixels, "values are [batch, channels, pixels]");
    let parts = 1 + 2 * frequencies;
    let mut out = vec![0.0f32; n * c * parts * pixels];
    if pixels == 0 {
        return out;
    }
    // One image of the batch per task: its output parts are one contiguous block.
    out.par_chunks_mut(c * parts * pixels).zip(values.par_chunks(c * pixels)).for_each(|(out, image)| {
        for (channel, plane) in image.chunks(pixels).enumerate() {
            let at = |part: usize| (part * c + channel) * pixels;
            out[at(0)..at(0) + pixels].copy_from_slice(plane);
            for (i, &x) in plane.iter().enumerate() {
                let (mut sin, mut cos) = (x * std::f32::consts::PI).sin_cos();
                for k in 0..frequencies {
                    if k > 0 {
                        (sin, cos) = (2.0 * sin * cos, 1.0 - 2.0 * sin * sin);
                    }
                    out[at(1 + 2 * k) + i] = sin;
                    out[at(2 + 2 * k) + i] = cos;
                }
            }
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Distribution;

    fn values(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec::<f32>().unwrap()
    }

    /// The host encoding against sin and cos in f64 of the same f32 inputs, and against the
    /// tensor encoding (taken when the input needs gradients) for the layout: every part in
    /// its place. Each frequency may err by the rounding of its argument 2^k pi x (a few ulp
    /// of it), as the tensor encoding does.
    #[test]
    fn positional_encoding_on_the_host_matches_sine_and_cosine() {
        let device = Device::flex();
        device.seed(7);
        let frequencies = 6;
        let x = Tensor::<4>::random([2, 3, 5, 4], Distribution::Uniform(-10.0, 10.0), &device);
        let inputs = values(x.clone());
        let host = values(positional_encoding(x.clone(), frequencies));
        let trained = Device::flex().autodiff();
        let tensor_path = positional_encoding(Tensor::<4>::from_data(x.into_data(), &trained).require_grad(), frequencies);
        let tensor_path = values(tensor_path.inner());
        assert_eq!(host.len(), inputs.len() * (1 + 2 * frequencies));
        let (c, pixels) = (3, 20);
        for (b, image) in inputs.chunks(c * pixels).enumerate() {
            for (channel, plane) in image.chunks(pixels).enumerate() {
                for (i, &v) in plane.iter().enumerate() {
                    let at = |part: usize| b * c * (1 + 2 * frequencies) * pixels + (part * c + channel) * pixels + i;
                    assert_eq!(host[at(0)], v);
                    for k in 0..frequencies {
                        let argument = std::f64::consts::PI * (1u64 << k) as f64 * v as f64;
                        let bound = 1e-6 + 8.0 * f32::EPSILON as f64 * argument.abs();
                        for (part, exact) in [(1 + 2 * k, argument.sin()), (2 + 2 * k, argument.cos())] {
                            let (ours, theirs) = (host[at(part)] as f64, tensor_path[at(part)] as f64);
                            assert!((ours - exact).abs() <= bound, "x {v}, frequency {k}, part {part}: {ours} vs {exact}");
                            assert!((theirs - exact).abs() <= bound, "tensor path: x {v}, frequency {k}, part {part}: {theirs} vs {exact}");
                        }
                    }
                }
            }
        }
    }
}
