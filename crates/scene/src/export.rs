//! Exporting a scene as manifest.toml + glTF.

use std::path::Path;

use glassbake_core::{Error, Result};

use crate::model::Scene;

pub fn export_scene(scene: &Scene, dir: &Path) -> Result<()> {
    let _ = (scene, dir);
    Err(Error::Internal("export not implemented yet".into()))
}
