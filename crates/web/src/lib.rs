//! glassbake-web: a baked scene as a static web site that renders GlassNet in the browser.
//!
//! It owns the site's description ([`site`]: `site.json`, read by the page and written by the
//! export), the export itself ([`export`], native only: `glassbake export-web` writes the page,
//! the module built by tools/web/build.sh, the model and the scene into one folder any static
//! server serves) and, compiled for wasm32, the page's side of the module ([`page`]): the
//! frame of `glassbake render` (the same `FramePipeline`) on the browser's WebGPU device,
//! drawn into a canvas.

#[cfg(not(target_arch = "wasm32"))]
pub mod export;
#[cfg(target_arch = "wasm32")]
pub mod page;
pub mod site;

pub use site::{SceneSource, SiteManifest, SiteVariable, SITE_FILE};
