//! LPIPS: the loading path on a tiny weights file the test writes, checked against a
//! deliberately naive re-implementation of the LPIPS formula.
#![allow(clippy::needless_range_loop)] // the reference is written index by index on purpose

use glassbake_eval::lpips::{Lpips, CONV_PADDING, CONV_STRIDE, INPUT_SCALE, INPUT_SHIFT};
use glassbake_eval::RgbImage;
use safetensors::tensor::TensorView;
use safetensors::Dtype;

/// A tiny AlexNet-shaped network: AlexNet's kernels (11, 5, 3, 3, 3), few channels.
const CHANNELS: [usize; 5] = [4, 5, 6, 4, 3];
const KERNELS: [usize; 5] = [11, 5, 3, 3, 3];
const INDEX: [usize; 5] = [0, 3, 6, 8, 10];

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

fn tensors(slice_names: bool) -> Vec<(String, Vec<usize>, Vec<f32>)> {
    let mut rng = Lcg(7);
    let mut out = Vec::new();
    let mut input = 3;
    for s in 0..5 {
        let (c, k) = (CHANNELS[s], KERNELS[s]);
        let scale = 1.0 / ((input * k * k) as f32).sqrt();
        let prefix = if slice_names { format!("net.slice{}.{}", s + 1, INDEX[s]) } else { format!("features.{}", INDEX[s]) };
        out.push((format!("{prefix}.weight"), vec![c, input, k, k], (0..c * input * k * k).map(|_| rng.next() * scale).collect()));
        out.push((format!("{prefix}.bias"), vec![c], (0..c).map(|_| rng.next() * 0.1).collect()));
        out.push((format!("lin{s}.model.1.weight"), vec![1, c, 1, 1], (0..c).map(|_| rng.next().abs()).collect()));
        input = c;
    }
    out
}

fn write(path: &std::path::Path, tensors: &[(String, Vec<usize>, Vec<f32>)]) {
    let bytes: Vec<(String, Vec<usize>, Vec<u8>)> =
        tensors.iter().map(|(n, s, d)| (n.clone(), s.clone(), d.iter().flat_map(|v| v.to_le_bytes()).collect())).collect();
    let views: Vec<(String, TensorView)> = bytes.iter().map(|(n, s, b)| (n.clone(), TensorView::new(Dtype::F32, s.clone(), b).unwrap())).collect();
    std::fs::write(path, safetensors::serialize(views, None).unwrap()).unwrap();
}

/// Textbook direct convolution, one output value at a time.
fn reference_conv(input: &[Vec<Vec<f64>>], weight: &[f32], bias: &[f32], out_c: usize, k: usize, stride: usize, pad: usize) -> Vec<Vec<Vec<f64>>> {
    let (in_c, h, w) = (input.len(), input[0].len(), input[0][0].len());
    let (oh, ow) = ((h + 2 * pad - k) / stride + 1, (w + 2 * pad - k) / stride + 1);
    let mut out = vec![vec![vec![0.0; ow]; oh]; out_c];
    for o in 0..out_c {
        for y in 0..oh {
            for x in 0..ow {
                let mut sum = bias[o] as f64;
                for i in 0..in_c {
                    for ky in 0..k {
                        for kx in 0..k {
                            let (iy, ix) = ((y * stride + ky) as i64 - pad as i64, (x * stride + kx) as i64 - pad as i64);
                            if iy >= 0 && ix >= 0 && (iy as usize) < h && (ix as usize) < w {
                                sum += weight[((o * in_c + i) * k + ky) * k + kx] as f64 * input[i][iy as usize][ix as usize];
                            }
                        }
                    }
                }
                out[o][y][x] = sum.max(0.0);
            }
        }
    }
    out
}

fn reference_pool(input: &[Vec<Vec<f64>>]) -> Vec<Vec<Vec<f64>>> {
    input
        .iter()
        .map(|plane| {
            let (oh, ow) = ((plane.len() - 3) / 2 + 1, (plane[0].len() - 3) / 2 + 1);
            (0..oh).map(|y| (0..ow).map(|x| (0..9).map(|d| plane[2 * y + d / 3][2 * x + d % 3]).fold(f64::MIN, f64::max)).collect()).collect()
        })
        .collect()
}

