//! Mitsuba 3 XML export of one scene instance.

use std::path::Path;

use glassbake_core::{Camera, Error, Result};

use crate::model::Scene;

pub fn write_mitsuba(scene: &Scene, camera: &Camera, out: &Path) -> Result<()> {
    let _ = (scene, camera, out);
    Err(Error::Internal("mitsuba export not implemented yet".into()))
}
