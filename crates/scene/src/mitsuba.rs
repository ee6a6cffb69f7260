//! Mitsuba 3 XML export of one scene instance and camera, so a user can render ground truth
//! with Mitsuba 3 (as the paper did) and compare it with glassbake's own path tracer.
//! Meshes are baked to world space as binary PLY files beside the XML; textures as PNGs.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use glassbake_core::image::write_bytes_atomically;
use glassbake_core::output_dir::{claim_output_dir, OutputKind};
use glassbake_core::{Camera, Result};

use crate::export::texture_png;
use crate::model::{DielectricKind, Material, Mesh, Scene};

/// Binary little-endian PLY with positions, normals and UVs. UVs keep glassbake's (glTF's)
/// top-down v, which is also Mitsuba's internal convention for PLY data.
pub fn ply_bytes(mesh: &Mesh) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.indices.len()
    )
    .into_bytes();
    for i in 0..mesh.positions.len() {
        let values = [mesh.positions[i].to_array(), mesh.normals[i].to_array()].concat();
        for v in values.iter().chain(mesh.uvs[i].to_array().iter()) {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for t in &mesh.indices {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    out
}

fn rgb(v: glam::Vec3) -> String {
    format!("{:.6}, {:.6}, {:.6}", v.x, v.y, v.z)
}

fn bsdf_xml(m: &Material, texture_files: &[String]) -> String {
    let tint = format!("<rgb name=\"specular_transmittance\" value=\"{}\"/>", rgb(m.base_color));
    match m.dielectric_kind() {
        Some(DielectricKind::Thin) => {
            if m.roughness >= crate::model::SMOOTH_ROUGHNESS {
                // Mitsuba 3 has no rough thin dielectric; glassbake's tracer does (docs/trace.md).
                tracing::warn!("material {}: Mitsuba has no rough thin dielectric; exported as a smooth pane (roughness {} dropped)", m.name, m.roughness);
            }
            let ior = m.transmission.map_or(1.5, |t| t.ior);
            format!("<bsdf type=\"thindielectric\"><float name=\"int_ior\" value=\"{ior}\"/>{tint}</bsdf>")
        }
        Some(DielectricKind::Smooth) => {
            let ior = m.transmission.map_or(1.5, |t| t.ior);
            format!("<bsdf type=\"dielectric\"><float name=\"int_ior\" value=\"{ior}\"/>{tint}</bsdf>")
        }
        Some(DielectricKind::Rough) => {
            let ior = m.transmission.map_or(1.5, |t| t.ior);
            // Mitsuba's alpha is glTF's roughness squared.
            format!(
                "<bsdf type=\"roughdielectric\"><string name=\"distribution\" value=\"ggx\"/>\
                 <float name=\"alpha\" value=\"{}\"/><float name=\"int_ior\" value=\"{ior}\"/>{tint}</bsdf>",
                m.roughness * m.roughness
            )
        }
        None => {
            let base = match m.base_color_texture {
                // Mitsuba's bitmap texture cannot be scaled here, so the base colour factor
                // is dropped (it is white in every built-in scene).
                Some(t) => format!("<texture type=\"bitmap\" name=\"base_color\"><string name=\"filename\" value=\"{}\"/></texture>", texture_files[t]),
                None => format!("<rgb name=\"base_color\" value=\"{}\"/>", rgb(m.base_color)),
            };
            if m.specular <= 0.0 && m.metallic <= 0.0 {
                // No specular layer: exactly Mitsuba's Lambertian `diffuse`.
                let reflectance = base.replace("name=\"base_color\"", "name=\"reflectance\"");
                return format!("<bsdf type=\"diffuse\">{reflectance}</bsdf>");
            }
            if m.metallic <= 0.0 {
                return dielectric_base_blend_xml(m, &base);
            }
            // Metals: `principled` is the closest stock plugin (Disney diffuse for the
            // non-metallic part, so a partly metallic surface is approximate);
            // `specular` maps principled's F0 = 0.08 x specular to glassbake's 0.04 x weight x colour.
            let specular = (0.5 * m.specular * m.specular_color.max_element()).clamp(0.0, 1.0);
            format!(
                "<bsdf type=\"principled\">{base}<float name=\"roughness\" value=\"{}\"/><float name=\"metallic\" value=\"{}\"/>\
                 <float name=\"specular\" value=\"{specular}\"/></bsdf>",
                m.roughness, m.metallic
            )
        }
    }
}

/// Cosine-weighted hemispherical mean of Schlick's Fresnel term: F0 + (1 - F0) x 2 x
/// integral of (1 - mu)^5 mu over [0, 1] = F0 + (1 - F0) / 21.
fn mean_schlick(f0: f32) -> f32 {
    f0 + (1.0 - f0) / 21.0
}

/// glassbake's non-metallic opaque material, (1 - F(wo.n)) x base / pi + F(wo.h) x GGX
/// specular (crates/trace/src/bsdf.rs), as Mitsuba's `blendbsdf` of a `diffuse` and a
/// `roughconductor` with k = 0 (a dielectric's Fresnel reflection of IOR 1.5, F0 = 0.04).
/// A blend weight cannot depend on the view angle, so the diffuse part's 1 - F(wo.n) becomes
/// its cosine-weighted mean; the conductor's weight is folded into its (unbounded) reflectance
/// so that the specular lobe keeps its full strength. The tint scales the whole Fresnel curve
/// where glassbake's Schlick term tints F0 only. Measured against glassbake on a glTF box in
/// docs/trace.md.
fn dielectric_base_blend_xml(m: &Material, base: &str) -> String {
    let f0 = (0.04 * m.specular_color.max_element()).min(1.0);
    let specular_blend = (m.specular * mean_schlick(f0)).clamp(1e-4, 1.0);
    let specular_tint = (0.04 * m.specular_color).min(glam::Vec3::ONE) / 0.04 * (m.specular / specular_blend);
    let reflectance = base.replace("name=\"base_color\"", "name=\"reflectance\"");
    format!(
        "<bsdf type=\"blendbsdf\"><float name=\"weight\" value=\"{specular_blend}\"/>\
         <bsdf type=\"diffuse\">{reflectance}</bsdf>\
         <bsdf type=\"roughconductor\"><string name=\"distribution\" value=\"ggx\"/>\
         <float name=\"alpha\" value=\"{}\"/><float name=\"eta\" value=\"1.5\"/><float name=\"k\" value=\"0\"/>\
         <texture type=\"srgb\" name=\"specular_reflectance\"><rgb name=\"color\" value=\"{}\"/>\
         <boolean name=\"unbounded\" value=\"true\"/></texture></bsdf></bsdf>",
        (m.roughness * m.roughness).max(1e-3),
        rgb(specular_tint)
    )
}

/// A user's name as the text of an XML comment: a comment may not hold "--" nor end in "-",
/// so an object named "a --> <shape .../>" cannot close it early and inject elements.
fn comment_text(name: &str) -> String {
    let mut text: String = name.chars().map(|c| if c.is_control() { ' ' } else { c }).collect();
    while text.contains("--") {
        text = text.replace("--", "- -");
    }
    if text.ends_with('-') {
        text.push(' ');
    }
    text
}

/// The output-folder kind of the meshes and textures an exported XML refers to.
pub const MITSUBA_ASSETS: OutputKind = OutputKind { name: "Mitsuba export's assets", signatures: &["meshes"] };

/// The folder beside `out` that holds its meshes and textures: named after the XML file, so
/// that two exports side by side never share (and silently change) each other's files.
pub fn assets_dir(out: &Path) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into());
    out.with_file_name(format!("{stem}_assets"))
}

