//! Exporting a scene as `manifest.toml` + `scene.gltf` + `scene.bin` + texture PNGs, so users
//! see the format with a real example and can edit built-in scenes in Blender.

use std::path::Path;

use glam::{Vec3, Vec4};
use glassbake_core::color::linear_to_srgb;
use glassbake_core::image::{write_atomically, write_bytes_atomically};
use glassbake_core::{Error, Result};
use serde_json::{json, Value};

use crate::camera_spec::CameraPosition;
use crate::manifest::{CameraManifest, LightManifest, Manifest, NumberOrRange, ObjectOverride, PositionManifest, TargetManifest, VariableManifest};
use crate::model::{Scene, Texture};
use crate::variables::VariableTarget;

const GLTF_FILE: &str = "scene.gltf";
const BIN_FILE: &str = "scene.bin";

/// Little-endian binary buffer with 4-byte aligned views, as glTF requires.
#[derive(Default)]
struct BinaryBuffer {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl BinaryBuffer {
    fn push_view(&mut self, data: &[u8], target: u32) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len(), "target": target}));
        self.bytes.extend_from_slice(data);
        self.views.len() - 1
    }

    fn vec_accessor(&mut self, values: &[f32], components: usize, kind: &str, with_bounds: bool) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.push_view(&bytes, 34962);
        let mut accessor = json!({"bufferView": view, "componentType": 5126, "count": values.len() / components, "type": kind});
        if with_bounds {
            let (mut lo, mut hi) = (vec![f32::INFINITY; components], vec![f32::NEG_INFINITY; components]);
            for chunk in values.chunks_exact(components) {
                for (c, &v) in chunk.iter().enumerate() {
                    lo[c] = lo[c].min(v);
                    hi[c] = hi[c].max(v);
                }
            }
            accessor["min"] = json!(lo);
            accessor["max"] = json!(hi);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn index_accessor(&mut self, indices: &[[u32; 3]]) -> usize {
        let bytes: Vec<u8> = indices.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.push_view(&bytes, 34963);
        self.accessors.push(json!({"bufferView": view, "componentType": 5125, "count": indices.len() * 3, "type": "SCALAR"}));
        self.accessors.len() - 1
    }
}

/// 8-bit PNG bytes of a texture (sRGB-encoded for colour textures, raw for data textures).
pub fn texture_png(texture: &Texture) -> Result<Vec<u8>> {
    let encode = |v: f32| {
        let v = if texture.is_color { linear_to_srgb(v) } else { v.clamp(0.0, 1.0) };
        (v * 255.0 + 0.5) as u8
    };
    let bytes: Vec<u8> =
        texture.texels.iter().flat_map(|t: &Vec4| [encode(t.x), encode(t.y), encode(t.z), (t.w.clamp(0.0, 1.0) * 255.0 + 0.5) as u8]).collect();
    let img = image::RgbaImage::from_raw(texture.width, texture.height, bytes).ok_or_else(|| Error::Internal("texture size".into()))?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| Error::Internal(format!("encoding texture {}: {e}", texture.name)))?;
    Ok(png)
}

fn texture_file_name(index: usize, texture: &Texture) -> String {
    let safe: String = texture.name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' || c == '-' { c } else { '_' }).collect();
    format!("texture{index}_{safe}.png")
}

