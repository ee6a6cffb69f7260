//! Resolving a scene argument (a built-in name or a path), the glTF / OBJ / manifest loaders,
//! and validation. Every error names the file and the field at fault.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use glam::Vec2;
use glassbake_core::{Error, Result};

mod gltf_file;
mod manifest_file;
mod obj_file;
mod scene_files;
mod validate;

pub use gltf_file::load_gltf;
pub use manifest_file::{apply_manifest, load_manifest};
pub use obj_file::load_obj;
use scene_files::FileSource;
pub use scene_files::MAX_SCENE_FILE_BYTES;
pub use validate::{validate, MAX_COORDINATE, MAX_RADIANCE, MAX_SPECULAR_COLOR, MAX_TEXTURE_COORDINATE, MAX_VARIABLES};

use crate::builtin::{builtin, BUILTIN_NAMES};
use crate::camera_spec::CameraSpec;
use crate::model::{Mesh, Scene};

/// Load a scene from a built-in name or a path to a manifest (.toml), glTF (.gltf/.glb) or
/// OBJ file, and validate it.
pub fn load_scene(arg: &str) -> Result<Scene> {
    if let Some(scene) = builtin(arg) {
        return Ok(scene);
    }
    load_scene_file(arg, FileSource::Disk)
}

/// [`load_scene`] of the scene file `entry` among `files`, the files of one scene folder held
/// in memory by their paths relative to it (what a web page fetched): the same references are
/// allowed as on disk, and nothing is read from anywhere else.
pub fn load_scene_from_memory(entry: &str, files: &BTreeMap<String, Vec<u8>>) -> Result<Scene> {
    load_scene_file(entry, FileSource::Memory(files))
}

fn load_scene_file(arg: &str, source: FileSource) -> Result<Scene> {
    let path = Path::new(arg);
    let extension = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let scene = match extension.as_deref() {
        Some("toml") => manifest_file::load_manifest_from(path, source)?,
        Some("gltf" | "glb" | "obj") => {
            let mut scene = load_geometry_from(path, source)?;
            let (lo, hi) = scene.bounds().ok_or_else(|| Error::bad_input(path.display(), "geometry", "the file holds no triangles"))?;
            scene.camera = CameraSpec::framing(lo, hi);
            scene
        }
        _ if !source.exists(path) && !arg.contains(['/', '\\', '.']) => {
            return Err(Error::bad_input(arg, "scene", format!("no built-in scene of that name (built-ins: {})", BUILTIN_NAMES.join(", "))))
        }
        _ => return Err(Error::bad_input(path.display(), "scene", "expected a built-in name or a .toml manifest, .gltf, .glb or .obj file")),
    };
    validate(&scene, arg)?;
    for w in &scene.load_warnings {
        tracing::warn!("{arg}: {w}");
    }
    Ok(scene)
}

/// Set to 1 to let scene files reference files outside their own folder.
pub const ALLOW_OUTSIDE_ENV: &str = "GLASSBAKE_ALLOW_OUTSIDE_FILES";

/// A file a scene file references (a manifest's geometry, a glTF buffer or image, an OBJ
/// material library or texture) must lie in the scene file's folder or below it: no absolute
/// path, no `..`, no URI scheme but `data:`. A scene from elsewhere can then not make
/// glassbake read, and copy into datasets and reports, any file the user can read.
/// `GLASSBAKE_ALLOW_OUTSIDE_FILES=1` lifts the rule for scenes that are trusted.
fn check_reference(file: &str, field: &str, reference: &str) -> Result<()> {
    if reference.starts_with("data:") {
        return Ok(());
    }
    // URIs may percent-encode the separators and dots. One that decodes to no file name at all
    // is refused here: the gltf crate (1.4.1) unwraps its own decoding and would panic.
    let Ok(decoded) = String::from_utf8(percent_decode(reference)) else {
        return Err(Error::bad_input(file, field, format!("{reference:?} is not a file name: its percent-encoding decodes to invalid UTF-8")));
    };
    if std::env::var(ALLOW_OUTSIDE_ENV).is_ok_and(|v| v == "1") {
        return Ok(());
    }
    let has_scheme = decoded.split_once(':').is_some_and(|(scheme, _)| {
        scheme.len() > 1 && scheme.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c)) && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
    });
    let outside = decoded.starts_with('/') || decoded.starts_with('\\') || has_scheme || decoded.split(['/', '\\']).any(|part| part == "..");
    if outside {
        return Err(Error::bad_input(
            file,
            field,
            format!("{reference:?} is outside the scene's folder; reference files beside the scene file or below it (or set {ALLOW_OUTSIDE_ENV}=1 for a trusted scene)"),
        ));
    }
    Ok(())
}

