//! `glassbake trace`: path trace one frame of a scene into an EXR (f32 linear RGB) and a PNG
//! preview beside it (clamp tone map, sRGB).

use std::path::PathBuf;

use super::dataset::{parse_estimator, parse_trace_device};
use anyhow::{Context, Result};
use clap::Args;
use glassbake_core::image::ExrPrecision;
use glassbake_core::seed::purpose_seed;
use glassbake_dataset::TraceDevice;
use glassbake_raster::RasterizerOptions;
use glassbake_scene::load_scene;
use glassbake_trace::{render, sample_trace_seed, Estimator, TraceSettings};
use glassbake_trace_gpu::GpuTracer;
use indicatif::{ProgressBar, ProgressStyle};

#[derive(Args)]
pub struct TraceArgs {
    /// A built-in name (cornellbox, cornellbox8, desk, bathroom, cornell-glass) or a scene path.
    scene: String,
    /// Render sample i of the sample set: its camera, its variable values, its trace seed
    /// (exactly what `glassbake dataset` renders for that sample).
    #[arg(long, conflicts_with_all = ["camera", "set"])]
    sample: Option<u64>,
    /// Seed of the sample set (with --sample), or the image seed (otherwise).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// With --sample: trace it with this image seed instead of its own, for an independent
    /// re-trace of the same camera and values (a reference, or a second seed to measure noise).
    #[arg(long, requires = "sample")]
    image_seed: Option<u64>,
    /// An explicit camera: position and look-at target, optionally the horizontal field of
    /// view in degrees (default: the middle of the scene's range).
    #[arg(long, value_name = "PX,PY,PZ,TX,TY,TZ[,FOV]", allow_hyphen_values = true)]
    camera: Option<String>,
    /// Set a scene variable (repeatable); the others keep their defaults.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 128)]
    res: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 256)]
    spp: u32,
    /// Samples per pixel on the pixels that show a transparent object (CPU; default: --spp).
    /// A dataset's test frame is `--sample i --spp <test spp> --glass-spp <its glass spp>`.
    #[arg(long)]
    glass_spp: Option<u32>,
    /// Longest path in segments (1 = emitters seen directly, 2 = direct light).
    #[arg(long, default_value_t = TraceSettings::DEFAULT_MAX_DEPTH)]
    max_depth: u32,
    /// The estimator, `TRANSPORT[+merging][+adaptive][+stratified]` (docs/trace.md):
    /// TRANSPORT is `caustic` (the path tracer plus a light tracer for the light that reaches
    /// surfaces through glass) or `plain` (the path tracer alone, the only one with --device
    /// wgpu); `+merging` (caustic only) takes what the camera sees through bending glass from
    /// photons: biased, a blur of about a pixel, much less noise on glass; `+adaptive` spreads
    /// the samples by the noise a pilot pass of 1/16 of them measured (from 256 spp);
    /// `+stratified` draws sample values from scrambled Sobol points. Default:
    /// `caustic+adaptive+stratified` on the CPU, what datasets trace (unbiased), and `plain`
    /// with --device wgpu. All but `+merging` converge to the same image.
    #[arg(long, value_parser = parse_estimator)]
    estimator: Option<Estimator>,
    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long, conflicts_with = "device")]
    threads: Option<usize>,
    /// `cpu` (the default; bit-identical for any thread count on one machine, other CPUs
    /// may differ in the last bits) or `wgpu`: the GPU tracer on a Vulkan adapter (chosen as
    /// the rasterizer's: `WGPU_ADAPTER_NAME`, else a discrete GPU first). The GPU runs the
    /// `plain` estimator only (no light tracer, uniform pixels, independent values): the same
    /// converged image as the CPU's default, with more noise at equal samples and other random
    /// numbers.
    #[arg(long, default_value = "cpu", value_parser = parse_trace_device)]
    device: TraceDevice,
    /// Output EXR; the PNG preview goes beside it with the extension .png.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: TraceArgs) -> Result<()> {
    // The PNG preview is written beside the EXR with the extension .png: any other extension
    // would let one overwrite the other.
    if !args.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        return Err(
            glassbake_core::Error::bad_input("--out", args.out.display().to_string(), "must name an .exr file (the .png preview goes beside it)").into()
        );
    }
    let scene = load_scene(&args.scene)?;
    for w in scene.warnings() {
        eprintln!("warning: {w}");
    }
    let (camera, values, image_seed) = match args.sample {
        Some(index) => {
            let sample = scene.sample(args.seed, index);
            let seed = args.image_seed.map_or_else(|| sample_trace_seed(sample.seed), |s| purpose_seed(s, "independent trace"));
            (sample.camera, sample.values, seed)
        }
        None => {
            let default_camera = scene.camera.middle();
            let camera = match &args.camera {
                Some(text) => scene.camera.camera_from_text(text)?,
                None => default_camera,
            };
            (camera, scene.values_from_assignments(&args.set)?, purpose_seed(args.seed, "trace"))
        }
    };
    let instance = scene.instantiate(&values)?;
    let estimator = args.estimator.unwrap_or(args.device.default_estimator());
    let settings = TraceSettings {
        max_depth: args.max_depth,
        threads: args.threads,
        estimator,
        glass_spp: args.glass_spp,
        ..TraceSettings::new(args.res, args.res, args.spp, image_seed)
    };

    // In pixel samples; the tracer re-scales it as it learns the real work.
    let bar = ProgressBar::new(args.res as u64 * args.res as u64 * args.spp as u64);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent:>3}%  {elapsed_precise} elapsed, ETA {eta_precise}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let gpu_tracer = match args.device {
        TraceDevice::Wgpu => Some(GpuTracer::new(&RasterizerOptions::default())?),
        TraceDevice::Cpu => None,
    };
    let on = gpu_tracer.as_ref().map_or_else(|| format!("CPU, rays cast by {}", glassbake_trace::RAY_CASTER), |t| t.adapter_name().to_string());
    bar.set_message(format!("tracing {} {}x{} @ {} spp ({estimator}, {on})", scene.name, args.res, args.res, args.spp));
    let progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let output = match &gpu_tracer {
        Some(tracer) => tracer.render(&instance, &camera, &settings, Some(&progress))?,
        None => render(&instance, &camera, &settings, Some(&progress))?,
    };
    bar.finish_and_clear();
    for w in &output.warnings {
        eprintln!("warning: {w}");
    }
    // Samples are discarded one by one; a pixel can still overflow when finite samples sum
    // past f32 (radiance too large for the scene's scale). Say so rather than write it quietly.
    let non_finite = output.image.data().iter().filter(|v| !v.is_finite()).count();
    if non_finite > 0 {
        eprintln!("warning: {non_finite} pixel values are NaN or infinite (radiance too large for f32?)");
    }

    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    output.image.write_exr(&args.out, ExrPrecision::F32)?;
    let preview = args.out.with_extension("png");
    output.image.write_png_rgb(&preview, [0, 1, 2])?;
    println!(
        "wrote {} and {} ({} samples in {:.1} s, {:.0} samples/s on {on}, {} discarded)",
        args.out.display(),
        preview.display(),
        output.samples,
        output.elapsed.as_secs_f64(),
        output.samples_per_second(),
        output.discarded_samples
    );
    for line in output.light_transport_summary() {
        println!("{line}");
    }
    Ok(())
}