/// The glTF JSON document and binary buffer of a scene's geometry and materials.
fn gltf_document(scene: &Scene) -> (Value, Vec<u8>) {
    let mut buffer = BinaryBuffer::default();
    let meshes: Vec<Value> = scene
        .meshes
        .iter()
        .map(|mesh| {
            let positions: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
            let normals: Vec<f32> = mesh.normals.iter().flat_map(|n| n.to_array()).collect();
            let uvs: Vec<f32> = mesh.uvs.iter().flat_map(|t| t.to_array()).collect();
            let position = buffer.vec_accessor(&positions, 3, "VEC3", true);
            let normal = buffer.vec_accessor(&normals, 3, "VEC3", false);
            let uv = buffer.vec_accessor(&uvs, 2, "VEC2", false);
            let indices = buffer.index_accessor(&mesh.indices);
            json!({"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal, "TEXCOORD_0": uv}, "indices": indices, "mode": 4}]})
        })
        .collect();
    // One glTF mesh per object, so that each object keeps its own material.
    let mut gltf_meshes = Vec::new();
    let mut nodes = Vec::new();
    for o in &scene.objects {
        let mut mesh = meshes[o.mesh].clone();
        mesh["primitives"][0]["material"] = json!(o.material);
        mesh["name"] = json!(o.name);
        gltf_meshes.push(mesh);
        let matrix = glam::Mat4::from(o.transform).to_cols_array();
        let mut node = json!({"name": o.name, "mesh": gltf_meshes.len() - 1});
        if matrix != glam::Mat4::IDENTITY.to_cols_array() {
            node["matrix"] = json!(matrix);
        }
        nodes.push(node);
    }
    let mut used_extensions = std::collections::BTreeSet::new();
    let materials: Vec<Value> = scene
        .materials
        .iter()
        .map(|m| {
            let mut pbr = json!({
                "baseColorFactor": [m.base_color.x, m.base_color.y, m.base_color.z, 1.0],
                "metallicFactor": m.metallic,
                "roughnessFactor": m.roughness,
            });
            if let Some(t) = m.base_color_texture {
                pbr["baseColorTexture"] = json!({"index": t});
            }
            if let Some(t) = m.roughness_texture {
                pbr["metallicRoughnessTexture"] = json!({"index": t});
            }
            let mut material = json!({"name": m.name, "pbrMetallicRoughness": pbr, "doubleSided": true});
            let mut extensions = serde_json::Map::new();
            let strength = m.emission.max_element();
            if strength > 0.0 {
                let factor = m.emission / strength;
                material["emissiveFactor"] = json!(factor.to_array());
                if strength != 1.0 {
                    extensions.insert("KHR_materials_emissive_strength".into(), json!({"emissiveStrength": strength}));
                }
            }
            if !m.has_default_specular() {
                let mut specular = json!({"specularFactor": m.specular, "specularColorFactor": m.specular_color.to_array()});
                if let Some(t) = m.specular_texture {
                    specular["specularTexture"] = json!({"index": t});
                }
                if let Some(t) = m.specular_color_texture {
                    specular["specularColorTexture"] = json!({"index": t});
                }
                extensions.insert("KHR_materials_specular".into(), specular);
            }
            if let Some(t) = m.transmission {
                extensions.insert("KHR_materials_transmission".into(), json!({"transmissionFactor": t.weight}));
                extensions.insert("KHR_materials_ior".into(), json!({"ior": t.ior}));
                if !t.thin {
                    // Any positive thickness marks a solid (non-thin-walled) volume.
                    extensions.insert("KHR_materials_volume".into(), json!({"thicknessFactor": 1.0}));
                }
            }
            used_extensions.extend(extensions.keys().cloned());
            if !extensions.is_empty() {
                material["extensions"] = Value::Object(extensions);
            }
            material
        })
        .collect();
    let images: Vec<Value> = scene.textures.iter().enumerate().map(|(i, t)| json!({"uri": texture_file_name(i, t), "name": t.name})).collect();
    let textures: Vec<Value> = (0..scene.textures.len()).map(|i| json!({"source": i, "sampler": 0})).collect();
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": "glassbake scene export"},
        "scene": 0,
        "scenes": [{"name": scene.name, "nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": gltf_meshes,
        "materials": materials,
        "buffers": [{"uri": BIN_FILE, "byteLength": buffer.bytes.len()}],
        "bufferViews": buffer.views,
        "accessors": buffer.accessors,
    });
    if !images.is_empty() {
        doc["images"] = json!(images);
        doc["textures"] = json!(textures);
        // Repeat wrapping with trilinear filtering.
        doc["samplers"] = json!([{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]);
    }
    if !used_extensions.is_empty() {
        doc["extensionsUsed"] = json!(used_extensions);
    }
    (doc, buffer.bytes)
}

fn range(min: f32, max: f32) -> NumberOrRange {
    if min == max {
        NumberOrRange::Number(min)
    } else {
        NumberOrRange::Range(vec![min, max])
    }
}

/// The manifest describing what glTF cannot hold (camera ranges, rectangle lights, variables).
pub fn manifest_of(scene: &Scene, geometry: &str) -> Manifest {
    let c = &scene.camera;
    let position = match c.position {
        CameraPosition::Box { min, max } => PositionManifest::Box { min: min.to_array(), max: max.to_array() },
        CameraPosition::Orbit { center, radius, azimuth_deg, elevation_deg } => PositionManifest::Orbit {
            center: center.to_array(),
            radius: range(radius.min, radius.max),
            azimuth_deg: range(azimuth_deg.min, azimuth_deg.max),
            elevation_deg: range(elevation_deg.min, elevation_deg.max),
        },
    };
    let variables = scene
        .variables
        .iter()
        .map(|v| {
            let material = |m: usize| scene.materials[m].name.clone();
            let target = match v.target {
                VariableTarget::Roughness { material: m } => TargetManifest::Roughness { material: material(m) },
                VariableTarget::Hue { material: m, saturation, brightness } => TargetManifest::Hue { material: material(m), saturation, brightness },
                VariableTarget::Translation { object, axis } => {
                    TargetManifest::Translation { object: scene.objects[object].name.clone(), axis: axis.to_array() }
                }
                VariableTarget::LightTranslation { light, axis } => {
                    TargetManifest::LightTranslation { light: scene.rect_lights[light].name.clone(), axis: axis.to_array() }
                }
                VariableTarget::LightIntensity { light } => TargetManifest::LightIntensity { light: scene.rect_lights[light].name.clone() },
                VariableTarget::EmissionIntensity { material: m } => TargetManifest::EmissionIntensity { material: material(m) },
            };
            VariableManifest { name: v.name.clone(), range: vec![v.min, v.max], default: Some(v.default), target }
        })
        .collect();
    // Record transparency flags that differ from what the materials imply.
    let objects = scene
        .objects
        .iter()
        .filter(|o| o.transparent != scene.materials[o.material].is_transmissive())
        .map(|o| (o.name.clone(), ObjectOverride { transparent: Some(o.transparent), thin: None }))
        .collect();
    Manifest {
        name: Some(scene.name.clone()),
        geometry: geometry.to_string(),
        background: (scene.background != Vec3::ZERO).then(|| scene.background.to_array()),
        camera: Some(CameraManifest {
            position,
            target: c.target.to_array(),
            target_jitter: (c.target_jitter != Vec3::ZERO).then(|| c.target_jitter.to_array()),
            up: Some(c.up.to_array()),
            fov_x_deg: range(c.fov_x_deg.min, c.fov_x_deg.max),
            near: Some(c.near),
            far: Some(c.far),
        }),
        lights: scene
            .rect_lights
            .iter()
            .map(|l| LightManifest {
                name: l.name.clone(),
                corner: l.corner.to_array(),
                edge_u: l.edge_u.to_array(),
                edge_v: l.edge_v.to_array(),
                radiance: l.radiance.to_array(),
                two_sided: l.two_sided,
            })
            .collect(),
        variables,
        objects,
    }
}

/// Replace every float by the shortest decimal that reads back as the same f32 (the model is
/// f32; printed as f64, 0.08 would read 0.07999999821186066).
fn shortest_floats(value: &mut toml::Value) {
    match value {
        toml::Value::Float(f) => *f = (*f as f32).to_string().parse().unwrap_or(*f),
        toml::Value::Array(items) => items.iter_mut().for_each(shortest_floats),
        toml::Value::Table(table) => table.iter_mut().for_each(|(_, v)| shortest_floats(v)),
        _ => {}
    }
}

/// Write `dir/manifest.toml`, `dir/scene.gltf`, `dir/scene.bin` and one PNG per texture.
/// The manifest is written last, so an interrupted export never leaves a loadable but
/// incomplete scene. Unless `overwrite`, a folder that already holds any of these files is
/// refused before anything is written (the file named), so an export never replaces a
/// user's scene by accident.
pub fn export_scene(scene: &Scene, dir: &Path, overwrite: bool) -> Result<()> {
    if !overwrite {
        let names = scene.textures.iter().enumerate().map(|(i, t)| texture_file_name(i, t)).chain([BIN_FILE, GLTF_FILE, "manifest.toml"].map(String::from));
        if let Some(existing) = names.map(|name| dir.join(name)).find(|path| path.symlink_metadata().is_ok()) {
            return Err(Error::bad_input(existing.display(), "file", "already exists; export into another folder, or pass --force to overwrite it"));
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    for (i, t) in scene.textures.iter().enumerate() {
        write_bytes_atomically(&dir.join(texture_file_name(i, t)), &texture_png(t)?)?;
    }
    let (doc, bin) = gltf_document(scene);
    write_bytes_atomically(&dir.join(BIN_FILE), &bin)?;
    let json = serde_json::to_vec_pretty(&doc).map_err(|e| Error::Internal(e.to_string()))?;
    write_bytes_atomically(&dir.join(GLTF_FILE), &json)?;
    let manifest = manifest_of(scene, GLTF_FILE);
    let mut value = toml::Value::try_from(&manifest).map_err(|e| Error::Internal(format!("serialising manifest: {e}")))?;
    shortest_floats(&mut value);
    let text = toml::to_string(&value).map_err(|e| Error::Internal(format!("serialising manifest: {e}")))?;
    let text = format!("# glassbake scene manifest; geometry and materials are in {GLTF_FILE}.\n{text}");
    write_atomically(&dir.join("manifest.toml"), |tmp| std::fs::write(tmp, &text).map_err(|e| Error::io(tmp, e)))
}
