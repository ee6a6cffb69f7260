//! How GlassNet's convolutions are computed: burn's convolution kernels, or matrix products
//! where those are slow. The parameters are burn's `Conv2d` / `ConvTranspose2d` either way, so
//! the choice never changes a saved model, only the rounding of what it computes.
//!
//! burn takes a convolution's weight gradient as another convolution whose kernel is the whole
//! output gradient. On the CPU backend (flex) that made the backward pass of the wide 1x1 input
//! projections (156 channels into h, 157 into F) ~75x slower than their forward pass, and of the
//! 3x3 layers ~9x (`cargo run --release -p glassbake-bake --example train_step`). So a 1x1
//! convolution is always the matrix product over channels it is, and while a network trains on
//! flex a stride-1 k x k convolution with "same" padding is one product over the k*k shifted
//! copies of its input (im2col, the copies written by `flex_ops::shift_stack` in one pass); the
//! backward passes are then matrix products too. Without gradients flex's own k x k forward pass
//! is faster than im2col and is kept.
//!
//! GPU backends keep burn's kernels by default ([`GpuConvolutions::Kernels`]). burn's wgpu
//! backend has the same weight-gradient fallback (a direct convolution, no NHWC kernel for the
//! transposed convolution's input gradient), so [`GpuConvolutions::MatrixProducts`] computes
//! every convolution of a training network there as matrix products: im2col from a padded input
//! and k*k strided slices (the down-sampling convolutions too), and the U-Net's 2x2 stride-2
//! transposed convolutions as one product followed by a pixel shuffle. Which of the two is
//! faster depends on the GPU and the network's widths; `train --gpu-convolutions` chooses.

use std::sync::atomic::{AtomicBool, Ordering};

use burn::nn::conv::{Conv2d, ConvTranspose2d};
use burn::nn::PaddingConfig2d;
use burn::prelude::*;
use burn::tensor::ops::PadMode;
use burn::tensor::Slice;

use crate::device::is_cpu;
#[cfg(not(target_arch = "wasm32"))]
use crate::flex_ops::shift_stack;
use crate::precision::activation;

/// How a GPU backend computes the convolutions of a network that is being trained. Inference
/// and the CPU backend are not affected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GpuConvolutions {
    /// burn's convolution kernels, forward and backward.
    #[default]
    Kernels,
    /// Matrix products: im2col for the k x k convolutions, a product and a pixel shuffle for
    /// the transposed ones.
    MatrixProducts,
}

impl GpuConvolutions {
    pub const NAMES: [&'static str; 2] = ["kernels", "matmul"];

    pub fn parse(name: &str) -> Option<GpuConvolutions> {
        match name {
            "kernels" => Some(GpuConvolutions::Kernels),
            "matmul" => Some(GpuConvolutions::MatrixProducts),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            GpuConvolutions::Kernels => "kernels",
            GpuConvolutions::MatrixProducts => "matmul",
        }
    }
}

/// Parses a `--gpu-convolutions` value (for clap).
impl std::str::FromStr for GpuConvolutions {
    type Err = String;

    fn from_str(name: &str) -> Result<GpuConvolutions, String> {
        GpuConvolutions::parse(name).ok_or_else(|| format!("{name:?} is not {}", GpuConvolutions::NAMES.join(" or ")))
    }
}

static GPU_MATRIX_PRODUCTS: AtomicBool = AtomicBool::new(false);

/// Chooses how GPU backends compute training convolutions, for the whole process: like the
/// backend's own kernel choice it is a property of the run, not of a model.
pub fn set_gpu_convolutions(choice: GpuConvolutions) {
    GPU_MATRIX_PRODUCTS.store(choice == GpuConvolutions::MatrixProducts, Ordering::Relaxed);
}

pub fn gpu_convolutions() -> GpuConvolutions {
    if GPU_MATRIX_PRODUCTS.load(Ordering::Relaxed) {
        GpuConvolutions::MatrixProducts
    } else {
        GpuConvolutions::Kernels
    }
}

/// Which code computes a convolution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConvolutionPath {
    /// burn's `forward`.
    Burn,
    /// Matrix products, im2col written by flex's one-pass kernel (the CPU backend only).
    FlexMatrixProducts,
    /// Matrix products, im2col from tensor operations (any backend).
    TensorMatrixProducts,
}

