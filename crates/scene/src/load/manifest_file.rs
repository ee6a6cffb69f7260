//! The TOML manifest: the geometry it names, and its objects, lights, camera ranges and
//! variables applied to that geometry.

use std::path::Path;

use glam::Vec3;
use glassbake_core::{Error, Result};

use super::scene_files::FileSource;
use super::{load_geometry_from, require_file};
use crate::camera_spec::{CameraPosition, CameraSpec, Interval};
use crate::manifest::{parse_manifest, CameraManifest, Manifest, NumberOrRange, PositionManifest, TargetManifest};
use crate::model::{Material, RectLight, Scene};
use crate::variables::{Variable, VariableTarget};
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

/// The index of `name` among `names`. Refused where the geometry file gives that name to
/// several objects (or materials), which the loader tells apart as `name`, `name#1`, ...: a
/// manifest naming one of them would silently address whichever came first.
fn named(names: &[&str], name: &str, kind: &str, file: &str, field: &str) -> Result<usize> {
    let Some(index) = names.iter().position(|n| *n == name) else {
        return Err(Error::bad_input(file, field, format!("no {kind} named {name:?} ({kind}s: {})", name_list(names.iter().copied()))));
    };
    let namesakes: Vec<&str> = names.iter().copied().filter(|n| n.strip_prefix(name).is_some_and(|rest| rest.starts_with('#'))).collect();
    if !namesakes.is_empty() {
        return Err(Error::bad_input(
            file,
            field,
            format!(
                "the geometry file names {} {kind}s {name:?} (told apart as {name}, {}); give them distinct names in the geometry file",
                namesakes.len() + 1,
                namesakes.join(", ")
            ),
        ));
    }
    Ok(index)
}

/// Load a manifest and the geometry it points to, and apply its declarations.
pub fn load_manifest(path: &Path) -> Result<Scene> {
    load_manifest_from(path, FileSource::Disk)
}

pub(crate) fn load_manifest_from(path: &Path, source: FileSource) -> Result<Scene> {
    let file = path.display().to_string();
    require_file(path, source)?;
    let bytes = source.read(path, &file, "file")?;
    let text = String::from_utf8(bytes).map_err(|e| Error::bad_input(&file, "file", format!("not UTF-8 text: {e}")))?;
    let manifest = parse_manifest(&text).map_err(|(field, message)| Error::bad_input(&file, field, message))?;
    let geometry = source.folder(path)?.resolve("geometry", &manifest.geometry)?;
    let mut scene = load_geometry_from(&geometry, source)?;
    apply_manifest(&mut scene, &manifest, &file)?;
    Ok(scene)
}

/// The camera ranges a manifest's `[camera]` declares.
fn camera_spec(c: &CameraManifest, file: &str) -> Result<CameraSpec> {
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
    Ok(CameraSpec {
        position,
        target: Vec3::from(c.target),
        target_jitter: c.target_jitter.map(Vec3::from).unwrap_or(Vec3::ZERO),
        up: c.up.map(Vec3::from).unwrap_or(Vec3::Y),
        fov_x_deg: interval(&c.fov_x_deg, file, "camera.fov_x_deg")?,
        near: c.near.unwrap_or(0.01),
        far: c.far.unwrap_or(100.0),
    })
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
        let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
        let i = named(&names, name, "object", file, &format!("objects.{name}"))?;
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
        scene.camera = camera_spec(c, file)?;
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
            let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
            named(&names, name, "material", file, &format!("{field}.target.material"))
        };
        let object = |name: &str| {
            let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
            named(&names, name, "object", file, &format!("{field}.target.object"))
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
