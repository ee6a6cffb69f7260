//! Fuzz the manifest parser and its application to a scene: arbitrary text must give a
//! manifest or an error, never a panic; an accepted scene must sample and instantiate.
#![no_main]

use std::sync::OnceLock;

use glassbake_scene::builtin::builtin;
use glassbake_scene::load::{apply_manifest, validate};
use glassbake_scene::manifest::parse_manifest;
use glassbake_scene::Scene;
use libfuzzer_sys::fuzz_target;

fn base() -> &'static Scene {
    static BASE: OnceLock<Scene> = OnceLock::new();
    BASE.get_or_init(|| builtin("cornell-glass").expect("built-in scene"))
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(manifest) = parse_manifest(text) else { return };
    let mut scene = base().clone();
    if apply_manifest(&mut scene, &manifest, "fuzz.toml").is_ok() && validate(&scene, "fuzz.toml").is_ok() {
        for i in 0..4 {
            let sample = scene.sample(7, i);
            assert!(sample.camera.position.is_finite());
            scene.instantiate(&sample.values).expect("sampled values are valid");
        }
    }
});
