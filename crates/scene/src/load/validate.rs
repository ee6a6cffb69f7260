//! The checks every scene passes before a later stage sees it.

use glam::Vec3;
use glassbake_core::{Error, Result};

use crate::camera_spec::CameraPosition;
use crate::model::Scene;
use crate::variables::VariableTarget;
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
