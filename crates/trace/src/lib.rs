//! glassbake-trace: the ground-truth CPU path tracer.
//!
//! It owns everything between a scene instance plus a camera and a linear-RGB radiance
//! image. Read it top-down: [`Estimator`] (`estimator.rs`) names what traces an image and its
//! `Default` is the ground truth's; [`render`] (`render/`, the image driver) runs the passes
//! over tiles; `integrator.rs` is the plain path tracer (next-event estimation, MIS, Russian
//! roulette) with the hooks through which the caustic estimator (`caustic_paths.rs`, its light
//! tracer `light_tracing.rs`, opt-in photon merging `photon_merging.rs`) leaves out the paths
//! it carries otherwise. Below them: the prepared scene (`prepared.rs`: hits, materials,
//! shadow segments), the BVH and its rays (glassbake-rays: obvhs, or Intel Embree with the
//! `embree` feature), BSDFs (`bsdf.rs`, glTF metallic-roughness and smooth / rough / thin dielectrics),
//! lights (`lights.rs`), adaptive sampling (`adaptive.rs`) and stratified sample values
//! (`qmc.rs`). Images are bit-identical whatever the thread count. The dataset stage calls
//! [`render`] once per sample; the CLI's `trace` command wraps it.

pub mod adaptive;
pub mod bsdf;
mod caustic_paths;
pub mod estimator;
pub mod glass_cones;
pub mod integrator;
pub mod light_tracing;
pub mod lights;
pub mod microfacet;
pub mod path_class;
pub mod photon_merging;
pub mod prepared;
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
/// makes. Revision 1: 2026-11-25 (before it, datasets recorded none). Revision 2: 2026-11-27,
/// the `caustic` transport takes the light of emitters reflected in smooth glass that the
/// camera sees at every sample (`integrator.rs`, `PreparedScene::reflected_emission`), and
/// stratified sampling stratifies smooth glass's Fresnel choice. Revision 3: 2026-11-27, the
/// `caustic` transport's shadow rays follow smooth glass from surfaces the camera sees in or
/// through bending glass (`PreparedScene::light_through_glass`).
pub const TRACER_REVISION: u32 = 3;

pub use bsdf::{Bsdf, MaterialModel, SurfaceMaterial};
pub use estimator::{Estimator, Transport};
pub use glassbake_rays::{geometry, triangle, RAY_CASTER};
pub use integrator::PathRadiance;
pub use path_class::PathFilter;
pub use prepared::{PreparedScene, SurfaceHit};
pub use render::{glass_pixels, render, sample_trace_seed, transparent_object_per_pixel, unlit_warning, Progress, TraceOutput, TraceSettings};
