//! The glTF 2.0 loader (.gltf and .glb, with their buffers and images).

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{Affine2, Affine3A, Mat4, Vec2, Vec3, Vec4};
use glassbake_core::color::srgb_to_linear;
use glassbake_core::{Error, Result};

use super::scene_files::{FileSource, SceneFolder};
use super::{check_reference, empty_scene, finish_mesh, unique_name};
use crate::gltf_extensions;
use crate::model::{Material, Mesh, Object, Scene, Texture, Transmission};
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

/// The glTF document of `bytes`, validated, with every file reference checked before any
/// file is read.
fn parse_document(bytes: &[u8], label: &str) -> Result<(gltf::Document, Option<Vec<u8>>)> {
    let gltf_error = |e: gltf::Error| Error::bad_input(label, "glTF", e.to_string().replace('\n', " "));
    // The required extensions are checked above against what glassbake renders; the gltf
    // crate's own check (gltf 1.4.1) also refuses KHR_materials_specular and _volume, which
    // it parses, so it validates the document with that list emptied.
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes).map_err(gltf_error)?;
    let mut root = document.into_json();
    root.extensions_required.clear();
    // gltf-json 1.4.1's validation indexes the accessors with a primitive's POSITION before it
    // checks that the index exists (a panic): check it first.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(accessor) = primitive.attributes.get(&gltf::json::validation::Checked::Valid(gltf::Semantic::Positions)) {
                if accessor.value() >= root.accessors.len() {
                    return Err(Error::bad_input(
                        label,
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
            return Err(Error::bad_input(label, format!("images[{i}]"), problem));
        }
    }
    let document = gltf::Document::from_json(root).map_err(gltf_error)?;
    // Every reference is checked before any file is read.
    let uris = document.buffers().filter_map(|b| match b.source() {
        gltf::buffer::Source::Uri(uri) => Some((format!("buffers[{}].uri", b.index()), uri)),
        gltf::buffer::Source::Bin => None,
    });
    let image_uris = document.images().filter_map(|i| match i.source() {
        gltf::image::Source::Uri { uri, .. } => Some((format!("images[{}].uri", i.index()), uri)),
        gltf::image::Source::View { .. } => None,
    });
    for (field, uri) in uris.chain(image_uris) {
        check_reference(label, &field, uri)?;
    }
    Ok((document, blob))
}

/// Load a glTF 2.0 file (.gltf or .glb) with its buffers and textures.
pub fn load_gltf(path: &Path) -> Result<Scene> {
    load_gltf_from(path, FileSource::Disk)
}

pub(crate) fn load_gltf_from(path: &Path, source: FileSource) -> Result<Scene> {
    let label = path.display().to_string();
    let bytes = source.read(path, &label, "file")?;
    let (used, required) = gltf_extensions::declared_extensions(&bytes, &label)?;
    let extension_warnings = gltf_extensions::check_extensions(&used, &required, &label)?;
    let (document, blob) = parse_document(&bytes, &label)?;
    let folder = source.folder(path)?;
    let buffers = read_buffers(&document, &folder, blob)?;
    let images = read_images(&document, &folder, &buffers)?;
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

/// The document's buffers: the GLB's binary chunk, `data:` URIs, and files read through the
/// scene folder's rule, each exactly its declared `byteLength` (padded to four bytes, as
/// glTF aligns accessors).
fn read_buffers(document: &gltf::Document, folder: &SceneFolder, mut blob: Option<Vec<u8>>) -> Result<Vec<gltf::buffer::Data>> {
    let label = folder.label();
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let field = format!("buffers[{}]", buffer.index());
        let declared = buffer.length() as u64;
        let mut bytes = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| Error::bad_input(label, &field, "refers to the GLB binary chunk, which the file lacks"))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let decoded =
                    gltf::buffer::Data::from_source(buffer.source(), None).map_err(|e| Error::bad_input(label, format!("{field}.uri"), e.to_string()))?;
                decoded.0
            }
            gltf::buffer::Source::Uri(uri) => folder.read_declared(&format!("{field}.uri"), uri, declared)?,
        };
        if (bytes.len() as u64) < declared {
            return Err(Error::bad_input(label, format!("{field}.byteLength"), format!("declares {declared} bytes where the data holds {}", bytes.len())));
        }
        bytes.resize(bytes.len().next_multiple_of(4), 0);
        buffers.push(gltf::buffer::Data(bytes));
    }
    Ok(buffers)
}

/// The document's images, decoded: those inside the file (`data:` URIs, buffer views) by the
/// gltf crate, files read through the scene folder's rule. The image crate's default limits
/// bound the memory a decoded image may take.
fn read_images(document: &gltf::Document, folder: &SceneFolder, buffers: &[gltf::buffer::Data]) -> Result<Vec<gltf::image::Data>> {
    use gltf::image::{Format, Source};
    let label = folder.label();
    let mut images = Vec::new();
    for image in document.images() {
        let field = format!("images[{}]", image.index());
        let data = match image.source() {
            Source::Uri { uri, mime_type } if !uri.starts_with("data:") => {
                let bytes = folder.read(&format!("{field}.uri"), uri)?;
                let format = match mime_type {
                    Some("image/png") => Some(image::ImageFormat::Png),
                    Some("image/jpeg") => Some(image::ImageFormat::Jpeg),
                    _ => image::ImageFormat::from_path(uri).ok(),
                };
                let decoded = match format {
                    Some(format) => image::load_from_memory_with_format(&bytes, format),
                    None => image::load_from_memory(&bytes),
                }
                .map_err(|e| Error::bad_input(label, format!("{field}.uri"), format!("{uri}: {e}")))?;
                let (width, height) = (decoded.width(), decoded.height());
                let format = match decoded {
                    image::DynamicImage::ImageLuma8(_) => Format::R8,
                    image::DynamicImage::ImageLumaA8(_) => Format::R8G8,
                    image::DynamicImage::ImageRgb8(_) => Format::R8G8B8,
                    image::DynamicImage::ImageRgba8(_) => Format::R8G8B8A8,
                    other => return Err(Error::bad_input(label, field, format!("unsupported pixel format {:?} (8-bit textures only)", other.color()))),
                };
                gltf::image::Data { pixels: decoded.into_bytes(), format, width, height }
            }
            // Decoding these touches no file, whatever the base folder.
            source => gltf::image::Data::from_source(source, Some(Path::new(".")), buffers).map_err(|e| Error::bad_input(label, &field, e.to_string()))?,
        };
        images.push(data);
    }
    Ok(images)
}
