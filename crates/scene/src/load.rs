//! Resolving a scene argument (a built-in name or a path), the glTF / OBJ / manifest loaders,
//! and validation. Every error names the file and the field at fault.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Affine2, Affine3A, Mat4, Vec2, Vec3, Vec4};
use glassbake_core::color::srgb_to_linear;
use glassbake_core::{Error, Result};

use crate::builtin::{builtin, BUILTIN_NAMES};
use crate::camera_spec::{CameraPosition, CameraSpec, Interval};
use crate::gltf_extensions;
use crate::manifest::{parse_manifest, Manifest, NumberOrRange, PositionManifest, TargetManifest};
use crate::model::{Material, Mesh, Object, RectLight, Scene, Texture, Transmission};
use crate::variables::{Variable, VariableTarget};

/// Load a scene from a built-in name or a path to a manifest (.toml), glTF (.gltf/.glb) or
/// OBJ file, and validate it.
pub fn load_scene(arg: &str) -> Result<Scene> {
    if let Some(scene) = builtin(arg) {
        return Ok(scene);
    }
    let path = Path::new(arg);
    let extension = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let scene = match extension.as_deref() {
        Some("toml") => load_manifest(path)?,
        Some("gltf" | "glb" | "obj") => {
            let mut scene = load_geometry(path)?;
            let (lo, hi) = scene.bounds().ok_or_else(|| Error::bad_input(path.display(), "geometry", "the file holds no triangles"))?;
            scene.camera = CameraSpec::framing(lo, hi);
            scene
        }
        _ if !path.exists() && !arg.contains(['/', '\\', '.']) => {
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

fn require_file(path: &Path) -> Result<()> {
    if !path.is_file() {
        return Err(Error::bad_input(path.display(), "file", "no such file"));
    }
    Ok(())
}

/// Load a glTF or OBJ file as a scene with a default name and no camera ranges or variables.
pub fn load_geometry(path: &Path) -> Result<Scene> {
    require_file(path)?;
    let extension = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let mut scene = match extension.as_deref() {
        Some("gltf" | "glb") => load_gltf(path)?,
        Some("obj") => load_obj(path)?,
        _ => return Err(Error::bad_input(path.display(), "geometry", "expected a .gltf, .glb or .obj file")),
    };
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

/// Give each object a unique name (a `#n` suffix on repeats), since manifests refer to
/// objects by name.
fn unique_name(taken: &mut HashMap<String, usize>, base: &str) -> String {
    let count = taken.entry(base.to_string()).or_insert(0);
    *count += 1;
    if *count == 1 {
        base.to_string()
    } else {
        format!("{base}#{}", *count - 1)
    }
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

fn gltf_texture(
    scene: &mut Scene,
    cache: &mut HashMap<(usize, bool), usize>,
    images: &[gltf::image::Data],
    image_index: usize,
    is_color: bool,
    label: &str,
) -> Result<usize> {
    if let Some(&i) = cache.get(&(image_index, is_color)) {
        return Ok(i);
    }
    let data = &images[image_index];
    use gltf::image::Format;
    let channels = match data.format {
        Format::R8 => 1,
        Format::R8G8 => 2,
        Format::R8G8B8 => 3,
        Format::R8G8B8A8 => 4,
        other => return Err(Error::bad_input(label, format!("images[{image_index}]"), format!("unsupported pixel format {other:?} (8-bit textures only)"))),
    };
    let decode = |v: u8| {
        let v = v as f32 / 255.0;
        if is_color {
            srgb_to_linear(v)
        } else {
            v
        }
    };
    let texels = data
        .pixels
        .chunks_exact(channels)
        .map(|p| {
            let alpha = |v: u8| v as f32 / 255.0;
            match *p {
                [l] => Vec4::new(decode(l), decode(l), decode(l), 1.0),
                // Two channels are luminance + alpha (PNG grey-alpha).
                [l, a] => Vec4::new(decode(l), decode(l), decode(l), alpha(a)),
                [r, g, b] => Vec4::new(decode(r), decode(g), decode(b), 1.0),
                [r, g, b, a, ..] => Vec4::new(decode(r), decode(g), decode(b), alpha(a)),
                [] => Vec4::ZERO,
            }
        })
        .collect();
    scene.textures.push(Arc::new(Texture { name: format!("image{image_index}"), width: data.width, height: data.height, texels, is_color }));
    let index = scene.textures.len() - 1;
    cache.insert((image_index, is_color), index);
    Ok(index)
}

/// A glTF material, and the KHR_texture_transform its textures share (baked into the UVs of
/// the primitives that use it, since glassbake's materials sample one UV set).
fn gltf_material(
    m: &gltf::Material,
    scene: &mut Scene,
    cache: &mut HashMap<(usize, bool), usize>,
    images: &[gltf::image::Data],
    label: &str,
) -> Result<(Material, Option<Affine2>)> {
    let pbr = m.pbr_metallic_roughness();
    let base = pbr.base_color_factor();
    let name = m.name().map(str::to_string).unwrap_or_else(|| format!("material{}", m.index().unwrap_or(0)));
    let mut warnings = Vec::new();
    // Each texture slot used: (field name, image index, is colour, its transform).
    let mut slot = |field: &str, info: Option<gltf::texture::Info>| -> Option<(usize, Option<Affine2>)> {
        let info = info?;
        let transform = info.texture_transform().map(|t| {
            if t.tex_coord().is_some_and(|c| c != 0) {
                warnings.push(format!("material {name}: {field} KHR_texture_transform selects another UV set; only TEXCOORD_0 is read"));
            }
            gltf_extensions::texture_transform_matrix(t.offset(), t.rotation(), t.scale())
        });
        if info.tex_coord() != 0 {
            warnings.push(format!("material {name}: {field} uses TEXCOORD_{}; only TEXCOORD_0 is read", info.tex_coord()));
        }
        Some((info.texture().source().index(), transform))
    };
    let specular_ext = m.specular();
    let base_slot = slot("baseColorTexture", pbr.base_color_texture());
    let rough_slot = slot("metallicRoughnessTexture", pbr.metallic_roughness_texture());
    let specular_slot = slot("specularTexture", specular_ext.as_ref().and_then(|s| s.specular_texture()));
    let specular_color_slot = slot("specularColorTexture", specular_ext.as_ref().and_then(|s| s.specular_color_texture()));
    let slots = [base_slot, rough_slot, specular_slot, specular_color_slot];
    // The first textured slot's transform is baked; any other must agree.
    let transform = slots.iter().flatten().map(|(_, t)| *t).next().flatten();
    if slots.iter().flatten().any(|(_, t)| *t != transform) {
        warnings.push(format!("material {name}: its textures have different KHR_texture_transforms; all use the first one's"));
    }
    scene.load_warnings.append(&mut warnings);
    let mut texture =
        |slot: Option<(usize, Option<Affine2>)>, is_color: bool| slot.map(|(i, _)| gltf_texture(scene, cache, images, i, is_color, label)).transpose();
    let base_color_texture = texture(base_slot, true)?;
    let roughness_texture = texture(rough_slot, false)?;
    // KHR_materials_specular: the factor's texture is read from its alpha channel (linear),
    // the colour's from RGB (sRGB).
    let specular_texture = texture(specular_slot, false)?;
    let specular_color_texture = texture(specular_color_slot, true)?;
    let strength = m.emissive_strength().unwrap_or(1.0);
    let transmission = m.transmission().map(|t| Transmission {
        weight: t.transmission_factor(),
        ior: m.ior().unwrap_or(1.5),
        // glTF: without KHR_materials_volume (or with zero thickness) the surface is thin-walled.
        thin: m.volume().is_none_or(|v| v.thickness_factor() <= 0.0),
    });
    if m.ior().is_some_and(|ior| (ior - 1.5).abs() > 1e-6) && transmission.is_none() {
        scene.load_warnings.push(format!("material {name}: KHR_materials_ior on an opaque material is ignored (F0 stays 0.04 x specular colour)"));
    }
    let material = Material {
        name,
        base_color: Vec3::new(base[0], base[1], base[2]),
        base_color_texture,
        roughness: pbr.roughness_factor(),
        roughness_texture,
        metallic: pbr.metallic_factor(),
        specular: specular_ext.as_ref().map_or(1.0, |s| s.specular_factor()),
        specular_texture,
        specular_color: specular_ext.as_ref().map_or(Vec3::ONE, |s| Vec3::from(s.specular_color_factor())),
        specular_color_texture,
        emission: Vec3::from(m.emissive_factor()) * strength,
        transmission: transmission.filter(|t| t.weight > 0.0),
    };
    Ok((material, transform))
}

/// Load a glTF 2.0 file (.gltf or .glb) with its buffers and textures.
pub fn load_gltf(path: &Path) -> Result<Scene> {
    let label = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| Error::bad_input(&label, "file", e.to_string()))?;
    let (used, required) = gltf_extensions::declared_extensions(&bytes, &label)?;
    let extension_warnings = gltf_extensions::check_extensions(&used, &required, &label)?;
    let gltf_error = |e: gltf::Error| Error::bad_input(&label, "glTF", e.to_string().replace('\n', " "));
    // The required extensions are checked above against what glassbake renders; the gltf
    // crate's own check (gltf 1.4.1) also refuses KHR_materials_specular and _volume, which
    // it parses, so it validates the document with that list emptied.
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(&bytes).map_err(gltf_error)?;
    let mut root = document.into_json();
    root.extensions_required.clear();
    // gltf-json 1.4.1's validation indexes the accessors with a primitive's POSITION before it
    // checks that the index exists (a panic): check it first.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(accessor) = primitive.attributes.get(&gltf::json::validation::Checked::Valid(gltf::Semantic::Positions)) {
                if accessor.value() >= root.accessors.len() {
                    return Err(Error::bad_input(
                        &label,
                        format!("meshes[{m}].primitives[{p}].attributes.POSITION"),
                        format!("accessor {} does not exist (the file has {})", accessor.value(), root.accessors.len()),
                    ));
                }
            }
        }
    }
    // The gltf crate's `Image::source` unwraps the uri when there is no bufferView, and the
    // mimeType when there is one: check both first.
    for (i, image) in root.images.iter().enumerate() {
        let problem = match (&image.uri, &image.buffer_view, &image.mime_type) {
            (None, None, _) => Some("has neither a uri nor a bufferView"),
            (Some(_), Some(_), _) => Some("has both a uri and a bufferView"),
            (None, Some(_), None) => Some("has a bufferView but no mimeType"),
            _ => None,
        };
        if let Some(problem) = problem {
            return Err(Error::bad_input(&label, format!("images[{i}]"), problem));
        }
    }
    let document = gltf::Document::from_json(root).map_err(gltf_error)?;
    let base = path.parent();
    for buffer in document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source() {
            check_reference(&label, &format!("buffers[{}].uri", buffer.index()), uri)?;
        }
    }
    for image in document.images() {
        if let gltf::image::Source::Uri { uri, .. } = image.source() {
            check_reference(&label, &format!("images[{}].uri", image.index()), uri)?;
        }
    }
    let buffers = gltf::import_buffers(&document, base, blob).map_err(gltf_error)?;
    let images = gltf::import_images(&document, base, &buffers).map_err(gltf_error)?;
    let mut scene = empty_scene(path);
    scene.load_warnings.extend(extension_warnings);
    let mut texture_cache = HashMap::new();
    // Materials keep the file's order, so indices match the file's material indices.
    let mut material_names = HashMap::new();
    let mut uv_transforms = Vec::new();
    for m in document.materials() {
        let (mut material, uv_transform) = gltf_material(&m, &mut scene, &mut texture_cache, &images, &label)?;
        material.name = unique_name(&mut material_names, &material.name);
        scene.materials.push(material);
        uv_transforms.push(uv_transform);
    }
    let mut default_material = None;
    let mut names = HashMap::new();
    let gltf_scene =
        document.default_scene().or_else(|| document.scenes().next()).ok_or_else(|| Error::bad_input(&label, "scenes", "the file has no scene"))?;
    // Depth-first in file order, so objects (and thus transparency buffers) keep a stable order.
    let mut stack: Vec<(gltf::Node, Mat4)> = gltf_scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    stack.reverse();
    // glTF's node hierarchy is a forest: a node reached twice is a cycle (which would grow
    // this stack without end) or a node with two parents; both are refused.
    let mut visited = vec![false; document.nodes().len()];
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[node.index()], true) {
            return Err(Error::bad_input(
                &label,
                format!("nodes[{}]", node.index()),
                "is reached twice from the scene's root nodes: the node hierarchy has a cycle or a node with two parents (glTF requires a tree)",
            ));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let children: Vec<_> = node.children().collect();
        for child in children.into_iter().rev() {
            stack.push((child, world));
        }
        let Some(mesh) = node.mesh() else { continue };
        let base_name = node.name().or(mesh.name()).map(str::to_string).unwrap_or_else(|| format!("node{}", node.index()));
        let primitive_count = mesh.primitives().len();
        for primitive in mesh.primitives() {
            let field = format!("meshes[{}].primitives[{}]", mesh.index(), primitive.index());
            if primitive.mode() != gltf::mesh::Mode::Triangles {
                scene.load_warnings.push(format!("{field}: {:?} primitives are skipped (triangles only)", primitive.mode()));
                continue;
            }
            check_accessors(&primitive, &buffers, &label, &field)?;
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<Vec3> =
                reader.read_positions().ok_or_else(|| Error::bad_input(&label, format!("{field}.attributes.POSITION"), "missing"))?.map(Vec3::from).collect();
            let normals = reader.read_normals().map(|n| n.map(Vec3::from).collect()).unwrap_or_default();
            let uvs = reader.read_tex_coords(0).map(|t| t.into_f32().map(Vec2::from).collect()).unwrap_or_default();
            let flat: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            let indices = flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
            let name = if primitive_count > 1 { format!("{base_name}.{}", primitive.index()) } else { base_name.clone() };
            let mesh = finish_mesh(Mesh { positions, normals, uvs, indices }, &format!("{field} ({name})"), &mut scene.load_warnings);
            let material = match primitive.material().index() {
                Some(i) => i,
                None => match default_material {
                    Some(i) => i,
                    None => {
                        let (m, uv_transform) = gltf_material(&primitive.material(), &mut scene, &mut texture_cache, &images, &label)?;
                        let name = unique_name(&mut material_names, "default");
                        scene.materials.push(Material { name, ..m });
                        uv_transforms.push(uv_transform);
                        *default_material.insert(scene.materials.len() - 1)
                    }
                },
            };
            let mut mesh = mesh;
            if let Some(t) = uv_transforms[material] {
                for uv in &mut mesh.uvs {
                    *uv = t.transform_point2(*uv);
                }
            }
            scene.meshes.push(Arc::new(mesh));
            let transparent = scene.materials[material].is_transmissive();
            scene.objects.push(Object {
                name: unique_name(&mut names, &name),
                mesh: scene.meshes.len() - 1,
                material,
                transform: Affine3A::from_mat4(world),
                transparent,
            });
        }
    }
    Ok(scene)
}

