//! A scene described for a person.

use std::fmt::Write;

use crate::{CameraPosition, Scene};

impl Scene {
    /// What the scene holds, for a person: objects, lights, variables, camera ranges
    /// (`glassbake scene info`).
    pub fn summary(&self) -> String {
        let s = self;
        let mut out = String::new();
        let _ = writeln!(out, "scene {}", s.name);
        let _ = writeln!(
            out,
            "  {} objects ({} transparent), {} triangles, {} meshes, {} textures, {} materials",
            s.objects.len(),
            s.transparent_count(),
            s.triangle_count(),
            s.meshes.len(),
            s.textures.len(),
            s.materials.len()
        );
        let _ = writeln!(out, "  objects:");
        for o in &s.objects {
            let m = &s.materials[o.material];
            let kind = match (o.transparent, m.dielectric_kind()) {
                (true, Some(k)) => format!("transparent ({k:?} dielectric, ior {})", m.transmission.map_or(1.0, |t| t.ior)).to_lowercase(),
                (true, None) => "transparent".to_string(),
                (false, _) if m.is_emissive() => "emissive".to_string(),
                (false, _) => "opaque".to_string(),
            };
            let _ = writeln!(out, "    {:<20} {:>7} tris  material {:<16} {kind}", o.name, s.meshes[o.mesh].triangle_count(), m.name);
        }
        let _ = writeln!(out, "  lights: {}", s.light_count());
        for l in &s.rect_lights {
            let _ = writeln!(out, "    {:<20} rectangle {:.2} m^2, radiance {}", l.name, l.area(), l.radiance);
        }
        for i in s.emissive_objects() {
            let o = &s.objects[i];
            let _ = writeln!(out, "    {:<20} emissive mesh, radiance {}", o.name, s.materials[o.material].emission);
        }
        let _ = writeln!(out, "  variables: {}", s.variables.len());
        for v in &s.variables {
            let _ = writeln!(out, "    {:<20} [{}, {}] default {}  {} of {}", v.name, v.min, v.max, v.default, v.kind_name(), s.variable_target_name(v));
        }
        let c = &s.camera;
        let position = match c.position {
            CameraPosition::Box { min, max } => format!("box {min} .. {max}"),
            CameraPosition::Orbit { center, radius, azimuth_deg, elevation_deg } => format!(
                "orbit about {center}, radius [{}, {}], azimuth [{}, {}] deg, elevation [{}, {}] deg",
                radius.min, radius.max, azimuth_deg.min, azimuth_deg.max, elevation_deg.min, elevation_deg.max
            ),
        };
        let _ =
            writeln!(out, "  camera: position {position}; target {} (+/- {}); fov_x [{}, {}] deg", c.target, c.target_jitter, c.fov_x_deg.min, c.fov_x_deg.max);
        out
    }
}
