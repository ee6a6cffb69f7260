//! glassbake-rays: the scene's triangles behind a BVH, and the rays cast in them.
//!
//! It owns the flattened world-space triangles and their shading attributes (`triangle.rs`,
//! `geometry.rs`), the two ray casters (obvhs' wide BVH, or Intel Embree with the `embree`
//! feature), light at a dielectric interface (`optics.rs`), and the frame's refraction pass
//! (`through.rs`: what each transparent object shows through itself). The ground-truth tracer
//! and the rasterizer's frame both build on it; it knows nothing of either.

pub mod geometry;
pub mod gpu_bvh;
pub mod optics;
pub mod through;
pub mod through_gpu;
pub mod triangle;

#[cfg(feature = "embree")]
mod embree_caster;
#[cfg(not(feature = "embree"))]
mod obvhs_caster;

pub use geometry::{SceneGeometry, RAY_CASTER};
