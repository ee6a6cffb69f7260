//! glassbake-core: the foundations every pipeline stage shares.
//!
//! It owns the camera convention (docs/design.md §2), the planar float image type with named
//! channels and its EXR/PNG I/O, the buffer channel layout of docs/design.md §3 (the one place
//! where channel names are spelled), per-sample seed derivation, tone mapping, the one-writer
//! lock and the ownership rule of an output folder, SHA-256 checksums of files read back
//! later, PNG previews of a buffer attribute, the constants WGSL shaders take from Rust, and
//! the error type whose "bad input" variant the CLI turns into exit code 2.

pub mod camera;
pub mod checksum;
pub mod color;
pub mod error;
pub mod image;
pub mod layout;
pub mod lock;
pub mod output_dir;
pub mod preview;
pub mod seed;
pub mod wgsl;

pub use camera::{Camera, Ray};
pub use error::{Error, Result};
pub use glam;
pub use image::PlanarImage;
