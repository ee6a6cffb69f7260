//! The presets: everything a bake sizes, as one value. `tiny` is a smoke test (seconds,
//! meaningless numbers), `quick` a CPU bake (96 px, about half an hour for cornellbox on 2
//! cores), `paper` the paper's resolution and network (a GPU bake).

use glassbake_core::{Error, Result};
use glassbake_net::config::{CnnConfig, PixelGeneratorConfig, RendererConfig, UNetConfig};
use glassbake_net::{NetShape, SuperSamplerConfig, TrainConfig};
use serde::{Deserialize, Serialize};

/// The frames a bake path-traces for its dataset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetSize {
    /// Square resolution of every frame.
    pub resolution: u32,
    /// Samples per pixel of the training and validation ground truth.
    pub spp: u32,
    /// Samples per pixel on the training frames' glass pixels (`None`: `spp`).
    pub glass_spp: Option<u32>,
    /// The most the glass pixels' extra samples (training and test splits alike) may add to
    /// the dataset's frames, as a share of their samples at their split's spp
    /// (`glassbake_dataset::fit_glass_budget`; `None`: no limit).
    #[serde(default)]
    pub glass_budget: Option<f64>,
    pub train: u64,
    pub val: u64,
    pub test: u64,
}

impl DatasetSize {
    pub fn frames(&self) -> u64 {
        self.train + self.val + self.test
    }
}

/// A named size of everything a bake makes: its dataset, the network, how the network is
/// trained, and the super-sampler.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    pub name: String,
    pub dataset: DatasetSize,
    pub network: NetShape,
    pub training: TrainConfig,
    pub super_sampler: SuperSamplerConfig,
}

impl Preset {
    pub const NAMES: [&'static str; 3] = ["tiny", "quick", "paper"];

    /// The preset called `name`: the one place a preset's name is read.
    pub fn named(name: &str) -> Result<Preset> {
        match name {
            "tiny" => Ok(Preset::tiny()),
            "quick" => Ok(Preset::quick()),
            "paper" => Ok(Preset::paper()),
            other => Err(Error::bad_input("--preset", "preset", format!("unknown preset {other:?}; the presets are {}", Preset::NAMES.join(", ")))),
        }
    }

    /// This preset with its networks seeded with `seed` where one is given.
    pub fn with_seed(mut self, seed: Option<u64>) -> Preset {
        self.training.seed = seed.unwrap_or(self.training.seed);
        self
    }

    /// A smoke test: seconds on a CPU, numbers that mean nothing.
    pub fn tiny() -> Preset {
        Preset {
            name: "tiny".into(),
            dataset: DatasetSize { resolution: 32, spp: 4, glass_spp: None, glass_budget: None, train: 8, val: 2, test: 2 },
            network: NetShape::smallest(),
            training: TrainConfig {
                steps: 40,
                batch_size: 2,
                crop: None,
                warmup_steps: 5,
                validate_every: 10,
                checkpoint_every: 10,
                validation_frames: Some(2),
                ..Preset::quick().training
            },
            super_sampler: super_sampler("tiny", 1, 4, 1),
        }
    }

    /// A CPU bake, sized to finish in about half an hour on a 2-core CPU on cornellbox
    /// (docs/benchmarks.md).
    pub fn quick() -> Preset {
        Preset {
            name: "quick".into(),
            // 96 px so that text behind the glass is resolvable; the test split at 8x spp
            // (`glassbake_dataset::default_test_spp`). Glass pixels of training frames at 4x
            // spp: at 96 spp what the camera sees through thick glass is mostly noise to learn
            // from (cornellbox8: the training frames' T.PSNR against the reference 31.6 dB,
            // 40.0 with 384 on glass; GlassNet's T.PSNR +0.7 and +1.2 dB for its two seeds;
            // the dataset takes 30 min, docs/benchmarks.md). Their extra samples add at most
            // three quarters to the frames' samples: where glass fills a quarter of the view
            // or less (cornellbox8's frames 24.7% on average, the other built-in scenes less)
            // nothing changes, and bathroom, whose partition fills 58%, gets 219 spp on glass
            // (1,754 in the test split) and bakes in 49 min on a 2-core box instead of about
            // 66, with no T.PSNR lost beyond its seeds' spread (docs/benchmarks.md).
            dataset: DatasetSize { resolution: 96, spp: 96, glass_spp: Some(4 * 96), glass_budget: Some(0.75), train: 320, val: 24, test: 24 },
            network: NetShape {
                encoding_frequencies: 4,
                scene_encoder: UNetConfig { base_width: 12, levels: 3, out_channels: 12 },
                transparency_encoder: CnnConfig { width: 12, layers: 3, out_channels: 12 },
                blending: UNetConfig { base_width: 12, levels: 3, out_channels: 12 },
                renderer: RendererConfig { width: 16, large_kernel: 5, layers: 1, pointwise_layers: 1 },
                pixel_generator: PixelGeneratorConfig { width: 64, layers: 6, skip_at: 3 },
            },
            // Batch 4 of 32 px crops, 50-100 ms a GlassNet step on a 2-core box with 4 objects
            // (docs/benchmarks.md, `--example train_step`). 6,000 steps of GlassNet and naive:
            // on cornellbox's dataset GlassNet at 3,000 steps was still gaining 0.4 dB of
            // validation PSNR over its last 900; at 6,000 seeds 0 and 1 score 1.5 and 1.3 dB
            // more PSNR, 1.4 and 0.6 more T.PSNR, naive 1.2 / 1.6, and the halo GlassNet drew
            // beside the lights mostly goes; the bake takes about 8 min more on cornellbox
            // (docs/benchmarks.md, 2026-12-03). At 2,000 GlassNet on cornellbox8 was still
            // improving; at 3,000 its two seeds gained 1.0 and 1.3 dB T.PSNR (2026-11-27).
            // Learning rate 1e-3, not 2e-3: at 2e-3 the naive baseline on the
            // default cornellbox dataset stalled at validation loss 0.18 with seed 0 (drawing
            // glass as flat dark blocks) and reached 0.118 with seed 1; at 1e-3 seed 0 trains
            // normally (docs/history/benchmarks-2026-11.md, 2026-11-24).
            training: TrainConfig {
                steps: 6000,
                batch_size: 4,
                crop: Some(32),
                learning_rate: 1e-3,
                weight_decay: 1e-4,
                warmup_steps: 50,
                final_lr_fraction: 0.05,
                ssim_weight: 1.0,
                validate_every: 100,
                checkpoint_every: 100,
                validation_frames: Some(16),
                seed: 0,
            },
            super_sampler: super_sampler("quick", 2, 16, 3),
        }
    }

    /// The paper's resolution, dataset size and network: a GPU bake.
    pub fn paper() -> Preset {
        Preset {
            name: "paper".into(),
            dataset: DatasetSize { resolution: 256, spp: 512, glass_spp: None, glass_budget: None, train: 1800, val: 200, test: 128 },
            network: NetShape {
                encoding_frequencies: 6,
                scene_encoder: UNetConfig { base_width: 32, levels: 4, out_channels: 32 },
                transparency_encoder: CnnConfig { width: 32, layers: 3, out_channels: 32 },
                blending: UNetConfig { base_width: 32, levels: 4, out_channels: 32 },
                renderer: RendererConfig { width: 48, large_kernel: 7, layers: 2, pointwise_layers: 2 },
                // Active Exploration's PixelGenerator: 8 layers of 512, input re-fed midway.
                pixel_generator: PixelGeneratorConfig { width: 512, layers: 8, skip_at: 4 },
            },
            // The paper: Adam, lr 1e-4, weight decay 1e-4 (Appendix table), 256x256.
            training: TrainConfig {
                steps: 100_000,
                batch_size: 8,
                crop: None,
                learning_rate: 1e-4,
                warmup_steps: 500,
                validate_every: 1000,
                checkpoint_every: 1000,
                validation_frames: None,
                ..Preset::quick().training
            },
            super_sampler: super_sampler("paper", 4, 32, 4),
        }
    }
}

fn super_sampler(preset: &str, encoding_frequencies: usize, width: usize, layers: usize) -> SuperSamplerConfig {
    SuperSamplerConfig { preset: preset.into(), encoding_frequencies, network: CnnConfig { width, layers, out_channels: 3 }, light_coverage: true }
}

/// The preset's name, as `--preset` takes it.
impl std::fmt::Display for Preset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name)
    }
}

