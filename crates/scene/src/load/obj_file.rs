//! The Wavefront OBJ loader, with its MTL material libraries and textures.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Affine3A, Vec2, Vec3, Vec4};
use glassbake_core::color::srgb_to_linear;
use glassbake_core::{Error, Result};

use super::scene_files::{FileSource, SceneFolder};
use super::{check_reference, empty_scene, finish_mesh, unique_name};
use crate::model::{Material, Mesh, Object, Scene, Texture, Transmission};
fn load_image_texture(folder: &SceneFolder, name: &str, is_color: bool, field: &str) -> Result<Texture> {
    let bytes = folder.read(field, name)?;
    let decoded = match image::ImageFormat::from_path(name) {
        Ok(format) => image::load_from_memory_with_format(&bytes, format),
        Err(_) => image::load_from_memory(&bytes),
    };
    let img = decoded.map_err(|e| Error::bad_input(folder.label(), field, format!("{name}: {e}")))?.to_rgba32f();
    let texels = img
        .pixels()
        .map(|p| {
            let c = |v: f32| if is_color { srgb_to_linear(v) } else { v };
            Vec4::new(c(p[0]), c(p[1]), c(p[2]), p[3])
        })
        .collect();
    Ok(Texture { name: name.to_string(), width: img.width(), height: img.height(), texels, is_color })
}

fn parse_floats3(s: &str) -> Option<Vec3> {
    let v: Vec<f32> = s.split_whitespace().filter_map(|x| x.parse().ok()).collect();
    match v.len() {
        1 => Some(Vec3::splat(v[0])),
        3.. => Some(Vec3::new(v[0], v[1], v[2])),
        _ => None,
    }
}

/// An MTL material as glassbake's: glass by dissolve `d` < 1 or illumination model 4, 6, 7 or
/// 9 (its tint `Tf`, IOR `Ni`), roughness from the Phong exponent `Ns`, the specular layer from
/// `Ks`, emission `Ke`; its diffuse texture, read through the scene folder, joins `scene`.
fn obj_material(m: &tobj::Material, i: usize, folder: &SceneFolder, scene: &mut Scene) -> Result<Material> {
    let field = format!("material {}", m.name);
    let unknown = |key: &str| m.unknown_param.get(key).and_then(|v| parse_floats3(v));
    let kd = m.diffuse.map(Vec3::from).unwrap_or(Vec3::splat(0.8));
    let illum = m.illumination_model.unwrap_or(2);
    let dissolve = m.dissolve.unwrap_or(1.0);
    let glass = dissolve < 1.0 || matches!(illum, 4 | 6 | 7 | 9);
    let ns = m.shininess.unwrap_or(0.0).max(0.0);
    let alpha = (2.0 / (ns + 2.0)).sqrt();
    let base_color_texture = match &m.diffuse_texture {
        Some(tex) => {
            let texture = load_image_texture(folder, tex, true, &format!("{field}.map_Kd"))?;
            scene.textures.push(Arc::new(texture));
            Some(scene.textures.len() - 1)
        }
        None => None,
    };
    // The specular layer by illumination model: 0 and 1 have none (Lambertian); 2 and
    // the others take Ks as the reflectance at normal incidence (F0 = 0.04 x colour, so
    // colour = Ks / 0.04), or glTF's default 4% where Ks is absent. Ks of zero is none.
    let (specular, specular_color) = match (illum, m.specular) {
        (0 | 1, _) => (0.0, Vec3::ONE),
        (_, Some(ks)) if Vec3::from(ks).max_element() <= 0.0 => (0.0, Vec3::ONE),
        (_, Some(ks)) => (1.0, Vec3::from(ks).max(Vec3::ZERO) / 0.04),
        (_, None) => (1.0, Vec3::ONE),
    };
    if !matches!(illum, 0..=2 | 4 | 6 | 7 | 9) {
        scene.load_warnings.push(format!("{field}: illum {illum} is read as illum 2 (diffuse + specular)"));
    }
    let mut material = Material {
        name: if m.name.is_empty() { format!("material{i}") } else { m.name.clone() },
        base_color: kd,
        base_color_texture,
        // glTF roughness is sqrt(alpha).
        roughness: alpha.sqrt().clamp(0.0, 1.0),
        roughness_texture: None,
        specular,
        specular_color,
        emission: m.emissive.map(Vec3::from).unwrap_or(Vec3::ZERO),
        ..Material::diffuse("", kd)
    };
    if glass {
        material.base_color = unknown("Tf").unwrap_or(Vec3::ONE);
        material.roughness = if ns >= 1000.0 || m.shininess.is_none() { 0.0 } else { material.roughness };
        material.transmission =
            Some(Transmission { weight: if dissolve < 1.0 { 1.0 - dissolve } else { 1.0 }, ior: m.optical_density.unwrap_or(1.5), thin: false });
    }
    Ok(material)
}