/// The accessors a primitive's triangles are read through, checked before gltf-rs reads them
/// (it panics on some and silently drops others): POSITION and NORMAL are three floats per
/// vertex, TEXCOORD_0 two numbers, indices unsigned scalars, and each accessor lies inside its
/// buffer view and buffer.
fn check_accessors(primitive: &gltf::Primitive, buffers: &[gltf::buffer::Data], label: &str, field: &str) -> Result<()> {
    use gltf::accessor::{DataType, Dimensions};
    // The gltf crate's readers meet other types of NORMAL and TEXCOORD_0 with `unreachable!()`.
    let rules = [
        ("attributes.POSITION", primitive.get(&gltf::Semantic::Positions), &[DataType::F32][..], Dimensions::Vec3, "positions must be FLOAT VEC3"),
        ("attributes.NORMAL", primitive.get(&gltf::Semantic::Normals), &[DataType::F32][..], Dimensions::Vec3, "normals must be FLOAT VEC3"),
        (
            "attributes.TEXCOORD_0",
            primitive.get(&gltf::Semantic::TexCoords(0)),
            &[DataType::F32, DataType::U8, DataType::U16][..],
            Dimensions::Vec2,
            "texture coordinates must be FLOAT, UNSIGNED_BYTE or UNSIGNED_SHORT VEC2",
        ),
        (
            "indices",
            primitive.indices(),
            &[DataType::U8, DataType::U16, DataType::U32][..],
            Dimensions::Scalar,
            "indices must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT SCALAR",
        ),
    ];
    let mut checked = Vec::new();
    for (name, accessor, types, dimensions, rule) in rules {
        let Some(accessor) = accessor else { continue };
        if !types.contains(&accessor.data_type()) || accessor.dimensions() != dimensions {
            return Err(Error::bad_input(
                label,
                format!("{field}.{name} (accessors[{}])", accessor.index()),
                format!("is {:?} {:?}; {rule}", accessor.data_type(), accessor.dimensions()),
            ));
        }
        checked.push((name, accessor));
    }
    for (name, accessor) in checked {
        let Some(view) = accessor.view() else { continue };
        let element = accessor.size();
        let stride = view.stride().unwrap_or(element);
        let needed = if accessor.count() == 0 { 0 } else { accessor.offset() + stride * (accessor.count() - 1) + element };
        let buffer_length = buffers.get(view.buffer().index()).map_or(0, |b| b.len());
        if needed > view.length() || view.offset() + view.length() > buffer_length {
            return Err(Error::bad_input(
                label,
                format!("{field}.{name} (accessors[{}])", accessor.index()),
                format!(
                    "runs past its data: {} elements need {needed} bytes of bufferViews[{}] ({} bytes at offset {} of a {buffer_length}-byte buffer)",
                    accessor.count(),
                    view.index(),
                    view.length(),
                    view.offset()
                ),
            ));
        }
    }
    Ok(())
}

