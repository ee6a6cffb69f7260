//! glassbake-raster: the headless wgpu rasterizer that makes the network's inputs.
//!
//! It owns, for a scene instance + camera + resolution: the opaque G-buffer (opaque geometry
//! only), the naive G-buffer (glass drawn over what is behind it, the paper's baseline input),
//! and one transparency buffer per transparent object (that object alone, its front-most
//! visible surface, with relative depth and coverage), in the channel layout of
//! `glassbake_core::layout` (docs/design.md §3); the direct light L_d from rectangle lights
//! (diffuse: exact polygon form factor; GGX specular: Linearly Transformed Cosines, fitted by
//! [`ltc`]) with shadow maps, plus emission; Vulkan adapter selection (lavapipe on CPU-only
//! machines); [`composition`], the share of glass pixels with textured detail behind them;
//! [`light_coverage`], the share of each pixel that sees a light, from a finer rasterization;
//! [`display`], a network's image into a texture a window shows; [`headless`], the
//! environment a process without a display gives the Vulkan driver.
//! Buffer semantics are documented on [`Rasterizer`] and in `shaders/gbuffer.wgsl`.

pub mod composition;
pub mod device;
pub mod display;
mod frame_data;
pub mod headless;
pub mod light_coverage;
pub mod ltc;
mod rasterizer;
mod resources;
mod unpack;

pub use device::{PowerPreference, RasterizerOptions};
pub use rasterizer::{Frame, FrameBuffers, Rasterizer, MAX_RESOLUTION};
pub use wgpu;
