//! Luminance, tone mapping and sRGB encoding. The one documented tone map of glassbake is "clamp":
//! linear radiance is clamped to [0, 1] and, for PNG previews, sRGB-encoded. Metrics are
//! computed on the clamped linear values (the paper's numbers are in [0, 1] image space).

use glam::Vec3;

/// Rec. 709 relative luminance of linear RGB.
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// The metric/preview tone map: clamp linear radiance to [0, 1]. NaN maps to 0.
pub fn tonemap_clamp(v: f32) -> f32 {
    if v.is_nan() {
        0.0
    } else {
        v.clamp(0.0, 1.0)
    }
}

/// sRGB opto-electronic transfer function (IEC 61966-2-1).
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = tonemap_clamp(v);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse of [`linear_to_srgb`], for sRGB-encoded textures.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

pub fn to_srgb8(v: f32) -> u8 {
    (linear_to_srgb(v) * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_and_known_points() {
        for i in 0..=100 {
            let v = i as f32 / 100.0;
            assert!((srgb_to_linear(linear_to_srgb(v)) - v).abs() < 1e-5);
        }
        // 18% grey encodes to ~0.4613 (sRGB standard curve).
        assert!((linear_to_srgb(0.18) - 0.4613).abs() < 1e-3);
        assert_eq!(to_srgb8(1.0), 255);
        assert_eq!(to_srgb8(-3.0), 0);
        assert_eq!(tonemap_clamp(f32::NAN), 0.0);
    }
}
