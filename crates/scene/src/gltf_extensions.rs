//! Which glTF extensions glassbake reads, warns about or refuses, and the
//! KHR_texture_transform matrix.
//!
//! A file lists the extensions it uses in `extensionsUsed` and those a reader must
//! understand in `extensionsRequired`. Every required extension outside [`SUPPORTED`] is an
//! error naming it; every used one outside it a warning naming it and what is lost. The lists
//! are read from the file's JSON before the gltf crate parses it: its own check names only
//! the array index, and (gltf 1.4.1) refuses two extensions it parses.

use glam::{Affine2, Mat2, Vec2};
use glassbake_core::{Error, Result};

/// Extensions glassbake renders as their specifications say.
pub const SUPPORTED: &[&str] = &[
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_volume",
    "KHR_materials_emissive_strength",
    "KHR_materials_specular",
    "KHR_texture_transform",
];

/// Extensions read in part or ignored, each with what a user loses.
pub const WARNED: &[(&str, &str)] = &[
    ("KHR_lights_punctual", "lights are ignored: declare rectangle lights in a manifest"),
    ("KHR_materials_clearcoat", "the clear-coat layer is not rendered"),
    ("KHR_materials_sheen", "the sheen layer is not rendered"),
    ("KHR_materials_iridescence", "iridescence is not rendered"),
    ("KHR_materials_anisotropy", "anisotropy is not rendered (isotropic GGX)"),
    ("KHR_materials_dispersion", "dispersion is not rendered (one IOR for all wavelengths)"),
    ("KHR_materials_unlit", "unlit materials are shaded as lit"),
    ("KHR_materials_variants", "only the default material of each primitive is used"),
];

/// The `extensionsUsed` and `extensionsRequired` lists of a .gltf or .glb file's bytes.
pub fn declared_extensions(bytes: &[u8], label: &str) -> Result<(Vec<String>, Vec<String>)> {
    let json: &[u8] = if bytes.starts_with(b"glTF") {
        // GLB: 12-byte header, then the JSON chunk (length, type "JSON", data).
        let chunk_length = bytes.get(12..16).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
        match chunk_length.and_then(|n| bytes.get(20..20 + n)) {
            Some(chunk) if bytes.get(16..20) == Some(b"JSON".as_slice()) => chunk,
            _ => return Err(Error::bad_input(label, "GLB header", "no JSON chunk after the 12-byte header")),
        }
    } else {
        bytes
    };
    let root: serde_json::Value = serde_json::from_slice(json).map_err(|e| Error::bad_input(label, "glTF JSON", e.to_string()))?;
    let list = |key: &str| -> Vec<String> {
        root.get(key).and_then(|v| v.as_array()).map(|a| a.iter().filter_map(|e| e.as_str().map(str::to_string)).collect()).unwrap_or_default()
    };
    Ok((list("extensionsUsed"), list("extensionsRequired")))
}

/// Refuses unsupported required extensions; returns the warnings for unsupported used ones.
pub fn check_extensions(used: &[String], required: &[String], label: &str) -> Result<Vec<String>> {
    for (i, name) in required.iter().enumerate() {
        if !SUPPORTED.contains(&name.as_str()) {
            return Err(Error::bad_input(
                label,
                format!("extensionsRequired[{i}]"),
                format!("{name} is required by the file but not supported by glassbake (supported: {})", SUPPORTED.join(", ")),
            ));
        }
    }
    let mut warnings = Vec::new();
    for name in used {
        if SUPPORTED.contains(&name.as_str()) {
            continue;
        }
        let what = WARNED.iter().find(|(n, _)| n == name).map_or("it is ignored", |(_, what)| what);
        warnings.push(format!("extensionsUsed: {name}: {what}"));
    }
    Ok(warnings)
}

/// KHR_texture_transform's matrix: uv' = translation(offset) x rotation(rotation) x
/// scale(scale) x uv, with the specification's rotation sense (counter-clockwise in UV space
/// seen with v pointing down).
pub fn texture_transform_matrix(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> Affine2 {
    let (sin, cos) = rotation.sin_cos();
    // Column-major: the specification's rotation matrix is [[cos, sin], [-sin, cos]] by rows.
    let rotate = Mat2::from_cols(Vec2::new(cos, -sin), Vec2::new(sin, cos));
    let scale = Mat2::from_diagonal(Vec2::from(scale));
    Affine2::from_mat2_translation(rotate * scale, Vec2::from(offset))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn required_unsupported_extensions_are_refused_by_name() {
        let required = vec!["KHR_materials_specular".to_string(), "KHR_draco_mesh_compression".to_string()];
        let err = check_extensions(&required, &required, "scene.gltf").unwrap_err().to_string();
        assert!(err.contains("KHR_draco_mesh_compression") && err.contains("extensionsRequired[1]") && err.contains("scene.gltf"), "{err}");
    }

    #[test]
    fn used_unsupported_extensions_are_warned_by_name() {
        let used: Vec<String> = ["KHR_materials_specular", "KHR_materials_clearcoat", "EXT_something"].map(String::from).to_vec();
        let warnings = check_extensions(&used, &[], "scene.gltf").unwrap();
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].contains("KHR_materials_clearcoat") && warnings[0].contains("clear-coat"));
        assert!(warnings[1].contains("EXT_something") && warnings[1].contains("ignored"));
    }

    /// The specification's example: offset (0, 1), rotation pi/2, scale (0.5, 0.5) "utilizes
    /// only the lower left quadrant of the source image" (v runs down): the unit square lands
    /// on [0, 0.5] x [0.5, 1].
    #[test]
    fn texture_transform_follows_the_specification() {
        let m = texture_transform_matrix([0.0, 1.0], std::f32::consts::FRAC_PI_2, [0.5, 0.5]);
        for corner in [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE] {
            let p = m.transform_point2(corner);
            assert!((-1e-6..=0.5 + 1e-6).contains(&p.x) && (0.5 - 1e-6..=1.0 + 1e-6).contains(&p.y), "{corner} -> {p}");
        }
        let m = texture_transform_matrix([0.5, 0.25], 0.0, [2.0, 3.0]);
        assert!((m.transform_point2(Vec2::new(1.0, 1.0)) - Vec2::new(2.5, 3.25)).length() < 1e-6);
        // Rotation by +90 degrees: (1, 0) -> (cos, -sin) = (0, -1) in the specification's
        // matrix [[cos, sin, 0], [-sin, cos, 0]] applied to (u, v, 1).
        let r = texture_transform_matrix([0.0, 0.0], std::f32::consts::FRAC_PI_2, [1.0, 1.0]);
        let p = r.transform_point2(Vec2::new(1.0, 0.0));
        assert!((p - Vec2::new(0.0, -1.0)).length() < 1e-6, "{p}");
        let q = r.transform_point2(Vec2::new(0.0, 1.0));
        assert!((q - Vec2::new(1.0, 0.0)).length() < 1e-6, "{q}");
    }
}
