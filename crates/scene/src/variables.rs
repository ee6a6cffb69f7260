//! Named scene variables (what the network learns to vary) and how their values are applied.

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// What a variable changes. Indices point into the scene's tables.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VariableTarget {
    /// The material's roughness is set to the value.
    Roughness { material: usize },
    /// The material's base colour (the tint, for glass) is set to the HSV colour with hue =
    /// value in degrees and the given saturation and value (brightness).
    Hue { material: usize, saturation: f32, brightness: f32 },
    /// The object is moved by `value * axis` from its base position.
    Translation { object: usize, axis: Vec3 },
    /// The rectangle light is moved by `value * axis` from its base position.
    LightTranslation { light: usize, axis: Vec3 },
    /// The rectangle light's radiance is its base radiance times the value.
    LightIntensity { light: usize },
    /// The material's emission is its base emission times the value (emissive meshes).
    EmissionIntensity { material: usize },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Variable {
    pub name: String,
    pub min: f32,
    pub max: f32,
    /// Value used for previews and `scene info`; within [min, max].
    pub default: f32,
    pub target: VariableTarget,
}

impl Variable {
    pub fn kind_name(&self) -> &'static str {
        match self.target {
            VariableTarget::Roughness { .. } => "roughness",
            VariableTarget::Hue { .. } => "hue",
            VariableTarget::Translation { .. } => "translation",
            VariableTarget::LightTranslation { .. } => "light_translation",
            VariableTarget::LightIntensity { .. } => "light_intensity",
            VariableTarget::EmissionIntensity { .. } => "emission_intensity",
        }
    }

    /// Map a value to [0, 1] over the variable's range (the network's input encoding).
    pub fn normalize(&self, value: f32) -> f32 {
        (value - self.min) / (self.max - self.min)
    }
}

/// HSV to linear RGB, hue in degrees.
pub fn hsv_to_rgb(hue_deg: f32, saturation: f32, value: f32) -> Vec3 {
    let h = hue_deg.rem_euclid(360.0) / 60.0;
    let c = value * saturation;
    let x = c * (1.0 - ((h % 2.0) - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    Vec3::new(r, g, b) + Vec3::splat(value - c)
}

/// One value per variable, in the scene's variable order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VariableValues(pub Vec<f32>);
