//! A scene's triangles and textures as the GPU kernels read them, one packing for the GPU
//! tracer and the through pass: each triangle's attribute record, the texture table and the
//! texels, and the record size and flags, written into their WGSL from here. Each kernel keeps
//! its own material record (the tracer's BSDF needs more than the through pass's colour).

use glam::Vec3;
use glassbake_core::wgsl::{constants, Value};
use glassbake_scene::{MipChain, Scene};

use crate::triangle::{Owner, TriangleAttributes};

/// A triangle's attribute record in vec4s: its corners (w: the material or light index, the
/// emitter index, the flags), the vertex normals, the UVs.
pub const ATTRIBUTE_VEC4S: usize = 8;
/// Flags of an attribute record: one of a rectangle light's triangles (its index is a
/// light's, not a material's); shading normals present; may let shadow rays through.
pub const ATTR_RECT_LIGHT: u32 = 1;
pub const ATTR_HAS_NORMALS: u32 = 2;
pub const ATTR_PASS_THROUGH: u32 = 4;
/// No texture, emitter or node.
pub const NONE: u32 = u32::MAX;

/// `x`'s bits in an f32 lane.
pub fn bits(x: u32) -> f32 {
    f32::from_bits(x)
}

pub fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

/// Appends the attribute record of each of `triangles` to `out`.
pub fn push_attributes(triangles: &[TriangleAttributes], out: &mut Vec<[f32; 4]>) {
    out.reserve(triangles.len() * ATTRIBUTE_VEC4S);
    for t in triangles {
        let (material_or_light, mut flags) = match t.owner {
            Owner::Object { material, .. } => (material, 0),
            Owner::RectLight { light } => (light, ATTR_RECT_LIGHT),
        };
        if t.normals.is_some() {
            flags |= ATTR_HAS_NORMALS;
        }
        if t.may_pass_through {
            flags |= ATTR_PASS_THROUGH;
        }
        let [p0, p1, p2] = t.positions;
        out.extend([v4(p0, bits(material_or_light)), v4(p1, bits(t.emitter.unwrap_or(NONE))), v4(p2, bits(flags))]);
        out.extend(t.normals.unwrap_or([Vec3::ZERO; 3]).map(|n| v4(n, 0.0)));
        let [t0, t1, t2] = t.uvs;
        out.extend([[t0.x, t0.y, t1.x, t1.y], [t2.x, t2.y, 0.0, 0.0]]);
    }
}

/// Appends the texture table (one `(texel offset, width, height, -)` a texture) to
/// `materials` and the scene's texels to `texels`; returns where the table starts in
/// `materials`, in vec4s.
pub fn push_textures(scene: &Scene, materials: &mut Vec<[f32; 4]>, texels: &mut Vec<[f32; 4]>) -> u32 {
    let table = materials.len() as u32;
    for t in &scene.textures {
        materials.push([bits(texels.len() as u32), bits(t.width), bits(t.height), 0.0]);
        texels.extend(t.texels.iter().map(|c| c.to_array()));
    }
    table
}

/// Appends the through pass's texture table (one `(texel offset, width, height, levels)` a
/// texture, its mip levels one after another from the offset, each half the one before:
/// `MipChain`) to `materials` and the levels' texels to `texels`; returns where the table
/// starts in `materials`, in vec4s. Level 0 is laid out as [`push_textures`] lays it out.
pub fn push_mip_textures(chains: &[MipChain], materials: &mut Vec<[f32; 4]>, texels: &mut Vec<[f32; 4]>) -> u32 {
    let table = materials.len() as u32;
    for chain in chains {
        let full = &chain.levels[0];
        materials.push([bits(texels.len() as u32), bits(full.width), bits(full.height), bits(chain.levels.len() as u32)]);
        for level in &chain.levels {
            texels.extend(level.texels.iter().map(|c| c.to_array()));
        }
    }
    table
}

/// The record size and flags as WGSL constants.
pub fn wgsl_constants() -> String {
    constants(&[
        ("ATTRIBUTE_VEC4S", Value::U32(ATTRIBUTE_VEC4S as u32)),
        ("ATTR_RECT_LIGHT", Value::U32(ATTR_RECT_LIGHT)),
        ("ATTR_HAS_NORMALS", Value::U32(ATTR_HAS_NORMALS)),
        ("ATTR_PASS_THROUGH", Value::U32(ATTR_PASS_THROUGH)),
        ("NONE", Value::U32(NONE)),
    ])
}
