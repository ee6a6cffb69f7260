//! LPIPS (Zhang et al. 2018, "The Unreasonable Effectiveness of Deep Features as a Perceptual
//! Metric"), version 0.1 with the AlexNet trunk, evaluated on the CPU from a weights file the
//! user supplies: glassbake downloads nothing.
//!
//! The file is one safetensors file holding f32 tensors named as in PyTorch:
//! - AlexNet's five convolutions, `features.{0,3,6,8,10}.{weight,bias}` (torchvision's names;
//!   the `net.slice{1..5}.N.` names of a saved `lpips.LPIPS` model are accepted too);
//! - the five linear heads `lin{0..4}.model.1.weight`, shape [1, C_k, 1, 1].
//!
//! `docs/eval.md` gives the three lines of Python that write it from the `lpips` package.
//! Channel counts are read from the shapes; kernels, strides and padding are AlexNet's.
//!
//! Distance: inputs are sRGB-encoded, mapped to [-1, 1] and normalised by LPIPS's scaling
//! layer; after each ReLU (conv1..conv5) the features of both images are unit-normalised over
//! channels, their squared difference weighted by the linear head, averaged over pixels, and
//! the five layers' values summed.

use std::path::{Path, PathBuf};

use glassbake_core::{Error, Result};
use rayon::prelude::*;
use safetensors::{Dtype, SafeTensors};

use crate::rgb::RgbImage;

/// LPIPS's scaling layer (lpips/pretrained_networks, ScalingLayer): x' = (x - shift) / scale.
pub const INPUT_SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
pub const INPUT_SCALE: [f32; 3] = [0.458, 0.448, 0.450];
/// AlexNet (Krizhevsky 2012, torchvision layout): stride and padding of each convolution; a
/// 3x3 stride-2 max-pool follows conv1 and conv2.
pub const CONV_STRIDE: [usize; 5] = [4, 1, 1, 1, 1];
pub const CONV_PADDING: [usize; 5] = [2, 2, 1, 1, 1];
const TORCHVISION_INDEX: [usize; 5] = [0, 3, 6, 8, 10];
/// Smallest frame side AlexNet's five stages accept (conv1 must give at least 7 px).
pub const MIN_SIDE: usize = 31;
const NORMALISE_EPS: f32 = 1e-10;

/// A C x H x W feature map.
#[derive(Clone, Debug)]
pub struct FeatureMap {
    pub channels: usize,
    pub height: usize,
    pub width: usize,
    pub data: Vec<f32>,
}

#[derive(Clone, Debug)]
pub struct Conv {
    /// [out, in, k, k]
    pub weight: Vec<f32>,
    pub bias: Vec<f32>,
    pub out_channels: usize,
    pub in_channels: usize,
    pub kernel: usize,
    pub stride: usize,
    pub padding: usize,
}

impl Conv {
    pub fn apply(&self, input: &FeatureMap) -> FeatureMap {
        let (k, s, p) = (self.kernel, self.stride, self.padding);
        let (h, w) = (input.height, input.width);
        let oh = (h + 2 * p - k) / s + 1;
        let ow = (w + 2 * p - k) / s + 1;
        let mut data = vec![0.0f32; self.out_channels * oh * ow];
        data.par_chunks_mut(oh * ow).enumerate().for_each(|(o, out)| {
            out.fill(self.bias[o]);
            for i in 0..self.in_channels {
                let plane = &input.data[i * h * w..(i + 1) * h * w];
                for ky in 0..k {
                    for kx in 0..k {
                        let weight = self.weight[((o * self.in_channels + i) * k + ky) * k + kx];
                        for oy in 0..oh {
                            let y = (oy * s + ky) as isize - p as isize;
                            if y < 0 || y >= h as isize {
                                continue;
                            }
                            let row = &plane[y as usize * w..(y as usize + 1) * w];
                            let out_row = &mut out[oy * ow..(oy + 1) * ow];
                            for (ox, value) in out_row.iter_mut().enumerate() {
                                let x = (ox * s + kx) as isize - p as isize;
                                if x >= 0 && x < w as isize {
                                    *value += weight * row[x as usize];
                                }
                            }
                        }
                    }
                }
            }
        });
        FeatureMap { channels: self.out_channels, height: oh, width: ow, data }
    }
}

