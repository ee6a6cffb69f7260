//! Per-frame image metrics on tone-mapped images (see `rgb` for the tone map).
//!
//! - MAE: mean absolute difference over pixels and the three channels.
//! - PSNR: 10 log10(1 / MSE), peak 1, MSE over pixels and channels; an exact match is capped at
//!   100 dB (MSE floor 1e-10) so that averages stay finite.
//! - DSSIM = (1 - SSIM) / 2, SSIM with the standard Gaussian window (11x11, sigma 1.5,
//!   K1 = 0.01, K2 = 0.03, dynamic range 1; Wang et al. 2004), computed per channel over the
//!   "valid" window positions (no padding) and averaged.
//! - T.MAE, T.PSNR: MAE and PSNR over the pixels covered by any transparent object only
//!   (absent when a frame has none).
//! - FLIP: mean of NVIDIA's LDR-FLIP error map (Andersson et al. 2020) on 8-bit sRGB, at the
//!   library's default 67 pixels per degree (0.7 m from a 24" 4K monitor).
//! - LPIPS: see `lpips`; only with a user-supplied weights file.

use glassbake_core::{Error, Result};
use serde::{Deserialize, Serialize};

use crate::rgb::RgbImage;

/// PSNR of an exact match (the MSE floor is 1e-10).
pub const PSNR_CAP_DB: f64 = 100.0;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameMetrics {
    pub mae: f64,
    pub psnr: f64,
    pub dssim: f64,
    pub t_mae: Option<f64>,
    pub t_psnr: Option<f64>,
    pub flip: f64,
    pub lpips: Option<f64>,
}

fn check_sizes(a: &RgbImage, b: &RgbImage) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::Internal(format!("comparing a {}x{} image with a {}x{} one", a.width, a.height, b.width, b.height)));
    }
    Ok(())
}

/// Sum of |a - b| and of (a - b)^2 over the selected pixels' channels, and the count of values.
fn error_sums(a: &RgbImage, b: &RgbImage, mask: Option<&[bool]>) -> (f64, f64, usize) {
    let mut abs = 0.0;
    let mut sq = 0.0;
    let mut count = 0;
    for (i, (p, q)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        for c in 0..3 {
            let d = (p[c] - q[c]) as f64;
            abs += d.abs();
            sq += d * d;
        }
        count += 3;
    }
    (abs, sq, count)
}

pub fn psnr_from_mse(mse: f64) -> f64 {
    10.0 * (1.0 / mse.max(1e-10)).log10()
}

/// MAE over all pixels, or over the masked ones (None when the mask selects nothing).
pub fn mae(a: &RgbImage, b: &RgbImage, mask: Option<&[bool]>) -> Result<Option<f64>> {
    check_sizes(a, b)?;
    let (abs, _, n) = error_sums(a, b, mask);
    Ok((n > 0).then(|| abs / n as f64))
}

/// PSNR over all pixels, or over the masked ones (None when the mask selects nothing).
pub fn psnr(a: &RgbImage, b: &RgbImage, mask: Option<&[bool]>) -> Result<Option<f64>> {
    check_sizes(a, b)?;
    let (_, sq, n) = error_sums(a, b, mask);
    Ok((n > 0).then(|| psnr_from_mse(sq / n as f64)))
}

pub const SSIM_WINDOW: usize = 11;
pub const SSIM_SIGMA: f64 = 1.5;