/// The path `apply_conv` takes for `conv` under the process's [`GpuConvolutions`].
pub fn conv_path(conv: &Conv2d) -> ConvolutionPath {
    let [k, k2] = conv.kernel_size;
    let plain = k == k2 && conv.dilation == [1, 1] && conv.groups == 1;
    let same = k % 2 == 1 && (k == 1 || matches!(conv.padding, PaddingConfig2d::Same)) && conv.stride == [1, 1];
    if !plain {
        return ConvolutionPath::Burn;
    }
    let training = conv.weight.val().is_require_grad();
    let on_cpu = is_cpu(conv.weight.device());
    if on_cpu {
        if same && (k == 1 || training) {
            ConvolutionPath::FlexMatrixProducts
        } else {
            ConvolutionPath::Burn
        }
    } else if training && gpu_convolutions() == GpuConvolutions::MatrixProducts && padding(conv).is_some() {
        ConvolutionPath::TensorMatrixProducts
    } else if same && k == 1 {
        // A 1x1 convolution is a product over channels on every backend.
        ConvolutionPath::TensorMatrixProducts
    } else {
        ConvolutionPath::Burn
    }
}

/// `conv` applied to `x` on the path [`conv_path`] chooses. Its input and output are rounded to
/// f16 while `precision::set_f16_activations` is on.
pub fn apply_conv(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    activation(convolve(conv, activation(x), conv_path(conv)))
}

/// `conv` applied to `x` on `path` (tests compare the paths).
pub fn convolve(conv: &Conv2d, x: Tensor<4>, path: ConvolutionPath) -> Tensor<4> {
    let [k, _] = conv.kernel_size;
    let [n, _, h, w] = x.dims();
    let (columns, [ho, wo]) = match path {
        ConvolutionPath::Burn => return conv.forward(x),
        ConvolutionPath::FlexMatrixProducts if k == 1 => (x, [h, w]),
        ConvolutionPath::FlexMatrixProducts => (shift_stack(x, k), [h, w]),
        ConvolutionPath::TensorMatrixProducts => {
            let pad = padding(conv).expect("a symmetric padding");
            im2col(x, k, conv.stride, pad)
        }
    };
    let out = conv.weight.dims()[0];
    let kkc = columns.dims()[1];
    // [out, c, k, k] -> [out, k, k, c]: the column order of `columns` (shift-major).
    let weight = conv.weight.val().permute([0, 2, 3, 1]).reshape([1, out, kkc]).expand([n, out, kkc]);
    let mut y = weight.matmul(columns.reshape([n, kkc, ho * wo]));
    if let Some(bias) = &conv.bias {
        y = y + bias.val().reshape([1, out, 1]);
    }
    y.reshape([n, out, ho, wo])
}

/// The symmetric padding (rows, columns) of `conv`, if it has one: "same" for odd kernels, or
/// explicit equal before and after.
fn padding(conv: &Conv2d) -> Option<[usize; 2]> {
    let [k, _] = conv.kernel_size;
    match conv.padding {
        PaddingConfig2d::Valid => Some([0, 0]),
        PaddingConfig2d::Same if k % 2 == 1 && conv.stride == [1, 1] => Some([k / 2, k / 2]),
        PaddingConfig2d::Explicit(top, left, bottom, right) if top == bottom && left == right => Some([top, left]),
        _ => None,
    }
}

/// The k*k (strided) shifted copies of `x` ([N, C, H, W]) a k x k convolution reads, from a
/// padded copy and k*k slices: [N, k*k*C, H', W'], shift-major (block dy * k + dx), and the
/// output's size [H', W'].
fn im2col(x: Tensor<4>, k: usize, stride: [usize; 2], [pad_y, pad_x]: [usize; 2]) -> (Tensor<4>, [usize; 2]) {
    let [_, _, h, w] = x.dims();
    let [sy, sx] = stride;
    let (ho, wo) = ((h + 2 * pad_y - k) / sy + 1, (w + 2 * pad_x - k) / sx + 1);
    if k == 1 && stride == [1, 1] && pad_y == 0 && pad_x == 0 {
        return (x, [h, w]);
    }
    let padded = if pad_y + pad_x > 0 { x.pad([(pad_y, pad_y), (pad_x, pad_x)], PadMode::Constant(0.0)) } else { x };
    let mut shifts = Vec::with_capacity(k * k);
    for dy in 0..k {
        for dx in 0..k {
            let (y_end, x_end) = (dy + sy * (ho - 1) + 1, dx + sx * (wo - 1) + 1);
            let rows = Slice::new(dy as isize, Some(y_end as isize), sy as isize);
            let columns = Slice::new(dx as isize, Some(x_end as isize), sx as isize);
            shifts.push(padded.clone().slice([Slice::full(), Slice::full(), rows, columns]));
        }
    }
    (Tensor::cat(shifts, 1), [ho, wo])
}