fn reference_lpips(tensors: &[(String, Vec<usize>, Vec<f32>)], a: &RgbImage, b: &RgbImage) -> f64 {
    let get = |name: &str| &tensors.iter().find(|t| t.0 == name).unwrap().2;
    let features = |img: &RgbImage| {
        let srgb = |v: f32| glassbake_core::color::linear_to_srgb(v) as f64;
        let mut x: Vec<Vec<Vec<f64>>> = (0..3)
            .map(|c| {
                (0..img.height)
                    .map(|y| (0..img.width).map(|px| (2.0 * srgb(img.get(px, y)[c]) - 1.0 - INPUT_SHIFT[c] as f64) / INPUT_SCALE[c] as f64).collect())
                    .collect()
            })
            .collect();
        let mut outs = Vec::new();
        for s in 0..5 {
            if s == 1 || s == 2 {
                x = reference_pool(&x);
            }
            x = reference_conv(
                &x,
                get(&format!("features.{}.weight", INDEX[s])),
                get(&format!("features.{}.bias", INDEX[s])),
                CHANNELS[s],
                KERNELS[s],
                CONV_STRIDE[s],
                CONV_PADDING[s],
            );
            outs.push(x.clone());
        }
        outs
    };
    let (fa, fb) = (features(a), features(b));
    let mut total = 0.0;
    for s in 0..5 {
        let lin = get(&format!("lin{s}.model.1.weight"));
        let (h, w) = (fa[s][0].len(), fa[s][0][0].len());
        let mut layer = 0.0;
        for y in 0..h {
            for x in 0..w {
                let norm = |f: &Vec<Vec<Vec<f64>>>| f.iter().map(|c| c[y][x] * c[y][x]).sum::<f64>().sqrt() + 1e-10;
                let (na, nb) = (norm(&fa[s]), norm(&fb[s]));
                for c in 0..CHANNELS[s] {
                    layer += lin[c] as f64 * (fa[s][c][y][x] / na - fb[s][c][y][x] / nb).powi(2);
                }
            }
        }
        total += layer / (h * w) as f64;
    }
    total
}

fn test_image(w: usize, h: usize, phase: f32) -> RgbImage {
    RgbImage::new(
        w,
        h,
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                [0.5 + 0.4 * (0.3 * x + phase).sin(), 0.5 + 0.4 * (0.2 * y - phase).cos(), ((x + y) / (w + h) as f32).powi(2)]
            })
            .collect(),
    )
    .unwrap()
}

#[test]
fn lpips_from_a_weights_file_matches_a_naive_reference() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lpips_alex.safetensors");
    let weights = tensors(false);
    write(&path, &weights);
    let lpips = Lpips::load(&path).unwrap();
    assert_eq!(lpips.convs.iter().map(|c| c.out_channels).collect::<Vec<_>>(), CHANNELS);
    let (a, b) = (test_image(40, 36, 0.0), test_image(40, 36, 0.7));
    let d = lpips.distance(&a, &b).unwrap();
    let expected = reference_lpips(&weights, &a, &b);
    assert!(d > 1e-4, "different images must be apart: {d}");
    assert!((d - expected).abs() < 1e-4 * expected.max(1.0), "LPIPS {d} vs reference {expected}");
    assert_eq!(lpips.distance(&a, &a).unwrap(), 0.0);
    assert!((lpips.distance(&b, &a).unwrap() - d).abs() < 1e-6);
}

#[test]
fn lpips_accepts_the_lpips_package_names() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.safetensors");
    write(&path, &tensors(true));
    let (a, b) = (test_image(32, 32, 0.0), test_image(32, 32, 1.0));
    let d = Lpips::load(&path).unwrap().distance(&a, &b).unwrap();
    assert!((d - reference_lpips(&tensors(false), &a, &b)).abs() < 1e-4);
}

#[test]
fn bad_weights_files_are_named_with_the_tensor_at_fault() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.safetensors");
    let mut missing = tensors(false);
    missing.retain(|t| t.0 != "lin3.model.1.weight");
    write(&path, &missing);
    let message = Lpips::load(&path).unwrap_err().to_string();
    assert!(message.contains("w.safetensors") && message.contains("lin3.model.1.weight"), "{message}");

    let mut wrong = tensors(false);
    wrong[3].1 = vec![5, 3, 5, 5]; // conv2 expects 4 input channels
    wrong[3].2.truncate(5 * 3 * 5 * 5);
    write(&path, &wrong);
    let message = Lpips::load(&path).unwrap_err().to_string();
    assert!(message.contains("features.3.weight") && message.contains("[5, 3, 5, 5]"), "{message}");

    std::fs::write(&path, b"not safetensors").unwrap();
    assert!(Lpips::load(&path).unwrap_err().to_string().contains("w.safetensors"));
    assert!(Lpips::load(&dir.path().join("absent.safetensors")).is_err());
}
