//! What the real-time tests share: the configuration of a model nobody trained.

use glassbake_net::model_dir::FORMAT_VERSION;
use glassbake_net::{DataSource, ModelConfig, Network, TrainConfig};
use glassbake_scene::Scene;

/// `network` as a model of the built-in `scene` (by that name) at `resolution`, trained on no
/// dataset.
pub fn untrained(scene: &Scene, network: Network, resolution: u32) -> ModelConfig {
    ModelConfig {
        format_version: FORMAT_VERSION,
        network,
        train: TrainConfig::preset("tiny").unwrap(),
        data: DataSource {
            dataset: "untrained".into(),
            scene: scene.name.clone(),
            scene_hash: String::new(),
            resolution,
            scene_argument: Some(scene.name.clone()),
            sample_seed: Some(0),
            dataset_sha256: None,
        },
    }
}
