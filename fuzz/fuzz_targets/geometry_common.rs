//! What the geometry fuzz targets share: arbitrary bytes written as a scene file into a folder
//! of this process's own, loaded as a user's file would be. Loading must give a scene or an
//! error, never a panic, a hang or an allocation the input cannot justify; a scene that loads
//! and validates must hash and report its bounds.

use std::path::PathBuf;
use std::sync::OnceLock;

use glassbake_scene::load::{load_geometry, validate};

/// A material library beside the fuzzed OBJ files (their `mtllib scene.mtl`).
const MATERIALS: &str = "newmtl white\nKd 0.8 0.8 0.8\nnewmtl glass\nKd 1 1 1\nd 0.2\nNi 1.5\nillum 7\n";

fn folder() -> &'static PathBuf {
    static FOLDER: OnceLock<PathBuf> = OnceLock::new();
    FOLDER.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("glassbake-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temp folder");
        std::fs::write(dir.join("scene.mtl"), MATERIALS).expect("the material library");
        dir
    })
}

pub fn load(data: &[u8], extension: &str) {
    let path = folder().join(format!("scene.{extension}"));
    std::fs::write(&path, data).expect("writing the input");
    let label = path.display().to_string();
    if let Ok(scene) = load_geometry(&path) {
        if validate(&scene, &label).is_ok() {
            let _ = scene.content_hash();
            if let Some((lo, hi)) = scene.bounds() {
                assert!(lo.is_finite() && hi.is_finite(), "a validated scene has finite bounds");
            }
        }
    }
}
