//! Small scene files the loader tests write themselves, and the check of a refusal.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use glassbake_core::Error;
use serde_json::json;

pub fn write(path: &Path, bytes: impl AsRef<[u8]>) {
    std::fs::write(path, bytes).unwrap();
}

pub fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// A unit quad (two triangles) in the xy-plane as glTF buffer data: positions, uvs, indices.
pub fn quad_buffer() -> Vec<u8> {
    let mut bin = f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0]);
    bin.extend(f32_bytes(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]));
    bin.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    bin
}

/// A glTF document with two nodes sharing the quad: an opaque textured one and a glass one
/// translated by (0, 0, 2) with transmission, IOR and (optionally) volume.
pub fn quad_gltf(buffer_uri: Option<&str>, volume: bool) -> serde_json::Value {
    let mut glass_ext = json!({
        "KHR_materials_transmission": {"transmissionFactor": 1.0},
        "KHR_materials_ior": {"ior": 1.33},
    });
    if volume {
        glass_ext["KHR_materials_volume"] = json!({"thicknessFactor": 0.5});
    }
    let mut buffer = json!({"byteLength": quad_buffer().len()});
    if let Some(uri) = buffer_uri {
        buffer["uri"] = json!(uri);
    }
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume", "KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"name": "wall", "mesh": 0},
            {"name": "glass", "mesh": 1, "translation": [0.0, 0.0, 2.0]},
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "material": 1}]},
        ],
        "materials": [
            {"name": "poster", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "roughnessFactor": 0.7, "metallicFactor": 0.0},
             "emissiveFactor": [1.0, 0.5, 0.0], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}},
            {"name": "glass", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.95, 1.0, 1.0], "roughnessFactor": 0.0, "metallicFactor": 0.0},
             "extensions": glass_ext},
        ],
        "textures": [{"source": 0}],
        "images": [{"uri": "poster.png"}],
        "buffers": [buffer],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
    })
}

/// A 2x1 PNG: left texel sRGB 188 (linear ~0.5), right texel pure red.
pub fn write_poster(dir: &Path) {
    let img = image::RgbaImage::from_raw(2, 1, vec![188, 188, 188, 255, 255, 0, 0, 255]).unwrap();
    img.save(dir.join("poster.png")).unwrap();
}

pub fn write_quad_gltf(dir: &Path, volume: bool) -> PathBuf {
    write_poster(dir);
    write(&dir.join("quad.bin"), quad_buffer());
    let path = dir.join("quad.gltf");
    write(&path, serde_json::to_vec(&quad_gltf(Some("quad.bin"), volume)).unwrap());
    path
}

pub fn expect_bad_input(result: glassbake_core::Result<glassbake_scene::Scene>, file_part: &str, field_part: &str) {
    match result {
        Err(Error::BadInput { file, field, message }) => {
            assert!(file.contains(file_part), "file {file:?} should name {file_part:?}");
            assert!(field.contains(field_part), "field {field:?} should contain {field_part:?} ({message})");
            assert!(!message.contains('\n') && !field.contains('\n'));
        }
        Err(other) => panic!("expected BadInput, got {other}"),
        Ok(_) => panic!("expected an error"),
    }
}
