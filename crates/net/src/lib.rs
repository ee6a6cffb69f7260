//! glassbake-net: GlassNet (paper 3.4) in burn. It owns the networks — scene encoder F,
//! the permutation-invariant transparency encoder T with its exact order-independent sum,
//! blending B, renderer R, positional encoding — the `naive` and `concat` baselines, the x2
//! super-sampler, the L1 + SSIM loss, the training loop with checkpoints and exact resume, the
//! model directory format, and inference, with the convolutions' matrix-product paths
//! (`convolution`) and the operations it runs as single passes on the CPU backend (`flex_ops`).
//! It reads frames as `glassbake_core` images and knows nothing of how they were made (the CLI
//! connects the dataset loader to it).

pub mod allocator;
pub mod batch;
pub mod blocks;
pub mod config;
pub mod convolution;
pub mod device;
#[cfg(not(target_arch = "wasm32"))]
pub mod flex_ops;
pub mod hash_grid;
pub mod infer;
pub mod init;
pub mod loss;
pub mod model;
pub mod model_dir;
pub mod precision;
pub mod sum;
pub mod super_sampler;
pub mod train;

pub use allocator::keep_freed_memory;
pub use batch::{FrameRef, HostBatch};
pub use config::{ModelKind, Modulator, NetConfig, NetShape, TrainConfig};
pub use device::{is_cpu, select_device, select_devices, DeviceChoice};
pub use infer::{TrainedModel, TrainedSuperSampler};
pub use model::{load_model, new_model, with_new_model, Concat, GlassNet, ModelTask, Naive, NetInputs, PixelGen, SceneModel};
pub use model_dir::{DataSource, ModelConfig, ModelFiles, Network};
pub use super_sampler::{SuperSampler, SuperSamplerConfig};
pub use train::{train, RunOptions, TrainEvent, TrainSummary, Trainable, TrainingData};

pub use burn;
