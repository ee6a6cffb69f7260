//! The training loss (paper 3.5): L1 + w (1 - SSIM) on tone-mapped values.
//!
//! The network predicts the tone-mapped image directly: the target is the path-traced radiance
//! through glassbake's one tone map, clamp to [0, 1] (`glassbake_core::color`), and the
//! prediction is compared unclamped so gradients never vanish. SSIM is the standard one (Wang
//! et al. 2004): an 11x11 Gaussian window of sigma 1.5, C1 = (0.01 L)^2, C2 = (0.03 L)^2 with
//! dynamic range L = 1, over the 'valid' window positions, averaged over channels.

use burn::prelude::*;
use burn::tensor::module::conv2d;
use burn::tensor::ops::ConvOptions;
use burn::tensor::TensorData;

pub const SSIM_WINDOW: usize = 11;
pub const SSIM_SIGMA: f64 = 1.5;
const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;

/// The normalised 1D Gaussian of the SSIM window.
pub fn gaussian_1d() -> Vec<f64> {
    let half = (SSIM_WINDOW / 2) as f64;
    let raw: Vec<f64> = (0..SSIM_WINDOW).map(|i| (-((i as f64 - half).powi(2)) / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()).collect();
    let total: f64 = raw.iter().sum();
    raw.into_iter().map(|v| v / total).collect()
}

/// Depthwise Gaussian filter weights for `channels` channels: [channels, 1, 11, 11].
fn window(channels: usize, device: &Device) -> Tensor<4> {
    let g = gaussian_1d();
    let mut w = Vec::with_capacity(channels * SSIM_WINDOW * SSIM_WINDOW);
    for _ in 0..channels {
        for a in &g {
            for b in &g {
                w.push((a * b) as f32);
            }
        }
    }
    Tensor::from_data(TensorData::new(w, [channels, 1, SSIM_WINDOW, SSIM_WINDOW]), device)
}

/// Per-window-position SSIM map of `x` against `y` ([N, C, H, W], both in [0, 1] space),
/// [N, C, H-10, W-10].
pub fn ssim_map(x: Tensor<4>, y: Tensor<4>) -> Tensor<4> {
    let [_, channels, h, w] = x.dims();
    assert!(h >= SSIM_WINDOW && w >= SSIM_WINDOW, "SSIM needs images of at least {SSIM_WINDOW}x{SSIM_WINDOW}, got {w}x{h}");
    let window = window(channels, &x.device());
    let options = ConvOptions::new([1, 1], [0, 0], [1, 1], channels);
    let blur = |t: Tensor<4>| conv2d(t, window.clone(), None, options.clone());
    let mu_x = blur(x.clone());
    let mu_y = blur(y.clone());
    let sigma_xx = blur(x.clone() * x.clone()) - mu_x.clone() * mu_x.clone();
    let sigma_yy = blur(y.clone() * y.clone()) - mu_y.clone() * mu_y.clone();
    let sigma_xy = blur(x * y) - mu_x.clone() * mu_y.clone();
    let numerator = (mu_x.clone() * mu_y.clone()).mul_scalar(2.0).add_scalar(C1) * sigma_xy.mul_scalar(2.0).add_scalar(C2);
    let denominator = (mu_x.clone() * mu_x + mu_y.clone() * mu_y).add_scalar(C1) * (sigma_xx + sigma_yy).add_scalar(C2);
    numerator / denominator
}

/// Mean SSIM over the batch.
pub fn ssim(x: Tensor<4>, y: Tensor<4>) -> Tensor<1> {
    ssim_map(x, y).mean()
}

/// The clamp tone map on a tensor (glassbake_core::color::tonemap_clamp).
pub fn tonemap(radiance: Tensor<4>) -> Tensor<4> {
    radiance.clamp(0.0, 1.0)
}

/// L1 + `ssim_weight` (1 - SSIM) of a prediction against tone-mapped ground truth.
pub fn training_loss(prediction: Tensor<4>, target: Tensor<4>, ssim_weight: f64) -> Tensor<1> {
    let l1 = (prediction.clone() - target.clone()).abs().mean();
    if ssim_weight == 0.0 {
        return l1;
    }
    l1 + ssim(prediction, target).neg().add_scalar(1.0).mul_scalar(ssim_weight)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Distribution;

    fn scalar(t: Tensor<1>) -> f64 {
        t.into_scalar::<f32>() as f64
    }

    #[test]
    fn ssim_of_an_image_with_itself_is_one() {
        let device = Device::flex();
        device.seed(1);
        let x = Tensor::<4>::random([2, 3, 16, 16], Distribution::Uniform(0.0, 1.0), &device);
        assert!((scalar(ssim(x.clone(), x)) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn ssim_of_constant_images_matches_the_closed_form() {
        // Constant images: every sigma is 0, so SSIM = (2ab + C1) / (a^2 + b^2 + C1).
        let device = Device::flex();
        let (a, b) = (0.3f64, 0.6f64);
        let x = Tensor::<4>::full([1, 1, 12, 12], a, &device);
        let y = Tensor::<4>::full([1, 1, 12, 12], b, &device);
        let expected = (2.0 * a * b + C1) / (a * a + b * b + C1);
        let got = scalar(ssim(x, y));
        // f32: the covariances are differences of ~0.1-sized moments (error ~1e-8) divided by
        // C2 = 9e-4, so ~1e-5 relative error is inherent in the formula.
        assert!((got - expected).abs() < 1e-4, "got {got}, expected {expected}");
    }

    #[test]
    fn ssim_of_a_structured_pair_matches_a_direct_evaluation() {
        // x = ramp, y = 0.5 x + 0.1 on one 11x11 window: the filtered moments reduce to weighted
        // moments under the Gaussian weights, evaluated here directly in f64.
        let device = Device::flex();
        let g = gaussian_1d();
        let n = SSIM_WINDOW;
        let xs: Vec<f64> = (0..n * n).map(|i| ((i % n) as f64 * 0.07 + (i / n) as f64 * 0.02) % 1.0).collect();
        let ys: Vec<f64> = xs.iter().map(|v| 0.5 * v + 0.1).collect();
        let weight = |i: usize| g[i / n] * g[i % n];
        let mean = |v: &[f64]| (0..n * n).map(|i| weight(i) * v[i]).sum::<f64>();
        let (mx, my) = (mean(&xs), mean(&ys));
        let vx = (0..n * n).map(|i| weight(i) * xs[i] * xs[i]).sum::<f64>() - mx * mx;
        let vy = (0..n * n).map(|i| weight(i) * ys[i] * ys[i]).sum::<f64>() - my * my;
        let cxy = (0..n * n).map(|i| weight(i) * xs[i] * ys[i]).sum::<f64>() - mx * my;
        let expected = (2.0 * mx * my + C1) * (2.0 * cxy + C2) / ((mx * mx + my * my + C1) * (vx + vy + C2));
        let to_tensor = |v: &[f64]| Tensor::<4>::from_data(TensorData::new(v.iter().map(|&x| x as f32).collect::<Vec<_>>(), [1, 1, n, n]), &device);
        let got = scalar(ssim(to_tensor(&xs), to_tensor(&ys)));
        assert!((got - expected).abs() < 1e-4, "got {got}, expected {expected}");
        assert!(expected < 0.99, "the pair must be dissimilar enough to test anything ({expected})");
    }

    #[test]
    fn l1_only_loss_is_the_mean_absolute_error() {
        let device = Device::flex();
        let p = Tensor::<4>::from_data(TensorData::new(vec![0.0f32, 0.5, 1.0, 2.0], [1, 1, 2, 2]), &device);
        let t = Tensor::<4>::from_data(TensorData::new(vec![0.25f32, 0.5, 0.0, 1.0], [1, 1, 2, 2]), &device);
        assert!((scalar(training_loss(p, t, 0.0)) - 0.5625).abs() < 1e-7);
    }
}
