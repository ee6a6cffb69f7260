//! `glassbake scene ...`: info, validate, export, mitsuba.

use std::path::PathBuf;

use anyhow::Result;
use clap::Subcommand;
use glassbake_scene::load_scene;

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
            print!("{}", s.summary());
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