/// For clap's `value_parser`: `--preset NAME`.
impl std::str::FromStr for Preset {
    type Err = String;

    fn from_str(name: &str) -> std::result::Result<Preset, String> {
        Preset::named(name).map_err(|_| format!("the presets are {}", Preset::NAMES.join(", ")))
    }
}

#[cfg(test)]
mod tests {
    use glassbake_net::{ModelKind, NetConfig};

    use super::*;

    #[test]
    fn every_preset_builds_every_model_and_trains_with_valid_settings() {
        for name in Preset::NAMES {
            let preset = Preset::named(name).unwrap();
            assert_eq!(preset.name, name);
            for kind in ModelKind::ALL {
                let config = NetConfig::new(&preset.network, &preset.name, kind, 3, 4).unwrap();
                assert_eq!(config.preset, name);
            }
            preset.training.check("preset").unwrap();
            preset.super_sampler.check("preset").unwrap();
            assert_eq!(preset.super_sampler.preset, name);
            // A preset's crops, or its whole frames, fit its networks' U-Nets.
            let config = NetConfig::new(&preset.network, &preset.name, ModelKind::Glassnet, 3, 4).unwrap();
            assert_eq!(preset.training.crop.unwrap_or(preset.dataset.resolution) as usize % config.size_multiple(), 0, "{name}");
        }
    }

    #[test]
    fn an_unknown_preset_is_refused_naming_the_known_ones() {
        let err = Preset::named("huge").unwrap_err().to_string();
        assert!(err.contains("huge") && err.contains("tiny, quick, paper"), "{err}");
        assert_eq!("huge".parse::<Preset>().unwrap_err(), "the presets are tiny, quick, paper");
        assert_eq!("paper".parse::<Preset>().unwrap(), Preset::paper());
    }

    #[test]
    fn presets_grow_from_tiny_to_paper() {
        let (tiny, quick, paper) = (Preset::tiny(), Preset::quick(), Preset::paper());
        assert!(tiny.dataset.frames() < quick.dataset.frames() && quick.dataset.frames() < paper.dataset.frames());
        assert!(tiny.dataset.resolution < quick.dataset.resolution && quick.dataset.resolution < paper.dataset.resolution);
        assert!(tiny.network.renderer.width < quick.network.renderer.width && quick.network.renderer.width < paper.network.renderer.width);
        assert!(tiny.training.steps < quick.training.steps && quick.training.steps < paper.training.steps);
    }
}