fn percent_decode(text: &str) -> Vec<u8> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    out
}

fn require_file(path: &Path, source: FileSource) -> Result<()> {
    if !source.exists(path) {
        return Err(Error::bad_input(path.display(), "file", "no such file"));
    }
    Ok(())
}

/// Load a glTF or OBJ file as a scene with a default name and no camera ranges or variables.
pub fn load_geometry(path: &Path) -> Result<Scene> {
    load_geometry_from(path, FileSource::Disk)
}

fn load_geometry_from(path: &Path, source: FileSource) -> Result<Scene> {
    require_file(path, source)?;
    let extension = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let mut scene = match extension.as_deref() {
        Some("gltf" | "glb") => gltf_file::load_gltf_from(path, source)?,
        Some("obj") => obj_file::load_obj_from(path, source)?,
        _ => return Err(Error::bad_input(path.display(), "geometry", "expected a .gltf, .glb or .obj file")),
    };
    warn_repeated_names(&mut scene);
    // Objects left without triangles (all degenerate) have nothing to draw or export.
    let empty: Vec<String> = scene.objects.iter().filter(|o| scene.meshes[o.mesh].indices.is_empty()).map(|o| o.name.clone()).collect();
    if !empty.is_empty() {
        scene.objects.retain(|o| !scene.meshes[o.mesh].indices.is_empty());
        scene.load_warnings.push(format!("objects without triangles are skipped: {}", empty.join(", ")));
    }
    Ok(scene)
}

fn empty_scene(path: &Path) -> Scene {
    let name = path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "scene".into());
    Scene::empty(&name)
}

/// Give each object a unique name (a `#n` suffix on repeats, skipping names the file itself
/// uses), since manifests refer to objects by name.
fn unique_name(taken: &mut HashMap<String, usize>, base: &str) -> String {
    let count = taken.entry(base.to_string()).or_insert(0);
    *count += 1;
    if *count == 1 {
        return base.to_string();
    }
    let mut n = *count - 1;
    loop {
        let candidate = format!("{base}#{n}");
        if !taken.contains_key(&candidate) {
            taken.insert(candidate.clone(), 1);
            return candidate;
        }
        n += 1;
    }
}

/// A warning for each name the file gives to several objects or materials.
fn warn_repeated_names(scene: &mut Scene) {
    let mut warnings = Vec::new();
    for (kind, names) in [
        ("objects", scene.objects.iter().map(|o| o.name.as_str()).collect::<Vec<_>>()),
        ("materials", scene.materials.iter().map(|m| m.name.as_str()).collect()),
    ] {
        for name in &names {
            let repeats: Vec<&str> = names.iter().copied().filter(|n| n.strip_prefix(name).is_some_and(|rest| rest.starts_with('#'))).collect();
            if !repeats.is_empty() && !name.contains('#') {
                warnings.push(format!(
                    "{} {kind} are named {name:?}; they are told apart as {name}, {} (a manifest naming {name:?} is refused)",
                    repeats.len() + 1,
                    repeats.join(", ")
                ));
            }
        }
    }
    scene.load_warnings.extend(warnings);
}

/// Drop degenerate triangles and fill in missing normals/UVs, recording warnings.
fn finish_mesh(mut mesh: Mesh, label: &str, warnings: &mut Vec<String>) -> Mesh {
    if mesh.uvs.len() != mesh.positions.len() {
        mesh.uvs = vec![Vec2::ZERO; mesh.positions.len()];
    }
    let vertex_count = mesh.positions.len();
    let before = mesh.indices.len();
    mesh.indices.retain(|t| t.iter().all(|&i| (i as usize) < vertex_count));
    if mesh.indices.len() < before {
        warnings.push(format!("{label}: dropped {} triangle(s) with a vertex index out of range", before - mesh.indices.len()));
    }
    if mesh.positions.iter().all(|p| p.is_finite()) {
        let dropped = mesh.drop_degenerate_triangles();
        if dropped > 0 {
            warnings.push(format!("{label}: dropped {dropped} degenerate triangle(s)"));
        }
    }
    if mesh.normals.len() != mesh.positions.len() {
        mesh.compute_vertex_normals();
    }
    mesh
}
