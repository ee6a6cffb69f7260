//! The checks every scene passes before a later stage sees it. The values a scene can take
//! (materials, lights, object placements, the background) are checked by one function
//! against one set of physical bounds, at the scene's static values and again at both ends
//! of every variable's range, so a range cannot reach what a static value may not be.

use glam::Vec3;
use glassbake_core::{Error, Result};

use crate::camera_spec::CameraPosition;
use crate::model::Scene;
use crate::variables::VariableTarget;

/// The largest radiance a light, an emissive material or the background may have: far above
/// any scene the tone map can show, far below what overflows f32 once a path divides it by
/// small densities (a light of 3e38 filled images with inf).
pub const MAX_RADIANCE: f32 = 1e9;

/// The largest |coordinate| of any vertex, light corner or camera position, in scene units:
/// 100 km at glTF's metres. Far beyond it f32 cannot tell neighbouring millimetres apart and
/// the ray casters' boxes overflow.
pub const MAX_COORDINATE: f32 = 1e5;

/// The largest |u| or |v| of a texture coordinate (after its KHR_texture_transform): a
/// million repeats of a texture, where f32 still places a texel.
pub const MAX_TEXTURE_COORDINATE: f32 = 1e6;

/// The largest specular colour factor that still means something: the reflectance at normal
/// incidence is min(0.04 x colour, 1) (glTF KHR_materials_specular), saturated from 25 up.
pub const MAX_SPECULAR_COLOR: f32 = 25.0;

fn check_radiance(file: &str, field: String, radiance: Vec3) -> Result<()> {
    check_finite(file, field.clone(), &radiance.to_array())?;
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

/// Each value in [min, max]; `why` says what the bound means.
fn check_within(file: &str, field: String, values: &[f32], min: f32, max: f32, why: &str) -> Result<()> {
    check_finite(file, field.clone(), values)?;
    match values.iter().find(|v| !(min..=max).contains(*v)) {
        Some(v) => Err(Error::bad_input(file, field, format!("{v} is outside [{min}, {max}]: {why}"))),
        None => Ok(()),
    }
}

fn check_coordinates(file: &str, field: String, points: &[Vec3]) -> Result<()> {
    let values: Vec<f32> = points.iter().flat_map(|p| p.to_array()).collect();
    check_within(file, field, &values, -MAX_COORDINATE, MAX_COORDINATE, "beyond it f32 loses the scene's detail")
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

/// The eight corners of an object-space box.
fn box_corners((lo, hi): (Vec3, Vec3)) -> [Vec3; 8] {
    std::array::from_fn(|i| Vec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][(i >> 2) & 1]))
}

/// Every value a variable can change, against the physical bounds: the materials, the
/// lights, the objects' placements (through each mesh's object-space bounds, `mesh_bounds`)
/// and the background.
fn check_values(scene: &Scene, file: &str, mesh_bounds: &[Option<(Vec3, Vec3)>]) -> Result<()> {
    for m in &scene.materials {
        let field = |part: &str| format!("material {:?} {part}", m.name);
        check_within(file, field("base colour"), &m.base_color.to_array(), 0.0, 1.0, "an albedo or tint above 1 creates energy")?;
        let unit = "a factor in [0, 1] (glTF)";
        check_within(file, field("roughness"), &[m.roughness], 0.0, 1.0, unit)?;
        check_within(file, field("metallic"), &[m.metallic], 0.0, 1.0, unit)?;
        check_within(file, field("specular"), &[m.specular], 0.0, 1.0, unit)?;
        let saturates = "the reflectance at normal incidence, 0.04 x colour, saturates at 1";
        check_within(file, field("specular colour"), &m.specular_color.to_array(), 0.0, MAX_SPECULAR_COLOR, saturates)?;
        check_radiance(file, field("emission"), m.emission)?;
        if let Some(t) = m.transmission {
            if !(t.ior.is_finite() && t.ior > 0.0 && (0.0..=1.0).contains(&t.weight)) {
                return Err(Error::bad_input(file, field("transmission"), "transmission needs ior > 0 and a weight in [0, 1]"));
            }
            // An index-matched dielectric bends nothing and reflects nothing: it is invisible,
            // and rough microfacet transmission is undefined for it.
            if (t.ior - 1.0).abs() < 1e-3 {
                return Err(Error::bad_input(
                    file,
                    field("transmission"),
                    format!("ior {} is 1: the object would be invisible; remove it or give it a real ior", t.ior),
                ));
            }
        }
    }
    for l in &scene.rect_lights {
        let field = format!("light {:?}", l.name);
        check_coordinates(file, field.clone(), &l.corners())?;
        check_finite(file, field.clone(), &[l.edge_u.to_array(), l.edge_v.to_array()].concat())?;
        check_radiance(file, format!("{field} radiance"), l.radiance)?;
    }
    for o in &scene.objects {
        let field = format!("object {:?} transform", o.name);
        check_finite(file, field.clone(), &o.transform.to_cols_array())?;
        if o.transform.matrix3.determinant() == 0.0 {
            return Err(Error::bad_input(file, field, "is singular"));
        }
        if let Some(bounds) = mesh_bounds[o.mesh] {
            let corners = box_corners(bounds).map(|p| o.transform.transform_point3(p));
            check_coordinates(file, format!("object {:?} placement", o.name), &corners)?;
        }
    }
    check_radiance(file, "background".into(), scene.background)
}