fn load_image_texture(path: &Path, name: &str, is_color: bool, label: &str, field: &str) -> Result<Texture> {
    let img = image::open(path).map_err(|e| Error::bad_input(label, field, format!("{}: {e}", path.display())))?.to_rgba32f();
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

/// Load a Wavefront OBJ file with its MTL materials. Glass is recognised by dissolve `d` < 1
/// or an illumination model 4, 6, 7 or 9; `Ni` is its IOR and `Tf` its tint; `Ke` emission;
/// roughness from the Phong exponent `Ns` (alpha = sqrt(2 / (Ns + 2))).
/// tobj 4.0.5 unwraps a colour statement (`Ka`, `Kd`, `Ks`, `Ke`) of fewer than three numbers
/// in a material library (a panic): check them first. A library that is not there is tobj's
/// to report (a warning, grey materials).
fn check_material_colours(library: &Path) -> Result<()> {
    let Ok(bytes) = std::fs::read(library) else { return Ok(()) };
    for (number, line) in String::from_utf8_lossy(&bytes).lines().enumerate() {
        let mut words = line.split_whitespace();
        if let Some(key @ ("Ka" | "Kd" | "Ks" | "Ke")) = words.next() {
            if words.take(3).count() < 3 {
                return Err(Error::bad_input(library.display(), format!("line {} {key}", number + 1), "needs three numbers (red, green, blue)"));
            }
        }
    }
    Ok(())
}

pub fn load_obj(path: &Path) -> Result<Scene> {
    let label = path.display().to_string();
    // tobj opens the material libraries itself: check their names first.
    let text = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    for (number, line) in String::from_utf8_lossy(&text).lines().enumerate() {
        let field = format!("line {} mtllib", number + 1);
        if let Some(libraries) = line.trim_start().strip_prefix("mtllib") {
            for library in libraries.split_whitespace() {
                check_reference(&label, &field, library)?;
            }
        }
        if line.split_whitespace().next() == Some("mtllib") {
            // The name tobj 4.0.5 opens: the rest of the line after the first space.
            let library = line.split_once(' ').unwrap_or_default().1.trim();
            check_reference(&label, &field, library)?;
            check_material_colours(&dir.join(library))?;
        }
    }
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, materials) = tobj::load_obj(path, &options).map_err(|e| Error::bad_input(&label, "OBJ", e.to_string()))?;
    let mut scene = empty_scene(path);
    let obj_materials = match materials {
        Ok(m) => m,
        Err(e) => {
            scene.load_warnings.push(format!("materials: {e}; using a grey default"));
            Vec::new()
        }
    };
    for (i, m) in obj_materials.iter().enumerate() {
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
                check_reference(&label, &format!("{field}.map_Kd"), tex)?;
                let texture = load_image_texture(&dir.join(tex), tex, true, &label, &format!("{field}.map_Kd"))?;
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

fn interval(value: &NumberOrRange, file: &str, field: &str) -> Result<Interval> {
    match value {
        NumberOrRange::Number(v) => Ok(Interval::fixed(*v)),
        NumberOrRange::Range(r) => match r.as_slice() {
            [min, max] if min <= max => Ok(Interval::new(*min, *max)),
            [min, max] => Err(Error::bad_input(file, field, format!("reversed range [{min}, {max}]: min must not exceed max"))),
            _ => Err(Error::bad_input(file, field, format!("expected a number or [min, max], got {} values", r.len()))),
        },
    }
}

fn name_list<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let v: Vec<&str> = names.collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// Load a manifest and the geometry it points to, and apply its declarations.
pub fn load_manifest(path: &Path) -> Result<Scene> {
    let file = path.display().to_string();
    require_file(path)?;
    let text = std::fs::read_to_string(path).map_err(|e| Error::bad_input(&file, "file", e.to_string()))?;
    let manifest = parse_manifest(&text).map_err(|(field, message)| Error::bad_input(&file, field, message))?;
    check_reference(&file, "geometry", &manifest.geometry)?;
    let geometry: PathBuf = path.parent().unwrap_or(Path::new(".")).join(&manifest.geometry);
    if !geometry.is_file() {
        return Err(Error::bad_input(&file, "geometry", format!("no such file: {}", geometry.display())));
    }
    let mut scene = load_geometry(&geometry)?;
    apply_manifest(&mut scene, &manifest, &file)?;
    Ok(scene)
}

/// Apply a parsed manifest to a loaded geometry scene.
pub fn apply_manifest(scene: &mut Scene, manifest: &Manifest, file: &str) -> Result<()> {
    if let Some(name) = &manifest.name {
        scene.name = name.clone();
    }
    if let Some(bg) = manifest.background {
        scene.background = Vec3::from(bg);
    }
    for (name, o) in &manifest.objects {
        let i = scene.object_index(name).ok_or_else(|| {
            Error::bad_input(
                file,
                format!("objects.{name}"),
                format!("no object of that name (objects: {})", name_list(scene.objects.iter().map(|o| o.name.as_str()))),
            )
        })?;
        if let Some(thin) = o.thin {
            let field = format!("objects.{name}.thin");
            let material = &scene.materials[scene.objects[i].material];
            let Some(mut transmission) = material.transmission else {
                return Err(Error::bad_input(file, field, format!("material {} is not transmissive: thin applies to glass only", material.name)));
            };
            transmission.thin = thin;
            // A material of its own, so other objects sharing the file's material keep theirs.
            let own = Material { name: format!("{}.{}", material.name, scene.objects[i].name), transmission: Some(transmission), ..material.clone() };
            scene.materials.push(own);
            scene.objects[i].material = scene.materials.len() - 1;
        }
        if let Some(t) = o.transparent {
            scene.objects[i].transparent = t;
        }
    }
    for (i, l) in manifest.lights.iter().enumerate() {
        let light = RectLight {
            name: l.name.clone(),
            corner: Vec3::from(l.corner),
            edge_u: Vec3::from(l.edge_u),
            edge_v: Vec3::from(l.edge_v),
            radiance: Vec3::from(l.radiance),
            two_sided: l.two_sided,
        };
        if light.edge_u.cross(light.edge_v).length() <= 0.0 || !light.edge_u.cross(light.edge_v).is_finite() {
            return Err(Error::bad_input(file, format!("lights[{i}]"), "edge_u and edge_v must span a rectangle of nonzero area"));
        }
        scene.rect_lights.push(light);
    }
    if let Some(c) = &manifest.camera {
        let position = match &c.position {
            PositionManifest::Box { min, max } => {
                let (min, max) = (Vec3::from(*min), Vec3::from(*max));
                if !min.cmple(max).all() {
                    return Err(Error::bad_input(file, "camera.position", format!("reversed box: min {min} exceeds max {max}")));
                }
                CameraPosition::Box { min, max }
            }
            PositionManifest::Orbit { center, radius, azimuth_deg, elevation_deg } => CameraPosition::Orbit {
                center: Vec3::from(*center),
                radius: interval(radius, file, "camera.position.radius")?,
                azimuth_deg: interval(azimuth_deg, file, "camera.position.azimuth_deg")?,
                elevation_deg: interval(elevation_deg, file, "camera.position.elevation_deg")?,
            },
        };
        scene.camera = CameraSpec {
            position,
            target: Vec3::from(c.target),
            target_jitter: c.target_jitter.map(Vec3::from).unwrap_or(Vec3::ZERO),
            up: c.up.map(Vec3::from).unwrap_or(Vec3::Y),
            fov_x_deg: interval(&c.fov_x_deg, file, "camera.fov_x_deg")?,
            near: c.near.unwrap_or(0.01),
            far: c.far.unwrap_or(100.0),
        };
    } else if let Some((lo, hi)) = scene.bounds() {
        scene.camera = CameraSpec::framing(lo, hi);
    }
    for (i, v) in manifest.variables.iter().enumerate() {
        let field = format!("variables[{i}] ({})", v.name);
        let (min, max) = match v.range.as_slice() {
            [min, max] if min < max => (*min, *max),
            [min, max] if min == max => {
                return Err(Error::bad_input(file, format!("{field}.range"), format!("empty range [{min}, {max}]: a variable must vary")))
            }
            [min, max] => return Err(Error::bad_input(file, format!("{field}.range"), format!("reversed range [{min}, {max}]: min must be below max"))),
            r => return Err(Error::bad_input(file, format!("{field}.range"), format!("expected [min, max], got {} values", r.len()))),
        };
        let material = |name: &str| {
            scene.material_index(name).ok_or_else(|| {
                Error::bad_input(
                    file,
                    format!("{field}.target.material"),
                    format!("no material named {name:?} (materials: {})", name_list(scene.materials.iter().map(|m| m.name.as_str()))),
                )
            })
        };
        let object = |name: &str| {
            scene.object_index(name).ok_or_else(|| {
                Error::bad_input(
                    file,
                    format!("{field}.target.object"),
                    format!("no object named {name:?} (objects: {})", name_list(scene.objects.iter().map(|o| o.name.as_str()))),
                )
            })
        };
        let light = |name: &str| {
            scene.light_index(name).ok_or_else(|| {
                Error::bad_input(
                    file,
                    format!("{field}.target.light"),
                    format!("no rectangle light named {name:?} (lights: {})", name_list(scene.rect_lights.iter().map(|l| l.name.as_str()))),
                )
            })
        };
        let axis = |a: [f32; 3]| {
            let a = Vec3::from(a);
            if a.length_squared() > 0.0 && a.is_finite() {
                Ok(a)
            } else {
                Err(Error::bad_input(file, format!("{field}.target.axis"), "must be a nonzero finite vector"))
            }
        };
        let target = match &v.target {
            TargetManifest::Roughness { material: m } => VariableTarget::Roughness { material: material(m)? },
            TargetManifest::Hue { material: m, saturation, brightness } => {
                VariableTarget::Hue { material: material(m)?, saturation: *saturation, brightness: *brightness }
            }
            TargetManifest::Translation { object: o, axis: a } => VariableTarget::Translation { object: object(o)?, axis: axis(*a)? },
            TargetManifest::LightTranslation { light: l, axis: a } => VariableTarget::LightTranslation { light: light(l)?, axis: axis(*a)? },
            TargetManifest::LightIntensity { light: l } => VariableTarget::LightIntensity { light: light(l)? },
            TargetManifest::EmissionIntensity { material: m } => VariableTarget::EmissionIntensity { material: material(m)? },
        };
        let default = v.default.unwrap_or(0.5 * (min + max));
        if !(min..=max).contains(&default) {
            return Err(Error::bad_input(file, format!("{field}.default"), format!("{default} is outside the range [{min}, {max}]")));
        }
        scene.variables.push(Variable { name: v.name.clone(), min, max, default, target });
    }
    Ok(())
}

/// The largest radiance a light, an emissive material or the background may have: far above
/// any scene the tone map can show, far below what overflows f32 once a path divides it by
/// small densities (a light of 3e38 filled images with inf).
pub const MAX_RADIANCE: f32 = 1e9;

fn check_radiance(file: &str, field: String, radiance: Vec3) -> Result<()> {
    if radiance.min_element() < 0.0 {
        return Err(Error::bad_input(file, field, format!("{radiance} is negative: radiance is at least 0")));
    }
    if radiance.max_element() > MAX_RADIANCE {
        return Err(Error::bad_input(file, field, format!("{radiance} is above {MAX_RADIANCE:e}, which would overflow the image")));
    }
    Ok(())
}

fn check_finite(file: &str, field: String, values: &[f32]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::bad_input(file, field, "contains NaN or infinity"))
    }
}

