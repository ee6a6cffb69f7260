//! The layer types GlassNet is built from: a 3x3 convolution + activation, the U-Net of F and
//! B, the plain CNN of h, the rendering network R and NeRF positional encoding.

use burn::nn::conv::{Conv2d, Conv2dConfig, ConvTranspose2d, ConvTranspose2dConfig};
use burn::nn::PaddingConfig2d;
use burn::prelude::*;
use burn::tensor::{DType, TensorData};

use crate::config::{CnnConfig, PixelGeneratorConfig, RendererConfig, UNetConfig};
use crate::device::is_cpu;
#[cfg(not(target_arch = "wasm32"))]
use crate::flex_ops::{leaky_relu, shift_stack};
use crate::precision::activation;
#[cfg(target_arch = "wasm32")]
use burn::tensor::activation::leaky_relu;

/// Leaky slope of every hidden activation: small nets lose too many units to plain ReLU.
const LEAK: f64 = 0.1;

fn conv(in_channels: usize, out_channels: usize, kernel: usize, device: &Device) -> Conv2d {
    Conv2dConfig::new([in_channels, out_channels], [kernel, kernel]).with_padding(PaddingConfig2d::Same).init(device)
}

/// `conv` applied to `x`, as matrix products where burn's flex backend is slow. burn takes a
/// convolution's weight gradient as another convolution whose kernel is the whole image, which
/// made the backward pass of the wide 1x1 input projections (156 channels into h, 157 into F)
/// ~75x slower than their forward pass, and of the 3x3 layers ~9x
/// (`cargo run --release -p glassbake-bake --example train_step`). So a 1x1 convolution is
/// computed as the matrix product over channels it is, and a stride-1 k x k convolution with
/// "same" padding, when training on flex, as one product over the k*k shifted copies of the
/// input (im2col); the backward passes are then matrix products too. Without gradients flex's
/// own k x k forward pass is faster than im2col and is kept, as are strided convolutions; GPU
/// backends keep their convolution kernels, where the k*k copies would only cost memory. The
/// parameters are the same `Conv2d` either way, so saved models are unchanged. Its input and
/// output are rounded to f16 while `precision::set_f16_activations` is on.
pub fn apply_conv(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    activation(convolve(conv, activation(x)))
}

fn convolve(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let [k, k2] = conv.kernel_size;
    let same = k == 1 || matches!(conv.padding, PaddingConfig2d::Same);
    let training_on_flex = conv.weight.val().is_require_grad() && is_cpu(conv.weight.device());
    if k != k2 || k % 2 == 0 || !same || (k > 1 && !training_on_flex) || conv.stride != [1, 1] || conv.dilation != [1, 1] || conv.groups != 1 {
        return conv.forward(x);
    }
    let [n, c, h, w] = x.dims();
    let out = conv.weight.dims()[0];
    let columns = if k == 1 { x } else { shift_stack(x, k) };
    // [out, c, k, k] -> [out, k, k, c]: the column order of `columns` (shift-major).
    let weight = conv.weight.val().permute([0, 2, 3, 1]).reshape([1, out, k * k * c]).expand([n, out, k * k * c]);
    let mut y = weight.matmul(columns.reshape([n, k * k * c, h * w]));
    if let Some(bias) = &conv.bias {
        y = y + bias.val().reshape([1, out, 1]);
    }
    y.reshape([n, out, h, w])
}

// A wasm32 build has no CPU backend, so `convolve` never takes the im2col path there.
#[cfg(target_arch = "wasm32")]
fn shift_stack(_: Tensor<4>, _: usize) -> Tensor<4> {
    unreachable!("im2col runs only when training on the CPU backend")
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
            x = block.forward(Tensor::cat(vec![activation(up.forward(x)), skip], 1));
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

    /// The matrix-product paths (1x1, and 3x3 / 5x5 by im2col) against burn's own convolution:
    /// same output, same gradients for the input, the weights and the bias.
    #[test]
    fn convolutions_as_matrix_products_match_burns_convolution() {
        let device = Device::flex().autodiff();
        device.seed(5);
        for kernel in [1, 3, 5] {
            let conv = conv(7, 5, kernel, &device);
            let x = Tensor::<4>::random([3, 7, 6, 9], Distribution::Uniform(-1.0, 1.0), &device).require_grad();
            let r = Tensor::<4>::random([3, 5, 6, 9], Distribution::Uniform(-1.0, 1.0), &device);
            let ours = apply_conv(&conv, x.clone());
            let reference = conv.forward(x.clone());
            assert_eq!(ours.dims(), reference.dims());
            let close = |a: Vec<f32>, b: Vec<f32>, what: &str| {
                assert_eq!(a.len(), b.len());
                for (i, (a, b)) in a.iter().zip(&b).enumerate() {
                    assert!((a - b).abs() <= 1e-5 * (1.0 + b.abs()), "{kernel}x{kernel} {what} element {i}: {a} vs {b}");
                }
            };
            close(values(ours.clone().inner()), values(reference.clone().inner()), "output");
            let grads_ours = (ours * r.clone()).sum().backward();
            let grads_reference = (reference * r).sum().backward();
            close(values(x.grad(&grads_ours).unwrap()), values(x.grad(&grads_reference).unwrap()), "input gradient");
            close(values(conv.weight.grad(&grads_ours).unwrap()), values(conv.weight.grad(&grads_reference).unwrap()), "weight gradient");
            let bias = conv.bias.as_ref().unwrap();
            let (b_ours, b_ref) = (bias.grad(&grads_ours).unwrap(), bias.grad(&grads_reference).unwrap());
            close(b_ours.into_data().try_to_vec::<f32>().unwrap(), b_ref.into_data().try_to_vec::<f32>().unwrap(), "bias gradient");
        }
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

    /// Strided convolutions keep burn's path.
    #[test]
    fn strided_convolutions_are_burns() {
        let device = Device::flex();
        device.seed(6);
        let conv = Conv2dConfig::new([3, 4], [3, 3]).with_stride([2, 2]).with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1)).init(&device);
        let x = Tensor::<4>::random([1, 3, 5, 5], Distribution::Uniform(-1.0, 1.0), &device);
        assert_eq!(values(apply_conv(&conv, x.clone())), values(conv.forward(x)));
    }
}