/// The per-vertex data of every object's mesh: finite, consistent attribute counts, indices
/// in range, texture coordinates within [`MAX_TEXTURE_COORDINATE`].
fn check_meshes(scene: &Scene, file: &str) -> Result<()> {
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
            let why = "texture coordinates this far out cannot place a texel";
            check_within(file, format!("{field} vertex {i} uv"), &uv.to_array(), -MAX_TEXTURE_COORDINATE, MAX_TEXTURE_COORDINATE, why)?;
        }
        if mesh.normals.len() != mesh.positions.len() || mesh.uvs.len() != mesh.positions.len() {
            return Err(Error::bad_input(file, field, "normals/uvs do not match the vertex count"));
        }
        if let Some(t) = mesh.indices.iter().position(|t| t.iter().any(|&i| i as usize >= mesh.positions.len())) {
            return Err(Error::bad_input(file, format!("{field} triangle {t}"), "vertex index out of range"));
        }
    }
    Ok(())
}

fn check_camera(scene: &Scene, file: &str) -> Result<()> {
    let c = &scene.camera;
    if c.target_jitter.min_element() < 0.0 {
        return Err(Error::bad_input(file, "camera.target_jitter", "half-extents must not be negative"));
    }
    check_finite(file, "camera".into(), &[c.target.to_array(), c.up.to_array(), c.target_jitter.to_array()].concat())?;
    check_coordinates(file, "camera.target".into(), &[c.target - c.target_jitter, c.target + c.target_jitter])?;
    match c.position {
        CameraPosition::Box { min, max } => check_coordinates(file, "camera.position".into(), &[min, max])?,
        CameraPosition::Orbit { center, radius, azimuth_deg, elevation_deg } => {
            let values = [center.x, center.y, center.z, radius.min, radius.max, azimuth_deg.min, azimuth_deg.max, elevation_deg.min, elevation_deg.max];
            check_finite(file, "camera.position".into(), &values)?;
            if radius.min < 0.0 {
                return Err(Error::bad_input(file, "camera.position.radius", "must not be negative"));
            }
            check_coordinates(file, "camera.position".into(), &[center - Vec3::splat(radius.max), center + Vec3::splat(radius.max)])?;
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
    Ok(())
}

/// The values at which the variables are checked: the defaults, each variable at either end
/// of its range with the others at their defaults, and all at their minima and at their
/// maxima. Each variable's effect is monotonic in its value (a hue's colour stays within its
/// saturation and brightness, which are checked themselves), so its extremes lie at these.
fn variable_extremes(scene: &Scene) -> Vec<(String, Vec<f32>)> {
    let defaults = scene.default_values();
    let mut extremes = Vec::new();
    for (i, v) in scene.variables.iter().enumerate() {
        for (end, value) in [("min", v.min), ("max", v.max)] {
            let mut values = defaults.clone();
            values[i] = value;
            extremes.push((format!("variables[{i}] ({}) at its {end} {value}", v.name), values));
        }
    }
    if scene.variables.len() > 1 {
        extremes.push(("every variable at its min".into(), scene.variables.iter().map(|v| v.min).collect()));
        extremes.push(("every variable at its max".into(), scene.variables.iter().map(|v| v.max).collect()));
    }
    extremes
}

/// The most variables a scene may declare: each is an input plane of the network, and
/// validation instantiates the scene at both ends of each.
pub const MAX_VARIABLES: usize = 256;

fn check_variables(scene: &Scene, file: &str, mesh_bounds: &[Option<(Vec3, Vec3)>]) -> Result<()> {
    if scene.variables.len() > MAX_VARIABLES {
        return Err(Error::bad_input(file, "variables", format!("{} variables; a scene has at most {MAX_VARIABLES}", scene.variables.len())));
    }
    for (i, v) in scene.variables.iter().enumerate() {
        let field = format!("variables[{i}] ({})", v.name);
        if !(v.min < v.max && v.min.is_finite() && v.max.is_finite()) {
            return Err(Error::bad_input(file, format!("{field}.range"), "must be finite with min < max"));
        }
        match v.target {
            VariableTarget::Hue { saturation, brightness, .. } => {
                let why = "an HSV colour's saturation and brightness lie in [0, 1]";
                check_within(file, format!("{field}.target"), &[saturation, brightness], 0.0, 1.0, why)?;
            }
            VariableTarget::Translation { axis, .. } | VariableTarget::LightTranslation { axis, .. } if !(axis.is_finite() && axis.length_squared() > 0.0) => {
                return Err(Error::bad_input(file, format!("{field}.target.axis"), "must be a nonzero finite vector"));
            }
            _ => {}
        }
    }
    for (at, values) in variable_extremes(scene) {
        let instance = scene.instantiate(&values)?;
        check_values(&instance, file, mesh_bounds).map_err(|e| match e {
            Error::BadInput { file, field, message } => Error::bad_input(file, format!("{at}: {field}"), message),
            other => other,
        })?;
    }
    Ok(())
}

/// Check the invariants every later stage relies on: finite geometry, every value the scene
/// can take (static or through a variable) within its physical bounds, unique names, sane
/// camera ranges.
pub fn validate(scene: &Scene, file: &str) -> Result<()> {
    check_meshes(scene, file)?;
    let mesh_bounds: Vec<Option<(Vec3, Vec3)>> = scene.meshes.iter().map(|m| m.bounds()).collect();
    check_values(scene, file, &mesh_bounds)?;
    check_unique(file, "objects", scene.objects.iter().map(|o| o.name.as_str()))?;
    check_unique(file, "materials", scene.materials.iter().map(|m| m.name.as_str()))?;
    check_unique(file, "lights", scene.rect_lights.iter().map(|l| l.name.as_str()))?;
    check_unique(file, "variables", scene.variables.iter().map(|v| v.name.as_str()))?;
    check_camera(scene, file)?;
    check_variables(scene, file, &mesh_bounds)
}
