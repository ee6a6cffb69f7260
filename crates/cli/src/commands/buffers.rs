//! `glassbake buffers`: rasterize one frame's buffers (opaque, naive, one transparency buffer
//! per transparent object) into a multi-layer EXR, with optional PNG previews.

use std::path::{Path, PathBuf};

use super::camera_arg::parse_camera;
use anyhow::Result;
use clap::{ArgGroup, Args};
use glassbake_core::image::ExrPrecision;
use glassbake_core::{Error, PlanarImage};
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
        (None, Some(text)) => (parse_camera(text, &scene)?, scene.values_from_assignments(&args.set)?),
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
        preview_channels(&image, name.trim())?;
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
        let path = preview(&image, name.trim(), &args.out)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The channels of the layer attribute `name` (e.g. `opaque.albedo`): 1 or 3 of them.
fn preview_channels(image: &PlanarImage, name: &str) -> Result<Vec<usize>> {
    let prefix = format!("{name}.");
    let channels: Vec<usize> = (0..image.channels().len()).filter(|&c| image.channels()[c].starts_with(&prefix)).collect();
    if channels.is_empty() {
        return Err(Error::bad_input("--png", name, "no such layer attribute (e.g. opaque.albedo, transparent.0.coverage)").into());
    }
    if !matches!(channels.len(), 1 | 3) {
        return Err(Error::bad_input("--png", name, "expected an attribute with 1 or 3 channels").into());
    }
    Ok(channels)
}

/// Write a PNG preview of one attribute: colours (albedo, L_d) with the clamp tone map and
/// sRGB; directions mapped from [-1, 1]; positions, depths and other scalars stretched over
/// their range in the image.
fn preview(image: &PlanarImage, name: &str, out: &Path) -> Result<PathBuf> {
    let channels = preview_channels(image, name)?;
    let stem = out.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "frame".into());
    let path = out.with_file_name(format!("{stem}.{name}.png"));
    let attribute = name.rsplit('.').next().unwrap_or(name);
    let range = |c: usize| {
        let p = image.plane(c);
        let lo = p.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = p.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        (lo, hi)
    };
    match (channels.len(), attribute) {
        (3, "albedo" | "Ld") => image.write_png_rgb(&path, [channels[0], channels[1], channels[2]])?,
        (3, _) => {
            // Map each channel linearly to [0, 1] (directions from [-1, 1]) and undo the sRGB
            // curve so the PNG stores the mapped value itself.
            let direction = matches!(attribute, "normal" | "wo");
            let mut mapped = image.select(&channels.iter().map(|&c| image.channels()[c].clone()).collect::<Vec<_>>())?;
            for (k, &c) in channels.iter().enumerate() {
                let (lo, hi) = if direction { (-1.0, 1.0) } else { range(c) };
                let scale = if hi > lo { 1.0 / (hi - lo) } else { 0.0 };
                for v in mapped.plane_mut(k) {
                    *v = glassbake_core::color::srgb_to_linear(((*v - lo) * scale).clamp(0.0, 1.0));
                }
            }
            mapped.write_png_rgb(&path, [0, 1, 2])?
        }
        (1, "coverage" | "roughness") => image.write_png_gray(&path, channels[0], 0.0, 1.0)?,
        (1, _) => {
            let (_, hi) = range(channels[0]);
            image.write_png_gray(&path, channels[0], 0.0, hi)?
        }
        _ => return Err(Error::bad_input("--png", name, "expected an attribute with 1 or 3 channels").into()),
    }
    Ok(path)
}