/// The normalised 1-D Gaussian of the SSIM window (the 2-D window is its outer product).
pub fn ssim_gaussian() -> [f64; SSIM_WINDOW] {
    let mut g = [0.0; SSIM_WINDOW];
    let centre = (SSIM_WINDOW / 2) as f64;
    for (i, v) in g.iter_mut().enumerate() {
        let d = i as f64 - centre;
        *v = (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let sum: f64 = g.iter().sum();
    g.map(|v| v / sum)
}

/// Separable "valid" Gaussian filtering of a w x h plane: (w - 10) x (h - 10) values.
fn filter_valid(plane: &[f64], w: usize, h: usize, g: &[f64; SSIM_WINDOW]) -> Vec<f64> {
    let (ow, oh) = (w + 1 - SSIM_WINDOW, h + 1 - SSIM_WINDOW);
    let mut rows = vec![0.0; ow * h];
    for y in 0..h {
        for x in 0..ow {
            rows[y * ow + x] = (0..SSIM_WINDOW).map(|k| g[k] * plane[y * w + x + k]).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..SSIM_WINDOW).map(|k| g[k] * rows[(y + k) * ow + x]).sum();
        }
    }
    out
}

/// Mean SSIM over the three channels (see the module comment). Frames must be at least 11 px.
pub fn ssim(a: &RgbImage, b: &RgbImage) -> Result<f64> {
    check_sizes(a, b)?;
    let (w, h) = (a.width, a.height);
    if w < SSIM_WINDOW || h < SSIM_WINDOW {
        return Err(Error::Internal(format!("SSIM needs frames of at least {SSIM_WINDOW} px, not {w}x{h}")));
    }
    const C1: f64 = 0.01 * 0.01;
    const C2: f64 = 0.03 * 0.03;
    let g = ssim_gaussian();
    let mut total = 0.0;
    for c in 0..3 {
        let x: Vec<f64> = a.pixels.iter().map(|p| p[c] as f64).collect();
        let y: Vec<f64> = b.pixels.iter().map(|p| p[c] as f64).collect();
        let product = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(p, q)| p * q).collect::<Vec<f64>>();
        let mu_x = filter_valid(&x, w, h, &g);
        let mu_y = filter_valid(&y, w, h, &g);
        let xx = filter_valid(&product(&x, &x), w, h, &g);
        let yy = filter_valid(&product(&y, &y), w, h, &g);
        let xy = filter_valid(&product(&x, &y), w, h, &g);
        let mut sum = 0.0;
        for i in 0..mu_x.len() {
            let (mx, my) = (mu_x[i], mu_y[i]);
            let (vx, vy, cov) = (xx[i] - mx * mx, yy[i] - my * my, xy[i] - mx * my);
            sum += ((2.0 * mx * my + C1) * (2.0 * cov + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2));
        }
        total += sum / mu_x.len() as f64;
    }
    Ok(total / 3.0)
}

pub fn dssim(a: &RgbImage, b: &RgbImage) -> Result<f64> {
    Ok((1.0 - ssim(a, b)?) / 2.0)
}

