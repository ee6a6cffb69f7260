//! The tone-mapped images every metric is computed on.
//!
//! Tone map (stated once, used everywhere): linear radiance is clamped to [0, 1]
//! (`glassbake_core::color::tonemap_clamp`, NaN -> 0). MAE, PSNR, DSSIM, T.MAE and T.PSNR are
//! computed on these clamped *linear* values, the space GlassNet is trained in and the paper
//! reports in. FLIP and LPIPS model human perception of displayed images, so they see the same
//! values sRGB-encoded (FLIP as 8-bit sRGB, the input its LDR variant is defined on).

use std::path::Path;

use glassbake_core::color::{linear_to_srgb, to_srgb8, tonemap_clamp};
use glassbake_core::layout::GROUND_TRUTH_CHANNELS;
use glassbake_core::{Error, PlanarImage, Result};

/// Clamped linear RGB in [0, 1], row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
}

impl RgbImage {
    pub fn new(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Result<RgbImage> {
        if pixels.len() != width * height {
            return Err(Error::Internal(format!("{}x{} image with {} pixels", width, height, pixels.len())));
        }
        Ok(RgbImage { width, height, pixels: pixels.into_iter().map(|p| p.map(tonemap_clamp)).collect() })
    }

    pub fn filled(width: usize, height: usize, value: [f32; 3]) -> RgbImage {
        RgbImage::new(width, height, vec![value; width * height]).expect("sizes agree")
    }

    /// Tone-maps the R, G, B channels of a planar image.
    pub fn from_planar(image: &PlanarImage) -> Result<RgbImage> {
        let planes: Vec<&[f32]> = GROUND_TRUTH_CHANNELS
            .iter()
            .map(|c| image.plane_by_name(c).ok_or_else(|| Error::Internal(format!("image without channel {c}"))))
            .collect::<Result<_>>()?;
        let pixels = (0..image.pixel_count()).map(|i| [planes[0][i], planes[1][i], planes[2][i]]).collect();
        RgbImage::new(image.width() as usize, image.height() as usize, pixels)
    }

    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        self.pixels[y * self.width + x]
    }

    /// 8-bit sRGB, interleaved RGB.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.map(to_srgb8)).collect()
    }

    /// sRGB-encoded values in [0, 1].
    pub fn to_srgb(&self) -> Vec<[f32; 3]> {
        self.pixels.iter().map(|p| p.map(linear_to_srgb)).collect()
    }

    pub fn write_png(&self, path: &Path) -> Result<()> {
        write_srgb8_png(path, self.width, self.height, self.to_srgb8())
    }

    /// Nearest-neighbour enlargement by an integer factor (small frames in grids and reports).
    pub fn enlarged(&self, factor: usize) -> RgbImage {
        let (w, h) = (self.width * factor, self.height * factor);
        let pixels = (0..w * h).map(|i| self.get((i % w) / factor, (i / w) / factor)).collect();
        RgbImage { width: w, height: h, pixels }
    }
}

impl RgbImage {
    /// Bilinear x2 enlargement, the up-sampling a renderer without a super-sampler would do:
    /// output pixel X samples the input at (X + 0.5) / 2 - 0.5 (pixel centres), clamped to
    /// the outer pixel centres at the edges.
    pub fn bilinear_x2(&self) -> RgbImage {
        let (w, h) = (self.width * 2, self.height * 2);
        let source = |x: usize, limit: usize| {
            let u = ((x as f32 + 0.5) * 0.5 - 0.5).clamp(0.0, (limit - 1) as f32);
            let i = (u.floor() as usize).min(limit.saturating_sub(2));
            (i, (i + 1).min(limit - 1), u - i as f32)
        };
        let pixels = (0..w * h)
            .map(|index| {
                let ((x0, x1, fx), (y0, y1, fy)) = (source(index % w, self.width), source(index / w, self.height));
                let mix = |a: [f32; 3], b: [f32; 3], t: f32| [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * t);
                mix(mix(self.get(x0, y0), self.get(x1, y0), fx), mix(self.get(x0, y1), self.get(x1, y1), fx), fy)
            })
            .collect();
        RgbImage { width: w, height: h, pixels }
    }
}

/// Writes interleaved 8-bit sRGB as PNG, atomically.
pub fn write_srgb8_png(path: &Path, width: usize, height: usize, bytes: Vec<u8>) -> Result<()> {
    let buffer = image::RgbImage::from_raw(width as u32, height as u32, bytes).ok_or_else(|| Error::Internal("PNG buffer size".into()))?;
    glassbake_core::image::write_atomically(path, |tmp| {
        buffer.save_with_format(tmp, image::ImageFormat::Png).map_err(|e| Error::Internal(format!("{}: {e}", path.display())))
    })
}

/// The transparency mask of a frame: true where any transparent object covers the pixel.
pub fn mask_from_planar(mask: &PlanarImage) -> Vec<bool> {
    mask.plane(0).iter().map(|&v| v > 0.5).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bilinear interpolation reproduces a linear function exactly, so an enlarged plane
    /// a + b x + c y is the same plane sampled at the output's pixel centres (clamped at the
    /// edges).
    #[test]
    fn bilinear_x2_reproduces_a_plane() {
        let (w, h) = (5usize, 3usize);
        let plane = |x: f32, y: f32| [0.1 + 0.05 * x + 0.02 * y, 0.9 - 0.1 * x, 0.3 + 0.2 * y];
        let image = RgbImage::new(w, h, (0..w * h).map(|i| plane((i % w) as f32, (i / w) as f32)).collect()).unwrap();
        let big = image.bilinear_x2();
        assert_eq!((big.width, big.height), (2 * w, 2 * h));
        for y in 0..2 * h {
            for x in 0..2 * w {
                let u = ((x as f32 + 0.5) / 2.0 - 0.5).clamp(0.0, (w - 1) as f32);
                let v = ((y as f32 + 0.5) / 2.0 - 0.5).clamp(0.0, (h - 1) as f32);
                let (got, want) = (big.get(x, y), plane(u, v));
                for c in 0..3 {
                    assert!((got[c] - want[c]).abs() < 1e-6, "({x}, {y}) channel {c}: {} vs {}", got[c], want[c]);
                }
            }
        }
        // One pixel wide or high: the edge clamp leaves nothing to interpolate.
        let column = RgbImage::new(1, 2, vec![[0.2; 3], [0.6; 3]]).unwrap().bilinear_x2();
        let got: Vec<f32> = column.pixels.iter().map(|p| p[0]).collect();
        let want = [0.2, 0.2, 0.3, 0.3, 0.5, 0.5, 0.6, 0.6];
        assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-6), "{got:?}");
    }
}
