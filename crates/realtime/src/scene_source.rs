//! The scene a model was trained on: the model's `config.json` records the scene argument and
//! the sampling seed of its dataset (older models: the dataset's manifest does); the scene's
//! content hash must match the model's.

use std::path::Path;

use glassbake_core::{Error, Result};
use glassbake_net::TrainedModel;
use glassbake_scene::{load_scene, Scene};
use serde::Deserialize;

pub struct ModelScene {
    pub scene: Scene,
    /// Seed of the dataset's samples (`--sample i` reproduces its frame i).
    pub dataset_seed: u64,
    /// What was loaded: a built-in name or a path.
    pub source: String,
}

/// Loads the model's scene, or `override_scene` (a built-in name or path) when given; either
/// way its content hash must be the one the model was trained on.
pub fn scene_of_model(model: &TrainedModel, override_scene: Option<&str>) -> Result<ModelScene> {
    let data = &model.files.config.data;
    let config_path = model.files.dir.join("config.json");
    let recorded = match (&data.scene_argument, data.sample_seed) {
        (Some(scene), Some(seed)) => Some((scene.clone(), seed)),
        _ => None,
    };
    let (source, dataset_seed) = match (override_scene, recorded) {
        (Some(s), recorded) => (s.to_string(), recorded.map_or(0, |(_, seed)| seed)),
        (None, Some(recorded)) => recorded,
        (None, None) => dataset_scene_and_seed(Path::new(&data.dataset)).map_err(|e| {
            Error::bad_input(config_path.display(), "data.dataset", format!("cannot read the training dataset to find the scene ({e}); pass --scene"))
        })?,
    };
    let scene = load_scene(&source)?;
    let hash = scene.content_hash();
    if hash != data.scene_hash {
        return Err(Error::bad_input(
            config_path.display(),
            "data.scene_hash",
            format!("the model was trained on scene {} ({}), {source} is {hash}", data.scene, data.scene_hash),
        ));
    }
    Ok(ModelScene { scene, dataset_seed, source })
}

/// The two fields of a dataset's `manifest.json` (docs/design.md §4) that a model trained
/// before its config recorded them needs: read here rather than through the dataset crate,
/// which would bring both path tracers into the real-time renderer.
fn dataset_scene_and_seed(dataset: &Path) -> Result<(String, u64)> {
    #[derive(Deserialize)]
    struct Manifest {
        spec: Spec,
    }
    #[derive(Deserialize)]
    struct Spec {
        scene: String,
        seed: u64,
    }
    let path = dataset.join("manifest.json");
    let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
    let manifest: Manifest = serde_json::from_slice(&bytes).map_err(|e| Error::bad_input(path.display(), "spec", e.to_string()))?;
    Ok((manifest.spec.scene, manifest.spec.seed))
}
