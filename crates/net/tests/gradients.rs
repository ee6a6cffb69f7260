//! The backward pass of every layer type GlassNet uses, against central finite differences,
//! on the CPU backend in f64 (its own test binary: the device's float type is process-wide).

use burn::prelude::*;
use burn::tensor::{Distribution, FloatDType, TensorData};
use glassbake_net::blocks::{positional_encoding, ConvAct, PlainCnn, Renderer, UNet};
use glassbake_net::burn;
use glassbake_net::config::{CnnConfig, RendererConfig, UNetConfig};
use glassbake_net::loss::training_loss;
use glassbake_net::super_sampler::upsample_nearest2;

/// Central-difference check of d(sum(r * f(x)))/dx at a few elements of `x`.
fn check_input_gradient(name: &str, x: Tensor<4>, f: impl Fn(Tensor<4>) -> Tensor<4>) {
    let device = x.device();
    let x = x.require_grad();
    let y = f(x.clone());
    let r = Tensor::<4>::random(y.dims(), Distribution::Uniform(-1.0, 1.0), &device);
    let objective = |x: Tensor<4>| -> f64 { (f(x) * r.clone()).sum().into_scalar::<f64>() };
    let grads = (y * r.clone()).sum().backward();
    let analytic = x.grad(&grads).expect("gradient reaches the input").into_data().try_to_vec::<f64>().unwrap();
    let base = x.clone().detach().into_data().try_to_vec::<f64>().unwrap();
    let shape = x.dims();
    let eps = 1e-5f64;
    let step = (base.len() / 7).max(1);
    for i in (0..base.len()).step_by(step) {
        let at = |delta: f64| {
            let mut v = base.clone();
            v[i] += delta;
            objective(Tensor::from_data(TensorData::new(v, shape), &device))
        };
        let numeric = (at(eps) - at(-eps)) / (2.0 * eps);
        let a = analytic[i];
        assert!((numeric - a).abs() <= 1e-5 * numeric.abs().max(a.abs()) + 1e-7, "{name}: element {i}: analytic {a}, numeric {numeric}");
    }
}

#[test]
fn backward_passes_of_every_layer_type_match_finite_differences() {
    let mut device = Device::flex();
    // f64 so central differences are accurate to ~1e-9 and the check can be tight.
    device.configure(FloatDType::F64).unwrap();
    let device = device.autodiff();
    device.seed(11);
    let x = |c: usize, s: usize| Tensor::<4>::random([1, c, s, s], Distribution::Uniform(-1.0, 1.0), &device);
    let conv3 = ConvAct::new(3, 4, 3, &device);
    check_input_gradient("3x3 convolution + leaky ReLU", x(3, 8), |t| conv3.forward(t));
    let conv5 = ConvAct::new(3, 2, 5, &device);
    check_input_gradient("5x5 convolution", x(3, 8), |t| conv5.forward(t));
    let unet = UNet::new(2, &UNetConfig { base_width: 3, levels: 2, out_channels: 2 }, &device);
    check_input_gradient("U-Net (strided and transposed convolutions, skip concat)", x(2, 8), |t| unet.forward(t));
    let cnn = PlainCnn::new(2, &CnnConfig { width: 3, layers: 2, out_channels: 2 }, &device);
    check_input_gradient("plain CNN with 1x1 head", x(2, 6), |t| cnn.forward(t));
    let renderer = Renderer::new(2, &RendererConfig { width: 3, large_kernel: 5, layers: 1, pointwise_layers: 1 }, 3, &device);
    check_input_gradient("renderer", x(2, 8), |t| renderer.forward(t));
    check_input_gradient("positional encoding", x(2, 4), |t| positional_encoding(t, 3));
    check_input_gradient("nearest x2 up-sampling", x(2, 4), upsample_nearest2);
    let target = Tensor::<4>::random([1, 3, 12, 12], Distribution::Uniform(0.0, 1.0), &device);
    check_input_gradient("L1 + SSIM loss", Tensor::random([1, 3, 12, 12], Distribution::Uniform(0.0, 1.0), &device), |t| {
        training_loss(t, target.clone(), 1.0).reshape([1, 1, 1, 1])
    });
}
