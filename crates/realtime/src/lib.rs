//! glassbake-realtime: rendering a trained scene frame by frame. It owns the frame pipeline
//! (camera + variable values -> rasterizer: opaque G-buffer, transparency buffers streamed one
//! at a time -> GlassNet -> optional x2 super-sampler -> image), opening a trained model's
//! pipeline, finding a model's scene,
//! synthesising scenes with more or fewer transparent objects for the benchmark, the
//! benchmark itself (frame times, peak memory), the orbit camera within a scene's trained
//! views, and, with the `viewer` feature, the
//! interactive viewer (eframe: egui on wgpu/winit).

pub mod bench;
pub mod gpu_handover;
pub mod memory;
pub mod open;
pub mod orbit;
pub mod pipeline;
pub mod scene_source;
pub mod synth;
#[cfg(feature = "viewer")]
pub mod viewer;

pub use bench::{run_bench, BenchOptions, BenchReport, BenchRow};
pub use open::{open_pipeline, OpenedPipeline, PipelineRequest};
pub use pipeline::{FramePipeline, FrameTimes, Output, ThroughRays};
pub use scene_source::{scene_of_model, ModelScene};
