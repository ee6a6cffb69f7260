//! What the real-time tests share: small networks and the configuration of a model nobody
//! trained.

#![allow(dead_code)]

use glassbake_net::config::CnnConfig;
use glassbake_net::model_dir::FORMAT_VERSION;
use glassbake_net::{DataSource, ModelConfig, ModelKind, NetConfig, NetShape, Network, SuperSamplerConfig, TrainConfig};
use glassbake_scene::Scene;

/// `network` as a model of the built-in `scene` (by that name) at `resolution`, trained on no
/// dataset.
pub fn untrained(scene: &Scene, network: Network, resolution: u32) -> ModelConfig {
    ModelConfig {
        format_version: FORMAT_VERSION,
        network,
        train: TrainConfig {
            steps: 1,
            batch_size: 1,
            crop: None,
            learning_rate: 1e-3,
            weight_decay: 0.0,
            warmup_steps: 0,
            final_lr_fraction: 1.0,
            ssim_weight: 1.0,
            validate_every: 1,
            checkpoint_every: 1,
            validation_frames: None,
            seed: 0,
        },
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

/// The smallest GlassNet (`NetShape::smallest`) for `scene`'s variables and transparent
/// objects: it reads the through buffers and the light coverage, as a baked one does.
pub fn small_glassnet(scene: &Scene) -> NetConfig {
    NetConfig::new(&NetShape::smallest(), "small", ModelKind::Glassnet, scene.variables.len(), scene.transparent_objects().len()).unwrap()
}

pub fn small_super_sampler() -> SuperSamplerConfig {
    SuperSamplerConfig { preset: "small".into(), encoding_frequencies: 1, network: CnnConfig { width: 4, layers: 1, out_channels: 3 }, light_coverage: true }
}
