//! glassbake-rays: the scene's triangles behind a BVH, and the rays cast in them.
//!
//! It owns the flattened world-space triangles and their shading attributes (`triangle.rs`,
//! `geometry.rs`), the two ray casters (obvhs' wide BVH, or Intel Embree with the `embree`
//! feature), light at a dielectric interface (`optics.rs`), the frame's refraction pass
//! (`through.rs`: what each transparent object shows through itself, lit where the camera
//! does not see it by the lights' direct light, `direct.rs`) and its wgpu twin
//! (`through_gpu.rs`), the BVH layout and WGSL traversal GPU kernels share (`gpu_bvh.rs`,
//! `shaders/bvh.wgsl`), and what every GPU pass shares: bind groups kept across frames
//! (`gpu_cache.rs`) and the count of what the passes create and wait for (`gpu_stats.rs`).
//! The ground-truth tracers and the rasterizer's frame build on it; it knows nothing of them.

pub mod direct;
pub mod geometry;
pub mod gpu_bvh;
pub mod gpu_cache;
pub mod gpu_errors;
pub mod gpu_readback;
pub mod gpu_scene;
pub mod gpu_stats;
pub mod optics;
pub mod through;
pub mod through_gpu;
pub mod triangle;

#[cfg(feature = "embree")]
mod embree_caster;
#[cfg(not(feature = "embree"))]
mod obvhs_caster;

pub use geometry::{SceneGeometry, RAY_CASTER};
