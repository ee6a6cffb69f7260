//! The scene a model was trained on: the dataset manifest its `config.json` names records the
//! scene argument and the sampling seed; the scene's content hash must match the model's.

use std::path::Path;

use glassbake_core::{Error, Result};
use glassbake_net::TrainedModel;
use glassbake_scene::{load_scene, Scene};

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
    let (source, dataset_seed) = match override_scene {
        Some(s) => (s.to_string(), 0),
        None => {
            let manifest = glassbake_dataset::store::read_manifest(Path::new(&data.dataset)).map_err(|e| {
                Error::bad_input(config_path.display(), "data.dataset", format!("cannot read the training dataset to find the scene ({e}); pass --scene"))
            })?;
            (manifest.spec.scene, manifest.spec.seed)
        }
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
