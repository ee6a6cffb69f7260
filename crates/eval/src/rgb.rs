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
