//! glassbake-bake: the bake as a library. Owns the presets (`Preset`: a dataset's size and
//! spp, the network, its training and the super-sampler, as one value), the training data
//! pipeline (a dataset's frames as network batches), training a model or a super-sampler on a
//! dataset, and the whole bake: dataset -> models -> evaluation -> report, each stage resumed
//! where a killed run stopped. The `glassbake` binary parses arguments into these requests
//! and prints what they report; a program that bakes from its own code calls the same
//! functions and gets the same files:
//!
//! ```no_run
//! use glassbake_bake::{bake, BakeRequest, Preset, Progress};
//!
//! let mut preset = Preset::quick();
//! preset.training.steps = 1000; // a preset is a plain value
//! let request = BakeRequest::new("cornellbox", preset, "bakes/cornellbox");
//! let result = bake(&request, &Progress::silent())?;
//! print!("{}", result.summary.text_table());
//! # Ok::<(), glassbake_core::Error>(())
//! ```

pub mod ablation;
pub mod bake;
pub mod dataset;
pub mod evaluation;
pub mod preset;
pub mod progress;
pub mod seed_choice;
pub mod training;

pub use ablation::Ablation;
pub use bake::{bake, BakeRequest, BakeResult};
pub use dataset::{make_dataset, DatasetRequest};
pub use evaluation::evaluate;
pub use preset::{DatasetSize, Preset};
pub use progress::Progress;
pub use seed_choice::SeedChoice;
pub use training::{train_model, train_super_sampler, SuperSamplerRequest, TrainOverrides, TrainRequest};