pub fn relu(mut map: FeatureMap) -> FeatureMap {
    map.data.iter_mut().for_each(|v| *v = v.max(0.0));
    map
}

/// 3x3 max-pool, stride 2, no padding (floor), as in AlexNet.
pub fn max_pool(map: &FeatureMap) -> FeatureMap {
    let (h, w) = (map.height, map.width);
    let (oh, ow) = ((h - 3) / 2 + 1, (w - 3) / 2 + 1);
    let mut data = Vec::with_capacity(map.channels * oh * ow);
    for c in 0..map.channels {
        let plane = &map.data[c * h * w..(c + 1) * h * w];
        for oy in 0..oh {
            for ox in 0..ow {
                let mut m = f32::NEG_INFINITY;
                for dy in 0..3 {
                    for dx in 0..3 {
                        m = m.max(plane[(2 * oy + dy) * w + 2 * ox + dx]);
                    }
                }
                data.push(m);
            }
        }
    }
    FeatureMap { channels: map.channels, height: oh, width: ow, data }
}

/// The weighted, spatially averaged squared difference of two unit-normalised feature maps.
pub fn layer_distance(a: &FeatureMap, b: &FeatureMap, weights: &[f32]) -> f64 {
    let pixels = a.height * a.width;
    let mut total = 0.0f64;
    for i in 0..pixels {
        let norm = |m: &FeatureMap| (0..m.channels).map(|c| m.data[c * pixels + i].powi(2)).sum::<f32>().sqrt() + NORMALISE_EPS;
        let (na, nb) = (norm(a), norm(b));
        for (c, wc) in weights.iter().enumerate() {
            let d = a.data[c * pixels + i] / na - b.data[c * pixels + i] / nb;
            total += (wc * d * d) as f64;
        }
    }
    total / pixels as f64
}

/// A loaded LPIPS-AlexNet.
#[derive(Clone, Debug)]
pub struct Lpips {
    pub convs: Vec<Conv>,
    pub linear: Vec<Vec<f32>>,
    pub source: PathBuf,
}

fn bad(path: &Path, field: &str, message: impl Into<String>) -> Error {
    Error::bad_input(path.display(), field, message)
}

fn tensor(file: &SafeTensors, path: &Path, names: &[String]) -> Result<(Vec<usize>, Vec<f32>)> {
    for name in names {
        if let Ok(view) = file.tensor(name) {
            if view.dtype() != Dtype::F32 {
                return Err(bad(path, name, format!("is {:?}; LPIPS weights must be f32", view.dtype())));
            }
            let data = view.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
            return Ok((view.shape().to_vec(), data));
        }
    }
    Err(bad(path, &names[0], "missing (an LPIPS AlexNet weights file needs features.{0,3,6,8,10}.{weight,bias} and lin{0..4}.model.1.weight)"))
}