/// `up` applied to `x`: burn's kernel, or, for a network training on a GPU under
/// [`GpuConvolutions::MatrixProducts`], the 2x2 stride-2 transposed convolution as the product
/// it is (each input pixel spreads into its own 2x2 block) and a pixel shuffle. Its output is
/// rounded to f16 while `precision::set_f16_activations` is on.
pub fn apply_conv_transpose(up: &ConvTranspose2d, x: Tensor<4>) -> Tensor<4> {
    let as_products = up.weight.val().is_require_grad() && !is_cpu(up.weight.device()) && gpu_convolutions() == GpuConvolutions::MatrixProducts;
    activation(if as_products && is_block_upsampling(up) { conv_transpose_as_product(up, x) } else { up.forward(x) })
}

/// A transposed convolution whose kernel equals its stride, without padding: every output
/// pixel comes from one input pixel.
fn is_block_upsampling(up: &ConvTranspose2d) -> bool {
    up.kernel_size == up.stride && up.padding == [0, 0] && up.padding_out == [0, 0] && up.dilation == [1, 1] && up.groups == 1
}

/// y[n, o, s*i + a, s*j + b] = sum_c x[n, c, i, j] W[c, o, a, b] + bias[o].
pub fn conv_transpose_as_product(up: &ConvTranspose2d, x: Tensor<4>) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    let [_, out, ky, kx] = up.weight.dims();
    // [c, out, ky, kx] -> [out * ky * kx, c].
    let weight = up.weight.val().permute([1, 2, 3, 0]).reshape([1, out * ky * kx, c]).expand([n, out * ky * kx, c]);
    let blocks = weight.matmul(x.reshape([n, c, h * w])).reshape([n, out, ky, kx, h, w]);
    let mut y = blocks.permute([0, 1, 4, 2, 5, 3]).reshape([n, out, h * ky, w * kx]);
    if let Some(bias) = &up.bias {
        y = y + bias.val().reshape([1, out, 1, 1]);
    }
    y
}

