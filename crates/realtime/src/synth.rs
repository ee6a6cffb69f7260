//! Scenes with a chosen number of transparent objects, for the benchmark's object axis.

use glam::{Affine3A, Vec3};
use glassbake_core::{Error, Result};
use glassbake_scene::Scene;

/// `scene` with exactly `count` transparent objects. With fewer wanted than it has, the last
/// ones are drawn as opaque (they stay in the image; only the transparency buffers go).
/// With more, copies of its transparent objects are added, each shifted sideways by a fifth
/// of the scene's extent per copy round so they do not coincide. Variables keep pointing at
/// the original objects.
pub fn with_transparent_count(scene: &Scene, count: usize) -> Result<Scene> {
    let transparent: Vec<usize> = (0..scene.objects.len()).filter(|&i| scene.objects[i].transparent).collect();
    if transparent.is_empty() {
        return Err(Error::bad_input(&scene.name, "objects", "has no transparent object to vary the count of"));
    }
    let mut out = scene.clone();
    for &i in transparent.iter().skip(count) {
        out.objects[i].transparent = false;
    }
    let extent = scene.bounds().map(|(lo, hi)| (hi - lo).max_element()).unwrap_or(1.0);
    for copy in transparent.len()..count {
        let source = transparent[copy % transparent.len()];
        let round = (copy / transparent.len()) as f32;
        let mut object = scene.objects[source].clone();
        let sign = if copy % 2 == 0 { 1.0 } else { -1.0 };
        object.transform = Affine3A::from_translation(Vec3::new(sign * 0.2 * extent * round, 0.0, 0.0)) * object.transform;
        object.name = format!("{} (copy {})", object.name, copy);
        out.objects.push(object);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_met_both_ways() {
        let scene = glassbake_scene::builtin::builtin("cornellbox").unwrap();
        assert_eq!(scene.transparent_count(), 4);
        for t in [1, 2, 4, 8] {
            let s = with_transparent_count(&scene, t).unwrap();
            assert_eq!(s.transparent_count(), t);
            assert_eq!(s.objects.len(), scene.objects.len() + t.saturating_sub(4));
            // The scene's variables still apply.
            s.instantiate(&s.default_values()).unwrap();
        }
        let copy = &with_transparent_count(&scene, 5).unwrap().objects[scene.objects.len()];
        let first = scene.objects.iter().find(|o| o.transparent).unwrap();
        assert_ne!(copy.transform, first.transform, "a copy is moved");
    }
}
