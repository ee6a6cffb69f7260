//! The SSIM that training optimises (burn, `glassbake_net::loss`) and the SSIM that evaluation
//! reports (f64 on the CPU, `glassbake_eval::metrics`) are two implementations of one
//! formula: on the same pairs of images they must agree to f32 precision (1e-5; they agreed to
//! 1e-6 when this was written, and a C2 of 0.035 instead of 0.03 moves them 2e-3 apart).

use glassbake_eval::metrics;
use glassbake_eval::rgb::RgbImage;
use glassbake_net::burn;

use burn::prelude::*;
use burn::tensor::TensorData;

/// A 26 x 19 image with structure at several scales, values in [0, 1].
fn image(seed: u32) -> RgbImage {
    let (width, height) = (26, 19);
    let s = seed as f32;
    let pixels = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f32, (i / width) as f32);
            std::array::from_fn(|c| {
                let c = c as f32;
                let wave = 0.5 + 0.3 * (0.37 * x * (1.0 + 0.1 * s) + 0.21 * y + c).sin() + 0.15 * (1.7 * y - 0.9 * x + s * c).cos();
                let hash = ((i as u32).wrapping_mul(2_654_435_761).wrapping_add(seed.wrapping_mul(97) + c as u32 * 13) >> 8) as f32 / (1u32 << 24) as f32;
                (wave + 0.1 * (hash - 0.5)).clamp(0.0, 1.0)
            })
        })
        .collect();
    RgbImage { width, height, pixels }
}

fn to_tensor(image: &RgbImage, device: &Device) -> Tensor<4> {
    let plane = image.width * image.height;
    let mut planar = vec![0.0f32; 3 * plane];
    for (i, p) in image.pixels.iter().enumerate() {
        for c in 0..3 {
            planar[c * plane + i] = p[c];
        }
    }
    Tensor::from_data(TensorData::new(planar, [1, 3, image.height, image.width]), device)
}

#[test]
fn training_ssim_equals_evaluation_ssim() {
    let device = Device::flex();
    let pairs = [
        (image(1), image(1)),
        (image(1), image(2)),
        (image(3), image(4)),
        (image(5), RgbImage { pixels: image(5).pixels.iter().map(|p| p.map(|v| 1.0 - v)).collect(), ..image(5) }),
    ];
    for (k, (a, b)) in pairs.iter().enumerate() {
        let evaluated = metrics::ssim(a, b).unwrap();
        let trained = glassbake_net::loss::ssim(to_tensor(a, &device), to_tensor(b, &device)).into_scalar::<f32>() as f64;
        eprintln!("pair {k}: evaluation {evaluated:.6}, training {trained:.6}");
        assert!((evaluated - trained).abs() < 1e-5, "pair {k}: evaluation SSIM {evaluated} vs training SSIM {trained}");
    }
    // The pairs span the range, so agreement is not agreement on one value.
    let values: Vec<f64> = pairs.iter().map(|(a, b)| metrics::ssim(a, b).unwrap()).collect();
    assert!(values[0] > 0.9999 && values[3] < 0.0, "{values:?}");
}
