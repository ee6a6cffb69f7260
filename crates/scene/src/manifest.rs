//! The TOML scene manifest: points at a geometry file and declares what glTF/OBJ cannot —
//! camera ranges, rectangle lights, variables, per-object overrides. The same types are
//! serialised by `scene export`, so an exported manifest is always one the loader accepts.
//!
//! ```toml
//! name = "my-scene"
//! geometry = "scene.gltf"          # relative to this file: .gltf, .glb or .obj
//! background = [0.0, 0.0, 0.0]     # radiance of escaped rays (optional)
//!
//! [camera]
//! target = [0.0, 0.9, 0.0]
//! target_jitter = [0.1, 0.1, 0.0]  # optional
//! fov_x_deg = [38.0, 42.0]         # a range, or one number
//! near = 0.05
//! far = 20.0
//! position = { kind = "box", min = [-0.35, 0.8, 3.3], max = [0.35, 1.2, 3.8] }
//! # or: position = { kind = "orbit", center = [0, 1, 0], radius = [3, 4],
//! #                  azimuth_deg = [-30, 30], elevation_deg = [5, 20] }
//!
//! [[lights]]
//! name = "ceiling_light"
//! corner = [-0.235, 1.98, -0.19]
//! edge_u = [0.47, 0.0, 0.0]
//! edge_v = [0.0, 0.0, 0.38]
//! radiance = [17.0, 12.0, 4.0]
//!
//! [[variables]]
//! name = "sphere_x"
//! range = [-0.3, 0.3]
//! default = 0.0                    # optional, the middle of the range otherwise
//! target = { kind = "translation", object = "glass_sphere", axis = [1.0, 0.0, 0.0] }
//!
//! [objects.glass_sphere]           # optional overrides
//! transparent = true
//! ```

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    pub geometry: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraManifest>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<LightManifest>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub variables: Vec<VariableManifest>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub objects: BTreeMap<String, ObjectOverride>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraManifest {
    pub position: PositionManifest,
    pub target: [f32; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_jitter: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<[f32; 3]>,
    pub fov_x_deg: NumberOrRange,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub far: Option<f32>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum PositionManifest {
    Box { min: [f32; 3], max: [f32; 3] },
    Orbit { center: [f32; 3], radius: NumberOrRange, azimuth_deg: NumberOrRange, elevation_deg: NumberOrRange },
}

/// A fixed number or a `[min, max]` range.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum NumberOrRange {
    Number(f32),
    Range(Vec<f32>),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightManifest {
    pub name: String,
    pub corner: [f32; 3],
    pub edge_u: [f32; 3],
    pub edge_v: [f32; 3],
    pub radiance: [f32; 3],
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub two_sided: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VariableManifest {
    pub name: String,
    pub range: Vec<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default: Option<f32>,
    pub target: TargetManifest,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TargetManifest {
    Roughness {
        material: String,
    },
    Hue {
        material: String,
        #[serde(default = "default_saturation")]
        saturation: f32,
        #[serde(default = "default_brightness")]
        brightness: f32,
    },
    Translation {
        object: String,
        axis: [f32; 3],
    },
    LightTranslation {
        light: String,
        axis: [f32; 3],
    },
    LightIntensity {
        light: String,
    },
    EmissionIntensity {
        material: String,
    },
}

fn default_saturation() -> f32 {
    0.5
}
fn default_brightness() -> f32 {
    0.95
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectOverride {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transparent: Option<bool>,
    /// Make the object's glass a thin pane (true) or a solid (false): OBJ cannot say which.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thin: Option<bool>,
}

/// Parse manifest text. On failure returns (field or location, one-line message).
pub fn parse_manifest(text: &str) -> Result<Manifest, (String, String)> {
    toml::from_str::<Manifest>(text).map_err(|e| {
        let location = match e.span() {
            Some(span) => {
                let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
                format!("line {line}")
            }
            None => "manifest".to_string(),
        };
        (location, e.message().replace('\n', " ").trim().to_string())
    })
}
