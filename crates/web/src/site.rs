//! `site.json`: what an exported site holds and how the page opens it. Written by
//! [`crate::export`], read by the page (the module's [`crate::page`] and `page/glassbake.js`),
//! so one type describes both sides.

use glassbake_core::{Camera, Error, Result};
use glassbake_realtime::orbit::{Orbit, OrbitRange};
use glassbake_scene::Scene;
use serde::{Deserialize, Serialize};

/// The file, at the site's root, that describes it.
pub const SITE_FILE: &str = "site.json";

/// Where a site keeps the model's files.
pub const MODEL_CONFIG: &str = "model/config.json";
pub const MODEL_WEIGHTS: &str = "model/glassnet.safetensors";

/// 1: the first.
pub const SITE_FORMAT: u32 = 1;

/// Where the page finds its scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SceneSource {
    /// A scene built into glassbake, by name: nothing to fetch.
    Builtin { name: String },
    /// The scene's files (a manifest and what it refers to), relative to the site; `entry` is
    /// the one the scene is opened from.
    Files { entry: String, files: Vec<String> },
}

/// A variable as the page shows it: a slider over `[min, max]`, starting at `default`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteVariable {
    pub name: String,
    /// What it changes ("roughness", "translation", ...).
    pub kind: String,
    pub min: f32,
    pub max: f32,
    pub default: f32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteManifest {
    pub format_version: u32,
    pub title: String,
    pub scene: SceneSource,
    /// The model's `config.json` and weights, relative to the site.
    pub model_config: String,
    pub model_weights: String,
    /// The weights' precision on disk ("f32" or "f16"); the network computes in f32.
    pub weights_precision: String,
    /// The frame's side in pixels: the resolution the model was trained at.
    pub resolution: u32,
    /// The views the model was trained on, which the page's orbit camera stays within.
    pub orbit: OrbitRange,
    /// Up vector, field of view and clip planes of every view.
    pub camera: Camera,
    pub variables: Vec<SiteVariable>,
}

impl SiteManifest {
    /// The site's description for `scene` (the model's, loaded from `scene_source`) and a model
    /// trained at `resolution`.
    pub fn new(scene: &Scene, scene_source: SceneSource, resolution: u32, weights_precision: &str) -> SiteManifest {
        SiteManifest {
            format_version: SITE_FORMAT,
            title: scene.name.clone(),
            scene: scene_source,
            model_config: MODEL_CONFIG.into(),
            model_weights: MODEL_WEIGHTS.into(),
            weights_precision: weights_precision.into(),
            resolution,
            orbit: OrbitRange::of(&scene.camera),
            camera: scene.camera.middle(),
            variables: scene
                .variables
                .iter()
                .map(|v| SiteVariable { name: v.name.clone(), kind: v.kind_name().into(), min: v.min, max: v.max, default: v.default })
                .collect(),
        }
    }

    pub fn parse(text: &str) -> Result<SiteManifest> {
        let site: SiteManifest = serde_json::from_str(text).map_err(|e| Error::bad_input(SITE_FILE, "site", e.to_string()))?;
        if site.format_version != SITE_FORMAT {
            return Err(Error::bad_input(SITE_FILE, "format_version", format!("{} is not a site format this page reads ({SITE_FORMAT})", site.format_version)));
        }
        Ok(site)
    }

    /// The camera of an orbit, brought into the trained views.
    pub fn camera_at(&self, orbit: Orbit) -> Camera {
        self.orbit.clamp(orbit).camera(&self.camera)
    }

    /// `values` (one per variable) each brought into its range; a missing one at its default.
    pub fn values(&self, values: &[f32]) -> Vec<f32> {
        self.variables.iter().enumerate().map(|(i, v)| values.get(i).copied().filter(|x| x.is_finite()).map_or(v.default, |x| x.clamp(v.min, v.max))).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_site_round_trips_and_keeps_values_and_views_in_range() {
        let scene = glassbake_scene::builtin::builtin("cornellbox").unwrap();
        let site = SiteManifest::new(&scene, SceneSource::Builtin { name: "cornellbox".into() }, 96, "f32");
        let back = SiteManifest::parse(&serde_json::to_string(&site).unwrap()).unwrap();
        assert_eq!(back, site);
        assert_eq!(site.variables.len(), scene.variables.len());
        let huge: Vec<f32> = vec![1e9; scene.variables.len()];
        for (value, variable) in site.values(&huge).iter().zip(&scene.variables) {
            assert_eq!(*value, variable.max);
        }
        assert_eq!(site.values(&[]), scene.variables.iter().map(|v| v.default).collect::<Vec<_>>());
        let far = site.camera_at(Orbit { distance: 1e6, ..site.orbit.middle() });
        assert!((far.position - site.orbit.target).length() <= site.orbit.distance.max * 1.0001);
        let wrong = serde_json::to_string(&SiteManifest { format_version: 99, ..site }).unwrap();
        assert!(SiteManifest::parse(&wrong).unwrap_err().to_string().contains("format_version"));
    }
}