impl Lpips {
    pub fn load(path: &Path) -> Result<Lpips> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let file = SafeTensors::deserialize(&bytes).map_err(|e| bad(path, "safetensors", e.to_string()))?;
        let mut convs = Vec::new();
        let mut in_channels = 3;
        for (stage, &index) in TORCHVISION_INDEX.iter().enumerate() {
            let names = |part: &str| vec![format!("features.{index}.{part}"), format!("net.slice{}.{index}.{part}", stage + 1)];
            let weight_names = names("weight");
            let (shape, weight) = tensor(&file, path, &weight_names)?;
            if shape.len() != 4 || shape[1] != in_channels || shape[2] != shape[3] {
                return Err(bad(path, &weight_names[0], format!("shape {shape:?} is not [out, {in_channels}, k, k]")));
            }
            let (bias_shape, bias) = tensor(&file, path, &names("bias"))?;
            if bias_shape != [shape[0]] {
                return Err(bad(path, &names("bias")[0], format!("shape {bias_shape:?} is not [{}]", shape[0])));
            }
            convs.push(Conv { weight, bias, out_channels: shape[0], in_channels, kernel: shape[2], stride: CONV_STRIDE[stage], padding: CONV_PADDING[stage] });
            in_channels = shape[0];
        }
        let mut linear = Vec::new();
        for (k, conv) in convs.iter().enumerate() {
            let name = format!("lin{k}.model.1.weight");
            let (shape, weight) = tensor(&file, path, std::slice::from_ref(&name))?;
            if shape != [1, conv.out_channels, 1, 1] {
                return Err(bad(path, &name, format!("shape {shape:?} is not [1, {}, 1, 1]", conv.out_channels)));
            }
            linear.push(weight);
        }
        Ok(Lpips { convs, linear, source: path.to_path_buf() })
    }

    /// The five post-ReLU feature maps of an image.
    pub fn features(&self, image: &RgbImage) -> Vec<FeatureMap> {
        let srgb = image.to_srgb();
        let pixels = image.width * image.height;
        let mut data = vec![0.0f32; 3 * pixels];
        for (i, p) in srgb.iter().enumerate() {
            for c in 0..3 {
                data[c * pixels + i] = (2.0 * p[c] - 1.0 - INPUT_SHIFT[c]) / INPUT_SCALE[c];
            }
        }
        let mut x = FeatureMap { channels: 3, height: image.height, width: image.width, data };
        let mut outputs = Vec::with_capacity(5);
        for (stage, conv) in self.convs.iter().enumerate() {
            if stage == 1 || stage == 2 {
                x = max_pool(&x);
            }
            x = relu(conv.apply(&x));
            outputs.push(x.clone());
        }
        outputs
    }

    pub fn distance(&self, a: &RgbImage, b: &RgbImage) -> Result<f64> {
        if a.width < MIN_SIDE || a.height < MIN_SIDE || (a.width, a.height) != (b.width, b.height) {
            return Err(Error::Internal(format!(
                "LPIPS needs two frames of the same size, at least {MIN_SIDE} px: {}x{} and {}x{}",
                a.width, a.height, b.width, b.height
            )));
        }
        let (fa, fb) = (self.features(a), self.features(b));
        Ok(fa.iter().zip(&fb).zip(&self.linear).map(|((x, y), w)| layer_distance(x, y, w)).sum())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layer_distance_matches_a_hand_computed_value() {
        // One pixel, two channels: a = (3, 4) -> (0.6, 0.8); b = (0, 2) -> (0, 1).
        // Squared differences (0.36, 0.04), weights (1, 0.5): 0.36 + 0.02 = 0.38.
        let a = FeatureMap { channels: 2, height: 1, width: 1, data: vec![3.0, 4.0] };
        let b = FeatureMap { channels: 2, height: 1, width: 1, data: vec![0.0, 2.0] };
        assert!((layer_distance(&a, &b, &[1.0, 0.5]) - 0.38).abs() < 1e-6);
        // Unit normalisation: scaling one map changes nothing.
        let b10 = FeatureMap { data: vec![0.0, 20.0], ..b.clone() };
        assert!((layer_distance(&a, &b10, &[1.0, 0.5]) - 0.38).abs() < 1e-6);
    }

    #[test]
    fn convolution_and_pooling_match_hand_computed_values() {
        // 3x3 input 1..9, 2x2 kernel of ones, stride 1, padding 1 -> 4x4 sums of 2x2 windows.
        let input = FeatureMap { channels: 1, height: 3, width: 3, data: (1..=9).map(|v| v as f32).collect() };
        let conv = Conv { weight: vec![1.0; 4], bias: vec![0.5], out_channels: 1, in_channels: 1, kernel: 2, stride: 1, padding: 1 };
        let out = conv.apply(&input);
        assert_eq!((out.height, out.width), (4, 4));
        // Corners see one input; the window at (1, 1) sees 1 + 2 + 4 + 5 = 12.
        assert_eq!(out.data[0], 1.5);
        assert_eq!(out.data[5], 12.5);
        assert_eq!(out.data[15], 9.5);
        let pooled = max_pool(&FeatureMap { channels: 1, height: 5, width: 5, data: (0..25).map(|v| v as f32).collect() });
        assert_eq!(pooled.data, vec![12.0, 14.0, 22.0, 24.0]);
    }
}