// A wasm32 build has no CPU backend, so `convolve` never takes the flex path there.
#[cfg(target_arch = "wasm32")]
fn shift_stack(_: Tensor<4>, _: usize) -> Tensor<4> {
    unreachable!("flex's im2col runs only on the CPU backend")
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::conv::{Conv2dConfig, ConvTranspose2dConfig};
    use burn::tensor::Distribution;

    fn values(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec::<f32>().unwrap()
    }

    fn close(a: Vec<f32>, b: Vec<f32>, what: &str) {
        assert_eq!(a.len(), b.len(), "{what}: lengths");
        for (i, (a, b)) in a.iter().zip(&b).enumerate() {
            assert!((a - b).abs() <= 1e-5 * (1.0 + b.abs()), "{what} element {i}: {a} vs {b}");
        }
    }

    /// `ours` and `reference`, both applied to `x` on `device`, give the same output and the
    /// same gradients for the input and every parameter.
    fn same_as_reference<M: burn::module::Module>(
        what: &str,
        module: &M,
        x: Tensor<4>,
        ours: impl Fn(Tensor<4>) -> Tensor<4>,
        reference: impl Fn(Tensor<4>) -> Tensor<4>,
    ) {
        let x = x.require_grad();
        let (a, b) = (ours(x.clone()), reference(x.clone()));
        assert_eq!(a.dims(), b.dims(), "{what}: output shape");
        close(values(a.clone().inner()), values(b.clone().inner()), &format!("{what} output"));
        let r = Tensor::<4>::random(b.dims(), Distribution::Uniform(-1.0, 1.0), &x.device());
        let (grads_a, grads_b) = ((a * r.clone()).sum().backward(), (b * r).sum().backward());
        close(values(x.grad(&grads_a).unwrap()), values(x.grad(&grads_b).unwrap()), &format!("{what} input gradient"));
        struct Params<'a>(&'a burn::tensor::Gradients, &'a burn::tensor::Gradients, &'a str);
        impl burn::module::ModuleVisitor for Params<'_> {
            fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
                let (a, b) = (param.val().grad(self.0).unwrap(), param.val().grad(self.1).unwrap());
                close(
                    a.into_data().try_to_vec::<f32>().unwrap(),
                    b.into_data().try_to_vec::<f32>().unwrap(),
                    &format!("{} parameter gradient {:?}", self.2, param.shape()),
                );
            }
        }
        module.visit(&mut Params(&grads_a, &grads_b, what));
    }

    /// Every matrix-product path against burn's own convolution on `device`: the stride-1
    /// "same" convolutions (1x1, 3x3, 5x5), the U-Net's stride-2 3x3 down-sampling and its 2x2
    /// stride-2 transposed convolution, each on odd and even sides.
    fn matrix_products_match_burns_kernels(device: &Device, paths: &[ConvolutionPath]) {
        device.seed(5);
        let input = |c: usize, h: usize, w: usize| Tensor::<4>::random([3, c, h, w], Distribution::Uniform(-1.0, 1.0), device);
        for &path in paths {
            for kernel in [1, 3, 5] {
                let conv = Conv2dConfig::new([7, 5], [kernel, kernel]).with_padding(PaddingConfig2d::Same).init(device);
                same_as_reference(&format!("{path:?} {kernel}x{kernel}"), &conv, input(7, 6, 9), |x| convolve(&conv, x, path), |x| conv.forward(x));
            }
        }
        let down = Conv2dConfig::new([4, 6], [3, 3]).with_stride([2, 2]).with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1)).init(device);
        for (h, w) in [(8, 6), (7, 9)] {
            let path = ConvolutionPath::TensorMatrixProducts;
            same_as_reference(&format!("stride-2 3x3 on {h}x{w}"), &down, input(4, h, w), |x| convolve(&down, x, path), |x| down.forward(x));
        }
        let up = ConvTranspose2dConfig::new([6, 4], [2, 2]).with_stride([2, 2]).init(device);
        same_as_reference("2x2 stride-2 transposed", &up, input(6, 3, 5), |x| conv_transpose_as_product(&up, x), |x| up.forward(x));
    }

    #[test]
    fn convolutions_as_matrix_products_match_burns_on_the_cpu() {
        let paths = [ConvolutionPath::FlexMatrixProducts, ConvolutionPath::TensorMatrixProducts];
        matrix_products_match_burns_kernels(&Device::flex().autodiff(), &paths);
    }

    /// The GPU path on wgpu (lavapipe in CI) against burn's wgpu kernels.
    #[test]
    fn convolutions_as_matrix_products_match_burns_on_wgpu() {
        let instance = burn::tensor::wgpu::wgpu::Instance::default();
        if pollster::block_on(instance.request_adapter(&Default::default())).is_err() {
            assert!(std::env::var("GLASSBAKE_TEST_RESOURCES").as_deref() != Ok("required"), "no wgpu adapter, and GLASSBAKE_TEST_RESOURCES=required");
            eprintln!("SKIPPED: no wgpu adapter on this machine");
            return;
        }
        matrix_products_match_burns_kernels(&Device::wgpu(Default::default()).autodiff(), &[ConvolutionPath::TensorMatrixProducts]);
    }

    /// Which layers take which path: the choice is what makes the paths' speed matter.
    #[test]
    fn the_cpu_trains_on_flex_products_and_keeps_burns_kernels_for_inference() {
        let device = Device::flex();
        let conv3 = Conv2dConfig::new([3, 4], [3, 3]).with_padding(PaddingConfig2d::Same).init(&device);
        let conv1 = Conv2dConfig::new([3, 4], [1, 1]).init(&device);
        let down = Conv2dConfig::new([3, 4], [3, 3]).with_stride([2, 2]).with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1)).init(&device);
        assert_eq!(conv_path(&conv3), ConvolutionPath::Burn);
        assert_eq!(conv_path(&conv1), ConvolutionPath::FlexMatrixProducts);
        assert_eq!(conv_path(&down), ConvolutionPath::Burn);
        let trained = Device::flex().autodiff();
        let conv3 = Conv2dConfig::new([3, 4], [3, 3]).with_padding(PaddingConfig2d::Same).init(&trained);
        assert_eq!(conv_path(&conv3), ConvolutionPath::FlexMatrixProducts);
    }

    /// Strided convolutions keep burn's path on the CPU.
    #[test]
    fn strided_convolutions_are_burns_on_the_cpu() {
        let device = Device::flex();
        device.seed(6);
        let conv = Conv2dConfig::new([3, 4], [3, 3]).with_stride([2, 2]).with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1)).init(&device);
        let x = Tensor::<4>::random([1, 3, 5, 5], Distribution::Uniform(-1.0, 1.0), &device);
        assert_eq!(values(apply_conv(&conv, x.clone())), values(conv.forward(x)));
    }

    #[test]
    fn gpu_convolution_names_parse_back() {
        for name in GpuConvolutions::NAMES {
            assert_eq!(GpuConvolutions::parse(name).unwrap().name(), name);
        }
        assert_eq!(GpuConvolutions::parse("im2col"), None);
    }
}
