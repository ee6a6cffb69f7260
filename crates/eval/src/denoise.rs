//! The path-traced + denoised baseline's denoiser: Intel Open Image Denoise's `RT` filter on a
//! linear HDR image with the albedo and normal of the first visible surface as guides (what a
//! real-time path tracer has at hand). Built only with the `oidn` cargo feature, since the
//! library is not in Debian; without it [`denoise`] says how to get it.

use glassbake_core::{Error, Result};

/// How to get the feature, for the error without it and for the docs.
pub const HOW_TO_ENABLE: &str = "this glassbake was built without the `oidn` feature: `pip install pyoidn`, then build with \
     `OIDN_DIR=$(python3 -c 'import pyoidn, os; print(os.path.join(os.path.dirname(pyoidn.__file__), \"oidn\"))') \
     cargo build --release --features oidn` (docs/eval.md)";

/// Whether this build can denoise.
pub const AVAILABLE: bool = cfg!(feature = "oidn");

/// Guide images and the image to denoise: interleaved RGB, row-major, `width * height * 3`
/// floats each. `color` is linear HDR radiance; `albedo` in [0, 1]; `normal` in [-1, 1] (any
/// fixed space).
pub struct DenoiseInput<'a> {
    pub width: usize,
    pub height: usize,
    pub color: &'a [f32],
    pub albedo: &'a [f32],
    pub normal: &'a [f32],
}

impl DenoiseInput<'_> {
    fn check(&self) -> Result<()> {
        let n = self.width * self.height * 3;
        for (name, image) in [("color", self.color), ("albedo", self.albedo), ("normal", self.normal)] {
            if image.len() != n {
                return Err(Error::Internal(format!("denoise: {name} has {} floats, not {n} ({}x{} RGB)", image.len(), self.width, self.height)));
            }
        }
        Ok(())
    }
}

/// Denoises `input.color`; returns linear HDR RGB, interleaved like the input.
#[cfg(feature = "oidn")]
pub fn denoise(input: &DenoiseInput) -> Result<Vec<f32>> {
    input.check()?;
    let device = oidn::Device::cpu().map_err(|e| Error::Internal(format!("Open Image Denoise: no CPU device: {e:?}")))?;
    let mut output = vec![0.0f32; input.color.len()];
    let mut filter = oidn::RayTracing::try_new(&device).map_err(|e| Error::Internal(format!("Open Image Denoise: no RT filter: {e:?}")))?;
    filter.hdr(true).image_dimensions(input.width, input.height).albedo_normal(input.albedo, input.normal);
    filter.filter(input.color, &mut output).map_err(|e| Error::Internal(format!("Open Image Denoise: filtering failed: {e:?}")))?;
    device.get_error().map_err(|e| Error::Internal(format!("Open Image Denoise: {e:?}")))?;
    Ok(output)
}

/// Without the `oidn` feature: an error naming the feature and how to build with it.
#[cfg(not(feature = "oidn"))]
pub fn denoise(input: &DenoiseInput) -> Result<Vec<f32>> {
    input.check()?;
    Err(Error::bad_input("--path-traced-baseline", "oidn", HOW_TO_ENABLE))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A smooth clean image (two flat regions with a soft gradient), its albedo and normals, and
    /// a noisy version: each pixel the clean value times an exponential-ish Monte Carlo factor.
    fn synthetic(width: usize, height: usize) -> (Vec<f32>, Vec<f32>, Vec<f32>, Vec<f32>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (mut clean, mut noisy, mut albedo, mut normal) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for y in 0..height {
            for x in 0..width {
                let left = x < width / 2;
                let a = if left { [0.8, 0.3, 0.2] } else { [0.2, 0.5, 0.8] };
                let light = 0.4 + 0.6 * y as f32 / height as f32;
                for &albedo_channel in &a {
                    let v = albedo_channel * light;
                    clean.push(v);
                    // Mean-one noise: the average of 4 exponential samples.
                    let factor: f32 = (0..4).map(|_| -(1.0 - rng.random::<f32>()).ln()).sum::<f32>() / 4.0;
                    noisy.push(v * factor);
                    albedo.push(albedo_channel);
                }
                normal.extend_from_slice(if left { &[0.0, 0.0, 1.0] } else { &[1.0, 0.0, 0.0] });
            }
        }
        (clean, noisy, albedo, normal)
    }

    #[cfg(feature = "oidn")]
    fn rmse(a: &[f32], b: &[f32]) -> f64 {
        (a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
    }

    #[cfg(feature = "oidn")]
    #[test]
    fn denoising_a_noisy_image_brings_it_closer_to_the_clean_one() {
        let (w, h) = (64, 48);
        let (clean, noisy, albedo, normal) = synthetic(w, h);
        let denoised = denoise(&DenoiseInput { width: w, height: h, color: &noisy, albedo: &albedo, normal: &normal }).unwrap();
        let (before, after) = (rmse(&noisy, &clean), rmse(&denoised, &clean));
        assert!(after < 0.3 * before, "RMSE {before:.4} before, {after:.4} after denoising: not down 3x");
    }

    #[cfg(not(feature = "oidn"))]
    #[test]
    fn without_the_feature_the_error_names_it_and_how_to_build_it() {
        let (clean, noisy, albedo, normal) = synthetic(8, 8);
        let err = denoise(&DenoiseInput { width: 8, height: 8, color: &noisy, albedo: &albedo, normal: &normal }).unwrap_err().to_string();
        assert!(err.contains("`oidn` feature") && err.contains("pip install pyoidn") && err.contains("--features oidn"), "{err}");
        assert_eq!(clean.len(), 8 * 8 * 3);
    }

    #[test]
    fn mismatched_sizes_are_refused() {
        let (_, noisy, albedo, normal) = synthetic(8, 8);
        let err = denoise(&DenoiseInput { width: 8, height: 9, color: &noisy, albedo: &albedo, normal: &normal }).unwrap_err().to_string();
        assert!(err.contains("color has 192 floats, not 216"), "{err}");
    }
}
