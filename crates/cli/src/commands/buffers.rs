//! `glassbake buffers`: rasterize one frame's buffers (opaque, naive, one transparency buffer
//! per transparent object) into a multi-layer EXR, with optional PNG previews.

use std::path::PathBuf;

use anyhow::Result;
use clap::{ArgGroup, Args};
use glassbake_core::image::ExrPrecision;
use glassbake_core::preview::{attribute_channels, write_attribute_preview};
use glassbake_core::Error;
use glassbake_raster::{Rasterizer, RasterizerOptions};
use glassbake_scene::load_scene;

#[derive(Args)]
#[command(group(ArgGroup::new("view").required(true).args(["sample", "camera"])))]
pub struct BuffersArgs {
    /// A built-in name (cornellbox, cornellbox8, desk, bathroom, cornell-glass) or a scene file.
    pub scene: String,
    /// Render sample i of the sample set (camera and variable values drawn from the scene's
    /// ranges, as in `glassbake dataset`).
    #[arg(long)]
    pub sample: Option<u64>,
    /// Seed of the sample set.
    #[arg(long, default_value_t = 0, requires = "sample")]
    pub seed: u64,
    /// Camera as px,py,pz,tx,ty,tz[,fov_x_deg] (position, look-at target, horizontal field of
    /// view; default fov: the middle of the scene's range).
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Variable values for --camera, NAME=VALUE (others take their defaults).
    #[arg(long = "set", requires = "camera")]
    pub set: Vec<String>,
    /// Image side in pixels (square images).
    #[arg(long, default_value_t = 256)]
    pub res: u32,
    /// The EXR file to write (layers opaque, naive, transparent.K, and the light coverage of the
    /// opaque and naive G-buffers, opaque_light and naive_light).
    #[arg(long)]
    pub out: PathBuf,
    /// Write half floats instead of 32-bit floats.
    #[arg(long)]
    pub half: bool,
    /// PNG previews of LAYER.ATTRIBUTE, comma-separated (e.g. opaque.albedo,opaque.Ld,
    /// transparent.0.coverage), written next to the EXR as <out stem>.<LAYER.ATTRIBUTE>.png.
    #[arg(long, value_delimiter = ',')]
    pub png: Vec<String>,
}

pub fn run(args: BuffersArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    for w in scene.warnings() {
        eprintln!("warning: {w}");
    }
    let (camera, values) = match (args.sample, &args.camera) {
        (Some(i), _) => {
            let drawn = scene.sample(args.seed, i);
            (drawn.camera, drawn.values)
        }
        (None, Some(text)) => (scene.camera.camera_from_text(text)?, scene.values_from_assignments(&args.set)?),
        (None, None) => unreachable!("clap requires --sample or --camera"),
    };
    let instance = scene.instantiate(&values)?;
    if args.res == 0 || args.res > glassbake_raster::MAX_RESOLUTION {
        return Err(Error::bad_input("--res", args.res.to_string(), format!("must be in [1, {}]", glassbake_raster::MAX_RESOLUTION)).into());
    }
    let mut rasterizer = Rasterizer::new(RasterizerOptions::default())?;
    let buffers = rasterizer.render(&instance, &camera, args.res, args.res)?;
    let image = buffers.combined()?;
    // Every --png name is checked before anything is written.
    for name in &args.png {
        attribute_channels(&image, name.trim())?;
    }
    let precision = if args.half { ExrPrecision::F16 } else { ExrPrecision::F32 };
    image.write_exr(&args.out, precision)?;
    println!(
        "wrote {} ({}x{}, {} channels: opaque, naive, {} transparency buffers) on {}",
        args.out.display(),
        args.res,
        args.res,
        image.channels().len(),
        buffers.transparent.len(),
        rasterizer.adapter_info().name
    );
    for name in &args.png {
        let path = write_attribute_preview(&image, name.trim(), &args.out)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
