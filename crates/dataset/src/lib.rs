//! glassbake-dataset: turning a scene into training data, and feeding it to training.
//!
//! It owns the dataset directory format of docs/design.md §4 (`manifest.json`, `gt/NNNNNN.exr`,
//! optional `buffers/NNNNNN.exr`), generation (a camera and variable values per frame, seeded
//! per sample; ground truth path-traced on the CPU or, with `TraceDevice::Wgpu`, a GPU; optionally cached rasterized buffers) with resume after
//! a kill, the glass pixels' sample budget, sharding across machines and the byte-identical merge of shards, the in-place
//! upgrade of an older format's dataset (its ground truth kept), `dataset info`, and
//! the training loader (batches of buffers + ground truth + transparency mask with seeded
//! shuffling and random crops, produced on worker threads).

pub mod format;
pub mod generate;
pub mod glass_budget;
pub mod loader;
pub mod merge;
pub mod store;

pub use format::{DatasetManifest, DatasetSpec, SampleRecord, Split, TraceDevice, FORMAT_VERSION};
pub use generate::{generate, upgrade, GenerateOptions, GenerateProgress, GenerateSummary, ShardSpec, UpgradeSummary};
pub use glass_budget::fit_glass_budget;
pub use loader::{Example, Loader, LoaderOptions};
pub use merge::merge;
pub use store::{DatasetInfo, DatasetStore};