/// `s` as an XML attribute value.
fn xml_attribute(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Write `out` (XML) and, beside it, `<stem>_assets/meshes/*.ply` and
/// `<stem>_assets/textures/*.png` (a folder of the user's own files there is refused before
/// anything is written). Resolution and samples per pixel are XML defaults (`-Dres=512
/// -Dspp=1024` on Mitsuba's command line).
pub fn write_mitsuba(scene: &Scene, camera: &Camera, out: &Path) -> Result<()> {
    let assets = assets_dir(out);
    claim_output_dir(&assets, MITSUBA_ASSETS, "--out")?;
    let assets_name = assets.file_name().expect("a file name").to_string_lossy().into_owned();
    for m in &scene.materials {
        if m.base_color_texture.is_some() && m.base_color != glam::Vec3::ONE {
            tracing::warn!("material {}: the base colour factor of a textured material is not exported to Mitsuba", m.name);
        }
        if m.specular_texture.is_some() || m.specular_color_texture.is_some() {
            tracing::warn!("material {}: specular textures are not exported to Mitsuba (their factors are)", m.name);
        }
        if m.transmission.is_some_and(|t| t.weight < 1.0) {
            tracing::warn!("material {}: partial transmission exported as full transmission", m.name);
        }
    }
    let mut texture_files = Vec::new();
    for (i, t) in scene.textures.iter().enumerate() {
        let rel = format!("textures/texture{i}.png");
        write_bytes_atomically(&assets.join(&rel), &texture_png(t)?)?;
        texture_files.push(xml_attribute(&format!("{assets_name}/{rel}")));
    }
    let mut xml = String::new();
    let _ = writeln!(xml, "<!-- glassbake scene {} exported for Mitsuba 3 -->", comment_text(&scene.name));
    let _ = writeln!(xml, "<scene version=\"3.0.0\">");
    let _ = writeln!(xml, "  <default name=\"spp\" value=\"256\"/>\n  <default name=\"res\" value=\"256\"/>\n  <default name=\"max_depth\" value=\"64\"/>");
    let _ = writeln!(xml, "  <integrator type=\"path\"><integer name=\"max_depth\" value=\"$max_depth\"/></integrator>");
    let (p, t, u) = (camera.position, camera.target, camera.up);
    let _ = writeln!(
        xml,
        "  <sensor type=\"perspective\">\n    <string name=\"fov_axis\" value=\"x\"/>\n    <float name=\"fov\" value=\"{}\"/>\n    \
         <float name=\"near_clip\" value=\"{}\"/>\n    <float name=\"far_clip\" value=\"{}\"/>\n    \
         <transform name=\"to_world\"><lookat origin=\"{}\" target=\"{}\" up=\"{}\"/></transform>\n    \
         <sampler type=\"independent\"><integer name=\"sample_count\" value=\"$spp\"/></sampler>\n    \
         <film type=\"hdrfilm\"><integer name=\"width\" value=\"$res\"/><integer name=\"height\" value=\"$res\"/>\
         <rfilter type=\"box\"/></film>\n  </sensor>",
        camera.fov_x_deg,
        camera.near,
        camera.far,
        rgb(p),
        rgb(t),
        rgb(u)
    );
    if scene.background.max_element() > 0.0 {
        let _ = writeln!(xml, "  <emitter type=\"constant\"><rgb name=\"radiance\" value=\"{}\"/></emitter>", rgb(scene.background));
    }
    for (i, o) in scene.objects.iter().enumerate() {
        let rel = format!("meshes/{i:03}.ply");
        write_bytes_atomically(&assets.join(&rel), &ply_bytes(&scene.world_mesh(i)))?;
        let rel = xml_attribute(&format!("{assets_name}/{rel}"));
        let m = &scene.materials[o.material];
        let emitter =
            if m.is_emissive() { format!("<emitter type=\"area\"><rgb name=\"radiance\" value=\"{}\"/></emitter>", rgb(m.emission)) } else { String::new() };
        let _ = writeln!(
            xml,
            "  <!-- {} -->\n  <shape type=\"ply\"><string name=\"filename\" value=\"{rel}\"/>{}{emitter}</shape>",
            comment_text(&o.name),
            bsdf_xml(m, &texture_files)
        );
    }
    for l in &scene.rect_lights {
        // Mitsuba's rectangle spans [-1, 1]^2 in its xy-plane and emits towards +z.
        let (hu, hv, n, c) = (0.5 * l.edge_u, 0.5 * l.edge_v, l.normal(), l.center());
        let m = [[hu.x, hv.x, n.x, c.x], [hu.y, hv.y, n.y, c.y], [hu.z, hv.z, n.z, c.z], [0.0, 0.0, 0.0, 1.0]];
        let matrix: Vec<String> = m.iter().flatten().map(|v| format!("{v}")).collect();
        let _ = writeln!(
            xml,
            "  <!-- light {} -->\n  <shape type=\"rectangle\"><transform name=\"to_world\"><matrix value=\"{}\"/></transform>\
             <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0, 0, 0\"/></bsdf>\
             <emitter type=\"area\"><rgb name=\"radiance\" value=\"{}\"/></emitter></shape>",
            comment_text(&l.name),
            matrix.join(" "),
            rgb(l.radiance)
        );
        if l.two_sided {
            tracing::warn!("light {}: Mitsuba area emitters are one-sided; exported facing its normal only", l.name);
        }
    }
    let _ = writeln!(xml, "</scene>");
    write_bytes_atomically(out, xml.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn float_attribute(xml: &str, name: &str) -> f32 {
        let key = format!("name=\"{name}\" value=\"");
        let start = xml.find(&key).unwrap_or_else(|| panic!("{name} in {xml}")) + key.len();
        let end = start + xml[start..].find('"').unwrap();
        xml[start..end].split(',').next().unwrap().trim().parse().unwrap()
    }

    #[test]
    fn mean_schlick_matches_quadrature() {
        for f0 in [0.0f32, 0.04, 0.5] {
            let n = 100_000;
            let quadrature: f64 = (0..n)
                .map(|i| {
                    let mu = (i as f64 + 0.5) / n as f64;
                    let f = f0 as f64 + (1.0 - f0 as f64) * (1.0 - mu).powi(5);
                    2.0 * f * mu / n as f64
                })
                .sum();
            assert!((mean_schlick(f0) as f64 - quadrature).abs() < 1e-6, "{f0}: {} vs {quadrature}", mean_schlick(f0));
        }
    }

    #[test]
    fn lambertian_exports_as_diffuse_and_the_default_opaque_as_a_blend() {
        let xml = bsdf_xml(&Material::lambertian("wall", Vec3::splat(0.5)), &[]);
        assert!(xml.starts_with("<bsdf type=\"diffuse\">"), "{xml}");
        let mut m = Material::diffuse("wall", Vec3::splat(0.5));
        m.specular = 0.5;
        m.roughness = 0.6;
        let xml = bsdf_xml(&m, &[]);
        assert!(xml.starts_with("<bsdf type=\"blendbsdf\">"), "{xml}");
        // The diffuse part keeps 1 - (mean Fresnel x weight); the specular part, once the
        // blend weight multiplies its reflectance, has exactly the layer's weight.
        let weight = float_attribute(&xml, "weight");
        assert!((weight - 0.5 * mean_schlick(0.04)).abs() < 1e-6);
        assert!((weight * float_attribute(&xml, "color") - 0.5).abs() < 1e-5);
        assert!((float_attribute(&xml, "alpha") - 0.36).abs() < 1e-6);
        m.metallic = 1.0;
        assert!(bsdf_xml(&m, &[]).starts_with("<bsdf type=\"principled\">"));
    }
}
