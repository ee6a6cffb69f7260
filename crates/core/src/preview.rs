//! PNG previews of one attribute of a multi-layer buffer image (`opaque.albedo`,
//! `transparent.0.coverage`), for looking at what the rasterizer wrote.

use std::path::{Path, PathBuf};

use crate::{Error, PlanarImage, Result};

/// The channels of the layer attribute `name` (e.g. `opaque.albedo`): 1 or 3 of them.
pub fn attribute_channels(image: &PlanarImage, name: &str) -> Result<Vec<usize>> {
    let prefix = format!("{name}.");
    let channels: Vec<usize> = (0..image.channels().len()).filter(|&c| image.channels()[c].starts_with(&prefix)).collect();
    if channels.is_empty() {
        return Err(Error::bad_input("--png", name, "no such layer attribute (e.g. opaque.albedo, transparent.0.coverage)"));
    }
    if !matches!(channels.len(), 1 | 3) {
        return Err(Error::bad_input("--png", name, "expected an attribute with 1 or 3 channels"));
    }
    Ok(channels)
}

/// Writes a PNG preview of the attribute `name` beside `out` (`<out stem>.<name>.png`): colours (albedo, L_d) with the clamp tone map and
/// sRGB; directions mapped from [-1, 1]; positions, depths and other scalars stretched over
/// their range in the image.
pub fn write_attribute_preview(image: &PlanarImage, name: &str, out: &Path) -> Result<PathBuf> {
    let channels = attribute_channels(image, name)?;
    let stem = out.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "frame".into());
    let path = out.with_file_name(format!("{stem}.{name}.png"));
    let attribute = name.rsplit('.').next().unwrap_or(name);
    let range = |c: usize| {
        let p = image.plane(c);
        let lo = p.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = p.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        (lo, hi)
    };
    match (channels.len(), attribute) {
        (3, "albedo" | "Ld") => image.write_png_rgb(&path, [channels[0], channels[1], channels[2]])?,
        (3, _) => {
            // Map each channel linearly to [0, 1] (directions from [-1, 1]) and undo the sRGB
            // curve so the PNG stores the mapped value itself.
            let direction = matches!(attribute, "normal" | "wo");
            let mut mapped = image.select(&channels.iter().map(|&c| image.channels()[c].clone()).collect::<Vec<_>>())?;
            for (k, &c) in channels.iter().enumerate() {
                let (lo, hi) = if direction { (-1.0, 1.0) } else { range(c) };
                let scale = if hi > lo { 1.0 / (hi - lo) } else { 0.0 };
                for v in mapped.plane_mut(k) {
                    *v = crate::color::srgb_to_linear(((*v - lo) * scale).clamp(0.0, 1.0));
                }
            }
            mapped.write_png_rgb(&path, [0, 1, 2])?
        }
        (1, "coverage" | "roughness") => image.write_png_gray(&path, channels[0], 0.0, 1.0)?,
        (1, _) => {
            let (_, hi) = range(channels[0]);
            image.write_png_gray(&path, channels[0], 0.0, hi)?
        }
        _ => return Err(Error::bad_input("--png", name, "expected an attribute with 1 or 3 channels")),
    }
    Ok(path)
}