/// LDR-FLIP of `test` against `reference`: the mean error and the per-pixel error map in [0, 1].
pub fn flip(reference: &RgbImage, test: &RgbImage) -> Result<(f64, Vec<f32>)> {
    check_sizes(reference, test)?;
    let (w, h) = (reference.width as u32, reference.height as u32);
    let reference = nv_flip::FlipImageRgb8::with_data(w, h, &reference.to_srgb8());
    let test = nv_flip::FlipImageRgb8::with_data(w, h, &test.to_srgb8());
    let map = nv_flip::flip(reference, test, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let mean = nv_flip::FlipPool::from_image(&map).mean() as f64;
    Ok((mean, map.to_vec()))
}

/// All metrics of one frame. `mask` selects the transparent pixels.
pub fn frame_metrics(reference: &RgbImage, test: &RgbImage, mask: &[bool], lpips: Option<&crate::Lpips>) -> Result<(FrameMetrics, Vec<f32>)> {
    if mask.len() != reference.pixels.len() {
        return Err(Error::Internal(format!("a mask of {} pixels for a frame of {}", mask.len(), reference.pixels.len())));
    }
    let (flip_mean, flip_map) = flip(reference, test)?;
    let metrics = FrameMetrics {
        mae: mae(reference, test, None)?.expect("a frame has pixels"),
        psnr: psnr(reference, test, None)?.expect("a frame has pixels"),
        dssim: dssim(reference, test)?,
        t_mae: mae(reference, test, Some(mask))?,
        t_psnr: psnr(reference, test, Some(mask))?,
        flip: flip_mean,
        lpips: lpips.map(|l| l.distance(reference, test)).transpose()?,
    };
    Ok((metrics, flip_map))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3]) -> RgbImage {
        RgbImage::new(w, h, (0..w * h).map(|i| f(i % w, i / w)).collect()).unwrap()
    }

    #[test]
    fn mae_and_psnr_match_hand_computed_values() {
        // Two pixels; differences (0.1, 0.2, 0.3) and (0, 0, 0.6): |d| sums to 1.2 over 6 values,
        // d^2 sums to 0.01 + 0.04 + 0.09 + 0.36 = 0.5 -> MSE 1/12, PSNR 10 log10(12) = 10.7918 dB.
        let a = RgbImage::new(2, 1, vec![[0.5, 0.5, 0.5], [0.2, 0.2, 0.2]]).unwrap();
        let b = RgbImage::new(2, 1, vec![[0.6, 0.7, 0.8], [0.2, 0.2, 0.8]]).unwrap();
        assert!((mae(&a, &b, None).unwrap().unwrap() - 0.2).abs() < 1e-6);
        assert!((psnr(&a, &b, None).unwrap().unwrap() - 10.791_812).abs() < 1e-4);
        // Only the second pixel: MAE 0.6 / 3 = 0.2, MSE 0.36 / 3 = 0.12, PSNR 9.2082 dB.
        let mask = [false, true];
        assert!((mae(&a, &b, Some(&mask)).unwrap().unwrap() - 0.2).abs() < 1e-6);
        assert!((psnr(&a, &b, Some(&mask)).unwrap().unwrap() - 9.208_188).abs() < 1e-4);
        // No transparent pixel: no T metric.
        assert_eq!(mae(&a, &b, Some(&[false, false])).unwrap(), None);
        assert_eq!(psnr(&a, &a, None).unwrap(), Some(PSNR_CAP_DB));
    }

    #[test]
    fn values_are_clamped_before_comparison() {
        // Radiance 3.0 and 1.0 both tone-map to 1.0.
        let a = RgbImage::new(1, 1, vec![[3.0, -1.0, f32::NAN]]).unwrap();
        let b = RgbImage::new(1, 1, vec![[1.0, 0.0, 0.0]]).unwrap();
        assert_eq!(mae(&a, &b, None).unwrap(), Some(0.0));
    }

    #[test]
    fn ssim_of_constant_images_is_the_luminance_term() {
        // With no variance, SSIM = (2ab + C1) / (a^2 + b^2 + C1): for a = 0.2, b = 0.6,
        // (0.24 + 1e-4) / (0.4 + 1e-4) = 0.2401 / 0.4001 = 0.600100, DSSIM = 0.199950.
        let a = RgbImage::filled(16, 12, [0.2; 3]);
        let b = RgbImage::filled(16, 12, [0.6; 3]);
        assert!((ssim(&a, &b).unwrap() - 0.600_100).abs() < 1e-6);
        assert!((dssim(&a, &b).unwrap() - 0.199_950).abs() < 1e-6);
        assert!((ssim(&a, &a).unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn ssim_of_an_image_and_its_negative_follows_the_formula_per_window() {
        // y = 1 - x: mu_y = 1 - mu_x, var_y = var_x, cov = -var_x. On a pattern whose every
        // window has the same statistics (period 2 stripes), mean 0.5 and variance v:
        // SSIM = (2 * 0.25 + C1)/(0.5 + C1) * (C2 - 2v)/(2v + C2), v from the Gaussian weights.
        let x = image(31, 31, |px, _| if px % 2 == 0 { [0.9; 3] } else { [0.1; 3] });
        let y = image(31, 31, |px, _| if px % 2 == 0 { [0.1; 3] } else { [0.9; 3] });
        let g = ssim_gaussian();
        // Window starting at even column: weight on 0.9 columns = sum of even taps.
        let even: f64 = g.iter().step_by(2).sum();
        let expected_window = |w_high: f64| {
            let mean = 0.9 * w_high + 0.1 * (1.0 - w_high);
            let var = 0.81 * w_high + 0.01 * (1.0 - w_high) - mean * mean;
            let my = 1.0 - mean;
            let (c1, c2) = (1e-4, 9e-4);
            ((2.0 * mean * my + c1) * (c2 - 2.0 * var)) / ((mean * mean + my * my + c1) * (2.0 * var + c2))
        };
        // 21 valid columns: 11 start on even columns, 10 on odd ones (weight on 0.9 = 1 - even).
        let expected = (11.0 * expected_window(even) + 10.0 * expected_window(1.0 - even)) / 21.0;
        assert!((ssim(&x, &y).unwrap() - expected).abs() < 1e-9, "{} vs {expected}", ssim(&x, &y).unwrap());
        assert!(expected < -0.9, "a negative is anti-correlated: {expected}");
    }

    /// LDR-FLIP of uniform white against uniform black, from the published formula
    /// (Andersson et al. 2020, Sec. 4): no edges or points, so FLIP is the colour error alone.
    /// White and black differ only in L* (100), so HyAB = 100; colour error
    /// = (HyAB^q_c) mapped by the (p_c, p_t) compression against
    /// c_max = HyAB(Hunt(green), Hunt(blue))^q_c, q_c = 0.7, p_c = 0.4, p_t = 0.95.
    #[test]
    fn flip_of_white_against_black_matches_the_published_formula() {
        fn lab(rgb: [f64; 3]) -> [f64; 3] {
            // Linear sRGB -> XYZ (D65) -> CIELAB, reference white of linear (1, 1, 1).
            let m = [[0.412_456_4, 0.357_576_1, 0.180_437_5], [0.212_672_9, 0.715_152_2, 0.072_175_0], [0.019_333_9, 0.119_192_0, 0.950_304_1]];
            let xyz = |v: [f64; 3]| m.map(|r| r[0] * v[0] + r[1] * v[1] + r[2] * v[2]);
            let (p, white) = (xyz(rgb), xyz([1.0; 3]));
            let f = |t: f64| if t > (6.0f64 / 29.0).powi(3) { t.cbrt() } else { t / (3.0 * (6.0f64 / 29.0).powi(2)) + 4.0 / 29.0 };
            let (fx, fy, fz) = (f(p[0] / white[0]), f(p[1] / white[1]), f(p[2] / white[2]));
            [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
        }
        let hunt = |l: [f64; 3]| [l[0], 0.01 * l[0] * l[1], 0.01 * l[0] * l[2]];
        let hyab = |a: [f64; 3], b: [f64; 3]| (a[0] - b[0]).abs() + ((a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        let (qc, pc, pt) = (0.7, 0.4, 0.95);
        let cmax = hyab(hunt(lab([0.0, 1.0, 0.0])), hunt(lab([0.0, 0.0, 1.0]))).powf(qc);
        let delta = 100.0f64.powf(qc);
        let expected = if delta < pc * cmax { pt * delta / (pc * cmax) } else { pt + (delta - pc * cmax) / (cmax - pc * cmax) * (1.0 - pt) };
        let white = RgbImage::filled(32, 32, [1.0; 3]);
        let black = RgbImage::filled(32, 32, [0.0; 3]);
        let (mean, map) = flip(&white, &black).unwrap();
        assert!((mean - expected).abs() < 2e-3, "FLIP {mean} vs formula {expected}");
        assert!(map.iter().all(|&v| (v as f64 - expected).abs() < 2e-3));
        assert_eq!(flip(&white, &white).unwrap().0, 0.0);
    }
}
