//! Scene instances (a scene with a value for every variable) and seeded sampling of
//! (camera, values) pairs.

use glam::Affine3A;
use glassbake_core::seed::{purpose_seed, sample_seed};
use glassbake_core::{Camera, Error, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::camera_spec::Interval;
use crate::model::Scene;
use crate::variables::{hsv_to_rgb, VariableTarget};

/// One training/evaluation frame's random draw: a camera and a value per variable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    pub index: u64,
    pub seed: u64,
    pub camera: Camera,
    pub values: Vec<f32>,
}

impl Scene {
    /// Sample `index` of a set generated with `dataset_seed`: camera and variable values
    /// uniform in their ranges. Depends on nothing but (scene ranges, seed, index), so any
    /// sample can be regenerated alone.
    pub fn sample(&self, dataset_seed: u64, index: u64) -> Sample {
        let seed = sample_seed(dataset_seed, index);
        let mut camera_rng = ChaCha8Rng::seed_from_u64(purpose_seed(seed, "camera"));
        let camera = self.camera.sample(&mut camera_rng);
        let mut value_rng = ChaCha8Rng::seed_from_u64(purpose_seed(seed, "variables"));
        let values = self.variables.iter().map(|v| Interval::new(v.min, v.max).sample(&mut value_rng)).collect();
        Sample { index, seed, camera, values }
    }

    pub fn default_values(&self) -> Vec<f32> {
        self.variables.iter().map(|v| v.default).collect()
    }

    /// The scene with `values` applied (one per variable, in order), as given: validation has
    /// checked every value of every range against the scene's bounds. The original scene is
    /// untouched; meshes and textures are shared, so this costs a copy of the small tables.
    pub fn instantiate(&self, values: &[f32]) -> Result<Scene> {
        if values.len() != self.variables.len() {
            return Err(Error::bad_input(&self.name, "variables", format!("expected {} values, got {}", self.variables.len(), values.len())));
        }
        let mut s = self.clone();
        for (var, &value) in self.variables.iter().zip(values) {
            if !value.is_finite() {
                return Err(Error::bad_input(&self.name, format!("variables.{}", var.name), "value is not finite"));
            }
            match var.target {
                VariableTarget::Roughness { material } => s.materials[material].roughness = value,
                VariableTarget::Hue { material, saturation, brightness } => s.materials[material].base_color = hsv_to_rgb(value, saturation, brightness),
                VariableTarget::Translation { object, axis } => {
                    let t = &mut s.objects[object].transform;
                    *t = Affine3A::from_translation(axis * value) * *t;
                }
                VariableTarget::LightTranslation { light, axis } => s.rect_lights[light].corner += axis * value,
                VariableTarget::LightIntensity { light } => s.rect_lights[light].radiance = self.rect_lights[light].radiance * value,
                VariableTarget::EmissionIntensity { material } => s.materials[material].emission = self.materials[material].emission * value,
            }
        }
        Ok(s)
    }

    /// Parse `name=value` assignments over the default values.
    pub fn values_from_assignments(&self, assignments: &[String]) -> Result<Vec<f32>> {
        let mut values = self.default_values();
        for a in assignments {
            let (name, value) = a.split_once('=').ok_or_else(|| Error::bad_input("--set", a.clone(), "expected NAME=VALUE"))?;
            let i = self.variables.iter().position(|v| v.name == name.trim()).ok_or_else(|| {
                let known: Vec<&str> = self.variables.iter().map(|v| v.name.as_str()).collect();
                Error::bad_input("--set", name, format!("no such variable (known: {})", known.join(", ")))
            })?;
            let v: f32 = value.trim().parse().map_err(|_| Error::bad_input("--set", name, format!("{value:?} is not a number")))?;
            let var = &self.variables[i];
            if !(var.min..=var.max).contains(&v) {
                return Err(Error::bad_input("--set", name, format!("{v} is outside the range [{}, {}]", var.min, var.max)));
            }
            values[i] = v;
        }
        Ok(values)
    }
}
