//! glassbake-trace: the ground-truth CPU path tracer.
//!
//! It owns everything between a scene instance plus a camera and a linear-RGB radiance
//! image: the BVH over the scene's triangles (obvhs, or Intel Embree with the `embree` feature), the BSDFs of the scene model (glTF
//! metallic-roughness, smooth / rough / thin dielectrics), rectangle and emissive-mesh
//! lights (rectangles sampled by solid angle), a unidirectional path tracer with
//! next-event estimation, MIS, Russian roulette and path guiding (an SD-tree learned over
//! the first passes), a light tracer for the light that reaches surfaces through glass
//! (the `caustic` estimator), adaptive sampling (a pilot pass spreads the samples where
//! the noise is), stratified (randomized quasi-Monte Carlo) sample values, opt-in photon merging
//! (biased) of what the camera sees through bending glass, and the tiling over threads that keeps images bit-identical
//! whatever the thread count. The dataset stage calls [`render`] once per sample; the CLI's `trace`
//! command wraps it.

pub mod adaptive;
pub mod bsdf;
#[cfg(feature = "embree")]
mod embree_caster;
pub mod geometry;
pub mod glass_cones;
pub mod guiding;
pub mod integrator;
pub mod light_tracing;
pub mod lights;
pub mod microfacet;
#[cfg(not(feature = "embree"))]
mod obvhs_caster;
pub mod photon_merging;
pub mod qmc;
pub mod render;
pub mod rng;
pub mod sampling;
pub mod spherical_rect;

#[cfg(test)]
mod bsdf_tests;

/// The tracers' revision (CPU and GPU): raised by every change after which the same scene,
/// camera, settings and seed give another image (other sample values, another estimator
/// behind the same name), and by nothing else. Datasets record it, so that one is continued
/// or merged only by the revision that traced its frames: its promise is the bytes a fresh run
/// makes. Revision 1: 2026-11-25 (before it, datasets recorded none).
pub const TRACER_REVISION: u32 = 1;

pub use bsdf::{Bsdf, MaterialModel, SurfaceMaterial};
pub use geometry::RAY_CASTER;
pub use integrator::{Integrator, PathFilter, PathRadiance, PreparedScene, SurfaceHit};
pub use render::{glass_pixels, render, sample_trace_seed, unlit_warning, Progress, TraceOutput, TraceSettings};
