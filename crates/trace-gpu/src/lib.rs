//! glassbake-trace-gpu: the ground-truth path tracer in wgpu compute shaders.
//!
//! It owns the GPU side of ground truth: flattening a scene instance into storage buffers
//! (a binary BVH, built and traversed by the rays crate's `gpu_bvh`, triangles, materials, textures, the CPU tracer's emitter
//! table), the WGSL port of the CPU tracer's BSDFs, light sampling and its `plain` estimator
//! (`shaders/`: next-event estimation through smooth thin panes, MIS, area sampling of
//! lights picked by power, Russian roulette), and the passes that accumulate samples per
//! pixel. Images are deterministic on one device (counter-based random numbers per pixel,
//! sample and dimension) and converge to the CPU tracer's; they are not bit-identical to it.
//! [`probe`] runs the GPU BSDF and light sampler on given inputs for tests.

pub mod probe;
mod tracer;
mod upload;

pub use tracer::{GpuTracer, SAMPLES_PER_THREAD, SAMPLES_PER_THREAD_LAVAPIPE};
pub use upload::{SceneBuffers, MAX_BVH_DEPTH};