/// tobj 4.0.5 unwraps a colour statement (`Ka`, `Kd`, `Ks`, `Ke`) of fewer than three numbers
/// in a material library (a panic): check them first. A library that is not there is tobj's
/// to report (a warning, grey materials).
fn check_material_colours(library: &Path, bytes: &[u8]) -> Result<()> {
    for (number, line) in String::from_utf8_lossy(bytes).lines().enumerate() {
        let mut words = line.split_whitespace();
        if let Some(key @ ("Ka" | "Kd" | "Ks" | "Ke")) = words.next() {
            if words.take(3).count() < 3 {
                return Err(Error::bad_input(library.display(), format!("line {} {key}", number + 1), "needs three numbers (red, green, blue)"));
            }
        }
    }
    Ok(())
}

/// Load a Wavefront OBJ file with its MTL materials ([`obj_material`]: glass by dissolve `d` < 1
/// or an illumination model 4, 6, 7 or 9; roughness from the Phong exponent `Ns`, alpha =
/// sqrt(2 / (Ns + 2))).
pub fn load_obj(path: &Path) -> Result<Scene> {
    load_obj_from(path, FileSource::Disk)
}

pub(crate) fn load_obj_from(path: &Path, source: FileSource) -> Result<Scene> {
    let label = path.display().to_string();
    let text = source.read(path, &label, "file")?;
    let folder = source.folder(path)?;
    // The material libraries are read here, through the scene folder's rule, and handed to
    // tobj by the name it asks for.
    let mut libraries = HashMap::new();
    for (number, line) in String::from_utf8_lossy(&text).lines().enumerate() {
        let field = format!("line {} mtllib", number + 1);
        if let Some(names) = line.trim_start().strip_prefix("mtllib") {
            for name in names.split_whitespace() {
                check_reference(&label, &field, name)?;
            }
        }
        if line.split_whitespace().next() == Some("mtllib") {
            // The name tobj 4.0.5 asks for: the rest of the line after the first space.
            let name = line.split_once(' ').unwrap_or_default().1.trim();
            // A library that is not there is tobj's to report.
            let library = path.with_file_name(name);
            let present = match source {
                FileSource::Disk => library.symlink_metadata().is_ok(),
                FileSource::Memory(_) => source.exists(&library),
            };
            if !present {
                continue;
            }
            let bytes = folder.read(&field, name)?;
            check_material_colours(&library, &bytes)?;
            libraries.insert(PathBuf::from(name), bytes);
        }
    }
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let library = |name: &Path| match libraries.get(name) {
        Some(bytes) => tobj::load_mtl_buf(&mut std::io::Cursor::new(bytes)),
        None => Err(tobj::LoadError::OpenFileFailed),
    };
    let (models, materials) =
        tobj::load_obj_buf(&mut std::io::Cursor::new(&text), &options, library).map_err(|e| Error::bad_input(&label, "OBJ", e.to_string()))?;
    let mut scene = empty_scene(path);
    let obj_materials = match materials {
        Ok(m) => m,
        Err(e) => {
            scene.load_warnings.push(format!("materials: {e}; using a grey default"));
            Vec::new()
        }
    };
    for (i, m) in obj_materials.iter().enumerate() {
        let material = obj_material(m, i, &folder, &mut scene)?;
        scene.materials.push(material);
    }
    let mut material_names = HashMap::new();
    for m in &mut scene.materials {
        m.name = unique_name(&mut material_names, &m.name);
    }
    let mut default_material = None;
    let mut names = HashMap::new();
    for model in &models {
        let m = &model.mesh;
        let positions: Vec<Vec3> = m.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])).collect();
        let normals: Vec<Vec3> = m.normals.chunks_exact(3).map(|n| Vec3::new(n[0], n[1], n[2])).collect();
        // OBJ's v runs bottom-up; ours (glTF's) top-down.
        let uvs: Vec<Vec2> = m.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], 1.0 - t[1])).collect();
        let indices = m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let name = if model.name.is_empty() { "object".to_string() } else { model.name.clone() };
        let mesh = finish_mesh(Mesh { positions, normals, uvs, indices }, &format!("object {name}"), &mut scene.load_warnings);
        let material = match m.material_id.filter(|&id| id < scene.materials.len()) {
            Some(id) => id,
            None => *default_material.get_or_insert_with(|| {
                scene.materials.push(Material::diffuse(&unique_name(&mut material_names, "default"), Vec3::splat(0.8)));
                scene.materials.len() - 1
            }),
        };
        scene.meshes.push(Arc::new(mesh));
        scene.objects.push(Object {
            name: unique_name(&mut names, &name),
            mesh: scene.meshes.len() - 1,
            material,
            transform: Affine3A::IDENTITY,
            transparent: scene.materials[material].is_transmissive(),
        });
    }
    Ok(scene)
}