fn check_unique<'a>(file: &str, kind: &str, names: impl Iterator<Item = &'a str>) -> Result<()> {
    let mut seen = std::collections::HashSet::new();
    for n in names {
        if !seen.insert(n) {
            return Err(Error::bad_input(file, kind, format!("the name {n:?} is used twice")));
        }
    }
    Ok(())
}

/// Check the invariants every later stage relies on: finite geometry and parameters,
/// consistent mesh attributes, unique names, sane ranges.
pub fn validate(scene: &Scene, file: &str) -> Result<()> {
    for o in &scene.objects {
        let mesh = &scene.meshes[o.mesh];
        let field = format!("object {:?}", o.name);
        for (i, p) in mesh.positions.iter().enumerate() {
            check_finite(file, format!("{field} vertex {i} position"), &p.to_array())?;
        }
        for (i, n) in mesh.normals.iter().enumerate() {
            check_finite(file, format!("{field} vertex {i} normal"), &n.to_array())?;
        }
        for (i, uv) in mesh.uvs.iter().enumerate() {
            check_finite(file, format!("{field} vertex {i} uv"), &uv.to_array())?;
        }
        if mesh.normals.len() != mesh.positions.len() || mesh.uvs.len() != mesh.positions.len() {
            return Err(Error::bad_input(file, field, "normals/uvs do not match the vertex count"));
        }
        if let Some(t) = mesh.indices.iter().position(|t| t.iter().any(|&i| i as usize >= mesh.positions.len())) {
            return Err(Error::bad_input(file, format!("{field} triangle {t}"), "vertex index out of range"));
        }
        check_finite(file, format!("{field} transform"), &o.transform.to_cols_array())?;
        if o.transform.matrix3.determinant() == 0.0 {
            return Err(Error::bad_input(file, format!("{field} transform"), "is singular"));
        }
    }
    for m in &scene.materials {
        let field = format!("material {:?}", m.name);
        check_finite(file, field.clone(), &[m.base_color.to_array(), m.emission.to_array()].concat())?;
        check_finite(file, field.clone(), &[m.roughness, m.metallic])?;
        if !(0.0..=1.0).contains(&m.roughness) || !(0.0..=1.0).contains(&m.metallic) {
            return Err(Error::bad_input(file, field, "roughness and metallic must lie in [0, 1]"));
        }
        if let Some(t) = m.transmission {
            if !(t.ior.is_finite() && t.ior > 0.0 && (0.0..=1.0).contains(&t.weight)) {
                return Err(Error::bad_input(file, field, "transmission needs ior > 0 and a weight in [0, 1]"));
            }
            // An index-matched dielectric bends nothing and reflects nothing: it is invisible,
            // and rough microfacet transmission is undefined for it.
            if (t.ior - 1.0).abs() < 1e-3 {
                return Err(Error::bad_input(file, field, format!("ior {} is 1: the object would be invisible; remove it or give it a real ior", t.ior)));
            }
        }
    }
    check_finite(file, "background".into(), &scene.background.to_array())?;
    check_radiance(file, "background".into(), scene.background)?;
    for m in &scene.materials {
        check_radiance(file, format!("material {:?} emission", m.name), m.emission)?;
    }
    for l in &scene.rect_lights {
        check_radiance(file, format!("light {:?} radiance", l.name), l.radiance)?;
    }
    for v in &scene.variables {
        if let VariableTarget::Hue { saturation, brightness, .. } = v.target {
            check_finite(file, format!("variable {:?} saturation/brightness", v.name), &[saturation, brightness])?;
        }
    }
    if scene.camera.target_jitter.min_element() < 0.0 {
        return Err(Error::bad_input(file, "camera.target_jitter", "half-extents must not be negative"));
    }
    for l in &scene.rect_lights {
        let v = [l.corner.to_array(), l.edge_u.to_array(), l.edge_v.to_array(), l.radiance.to_array()].concat();
        check_finite(file, format!("light {:?}", l.name), &v)?;
    }
    check_unique(file, "objects", scene.objects.iter().map(|o| o.name.as_str()))?;
    check_unique(file, "materials", scene.materials.iter().map(|m| m.name.as_str()))?;
    check_unique(file, "lights", scene.rect_lights.iter().map(|l| l.name.as_str()))?;
    check_unique(file, "variables", scene.variables.iter().map(|v| v.name.as_str()))?;
    let c = &scene.camera;
    check_finite(file, "camera".into(), &[c.target.to_array(), c.up.to_array(), c.target_jitter.to_array()].concat())?;
    match c.position {
        CameraPosition::Box { min, max } => check_finite(file, "camera.position".into(), &[min.to_array(), max.to_array()].concat())?,
        CameraPosition::Orbit { center, radius, azimuth_deg, elevation_deg } => {
            let values = [center.x, center.y, center.z, radius.min, radius.max, azimuth_deg.min, azimuth_deg.max, elevation_deg.min, elevation_deg.max];
            check_finite(file, "camera.position".into(), &values)?;
            if radius.min < 0.0 {
                return Err(Error::bad_input(file, "camera.position.radius", "must not be negative"));
            }
        }
    }
    if c.up.cross(c.target - c.position.middle()).length_squared() == 0.0 {
        return Err(Error::bad_input(file, "camera.up", "must not be parallel to the view direction"));
    }
    check_finite(file, "camera.fov_x_deg".into(), &[c.fov_x_deg.min, c.fov_x_deg.max, c.near, c.far])?;
    if !(c.fov_x_deg.min > 0.0 && c.fov_x_deg.max < 180.0) {
        return Err(Error::bad_input(file, "camera.fov_x_deg", "must lie in (0, 180) degrees"));
    }
    if !(c.near > 0.0 && c.far > c.near) {
        return Err(Error::bad_input(file, "camera.near/far", "need 0 < near < far"));
    }
    for v in &scene.variables {
        let ordered = v.min < v.max;
        if !ordered || !v.min.is_finite() || !v.max.is_finite() {
            return Err(Error::bad_input(file, format!("variable {:?}", v.name), "range must be finite with min < max"));
        }
    }
    Ok(())
}
