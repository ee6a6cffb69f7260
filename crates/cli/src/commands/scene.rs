//! `glassbake scene ...`: info, validate, export, mitsuba.

use std::path::PathBuf;

use anyhow::Result;
use clap::Subcommand;
use glassbake_scene::{load_scene, CameraPosition, Scene};

#[derive(Subcommand)]
pub enum SceneCommand {
    /// Print objects, transparent count, triangles, lights and variables with their ranges.
    Info {
        /// A built-in name (cornellbox, cornellbox8, desk, bathroom, cornell-glass) or a path
        /// to a manifest (.toml), glTF (.gltf/.glb) or OBJ file.
        scene: String,
    },
    /// Load and check a scene; print warnings; exit 2 on errors.
    Validate { scene: String },
    /// Write a scene as manifest.toml + scene.gltf (+ texture PNGs) into a directory.
    Export {
        scene: String,
        dir: PathBuf,
        /// Replace the scene files already in DIR (by default a folder holding any of them is
        /// refused).
        #[arg(long)]
        force: bool,
    },
    /// Write one scene instance (camera and variable values of sample i) as Mitsuba 3 XML.
    Mitsuba {
        scene: String,
        #[arg(long, default_value_t = 0)]
        sample: u64,
        /// Seed of the sample set (as in `glassbake dataset --seed`).
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(cmd: SceneCommand) -> Result<()> {
    match cmd {
        SceneCommand::Info { scene } => {
            let s = load_scene(&scene)?;
            print!("{}", describe(&s));
            for w in s.warnings() {
                eprintln!("warning: {w}");
            }
        }
        SceneCommand::Validate { scene } => {
            let s = load_scene(&scene)?;
            let warnings = s.warnings();
            for w in &warnings {
                eprintln!("warning: {w}");
            }
            println!("{scene}: valid ({} objects, {} transparent, {} warnings)", s.objects.len(), s.transparent_count(), warnings.len());
        }
        SceneCommand::Export { scene, dir, force } => {
            let s = load_scene(&scene)?;
            glassbake_scene::export::export_scene(&s, &dir, force)?;
            println!("wrote {}", dir.join("manifest.toml").display());
        }
        SceneCommand::Mitsuba { scene, sample, seed, out } => {
            let s = load_scene(&scene)?;
            let drawn = s.sample(seed, sample);
            let instance = s.instantiate(&drawn.values)?;
            glassbake_scene::mitsuba::write_mitsuba(&instance, &drawn.camera, &out)?;
            println!("wrote {}", out.display());
        }
    }
    Ok(())
}

/// The human-readable summary printed by `scene info`.
pub fn describe(s: &Scene) -> String {
    use std::fmt::Write;
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
    let _ = writeln!(out, "  camera: position {position}; target {} (+/- {}); fov_x [{}, {}] deg", c.target, c.target_jitter, c.fov_x_deg.min, c.fov_x_deg.max);
    out
}
