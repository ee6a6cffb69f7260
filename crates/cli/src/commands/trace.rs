//! `glassbake trace`: path trace one frame of a scene into an EXR (f32 linear RGB) and a PNG
//! preview beside it (clamp tone map, sRGB).

use std::path::PathBuf;

use super::camera_arg::parse_camera;
use super::dataset::parse_trace_device;
use anyhow::{Context, Result};
use clap::Args;
use glassbake_core::image::ExrPrecision;
use glassbake_core::seed::purpose_seed;
use glassbake_dataset::TraceDevice;
use glassbake_raster::RasterizerOptions;
use glassbake_scene::load_scene;
use glassbake_trace::{render, sample_trace_seed, Integrator, TraceSettings};
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
    /// Light-transport estimator: `caustic` (the path tracer plus light tracing of the light
    /// that reaches surfaces through glass; the default on the CPU, and what new CPU datasets
    /// use), `plain` (the path tracer alone, area light sampling; the default with --device
    /// wgpu), `solid-angle` (rectangle lights sampled by solid angle) or `guided` (solid angle
    /// plus path guiding learned over the first quarter of the samples). All converge to the
    /// same image; docs/trace.md has their measured efficiency.
    #[arg(long, value_parser = parse_integrator)]
    integrator: Option<Integrator>,
    /// `adaptive` (the default on the CPU, and what new CPU datasets use): a pilot pass of
    /// 1/16 of the samples measures where the noise is and the rest go there, each pixel
    /// keeping at least a quarter of its share (from 256 spp; below, pixels are sampled
    /// uniformly); or `uniform` (every pixel --spp; the only choice with --device wgpu and
    /// --integrator guided). Same total of samples, same converged image.
    #[arg(long, value_parser = parse_sampling)]
    sampling: Option<bool>,
    /// `stratified` (the default on the CPU, and what new CPU datasets use): each sample's
    /// position in its pixel and its first vertices' light and BSDF samples come from
    /// scrambled Sobol points, so a pixel's samples cover them evenly; or `independent`
    /// (independent random numbers; the only choice with --device wgpu). Same converged image.
    #[arg(long, value_parser = parse_sampler)]
    sampler: Option<bool>,
    /// With `--integrator caustic` (CPU): photon merging of what the camera sees through
    /// bending glass: the caustics seen in or through glass, and where rough glass blurs the
    /// view widely (a frosted partition) all light that scattered, from photons' density
    /// estimates instead of path tracing; and, in scenes with a black background, the light
    /// of many bounces by a final gather at the second vertex. Biased (a blur of about a
    /// pixel, shrinking as --spp grows), far less noise on glass; docs/trace.md.
    #[arg(long)]
    photon_merging: bool,
    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long, conflicts_with = "device")]
    threads: Option<usize>,
    /// `cpu` (the default; bit-identical for any thread count on one machine, other CPUs
    /// may differ in the last bits) or `wgpu`: the GPU tracer on a Vulkan adapter (chosen as
    /// the rasterizer's: `WGPU_ADAPTER_NAME`, else a discrete GPU first). The GPU has no light
    /// tracer, adaptive sampling or stratified values; its default estimator is `plain`: the
    /// same converged image as the CPU's default, with more noise at equal samples and other
    /// random numbers.
    #[arg(long, default_value = "cpu", value_parser = parse_trace_device)]
    device: TraceDevice,
    /// Output EXR; the PNG preview goes beside it with the extension .png.
    #[arg(long)]
    out: PathBuf,
}

/// Whether `--sampling` asks for adaptive sampling.
fn parse_sampling(name: &str) -> std::result::Result<bool, String> {
    match name {
        "adaptive" => Ok(true),
        "uniform" => Ok(false),
        other => Err(format!("unknown sampling {other:?}: expected adaptive or uniform")),
    }
}

/// Whether `--sampler` asks for stratified sample values.
fn parse_sampler(name: &str) -> std::result::Result<bool, String> {
    match name {
        "stratified" => Ok(true),
        "independent" => Ok(false),
        other => Err(format!("unknown sampler {other:?}: expected stratified or independent")),
    }
}

fn parse_integrator(name: &str) -> std::result::Result<Integrator, String> {
    Integrator::parse(name).ok_or_else(|| format!("unknown estimator {name:?}: expected plain, solid-angle, guided or caustic"))
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
                Some(text) => parse_camera(text, &scene)?,
                None => default_camera,
            };
            (camera, scene.values_from_assignments(&args.set)?, purpose_seed(args.seed, "trace"))
        }
    };
    let instance = scene.instantiate(&values)?;
    let integrator = args.integrator.unwrap_or(match args.device {
        TraceDevice::Cpu => Integrator::Caustic,
        TraceDevice::Wgpu => Integrator::Plain,
    });
    // Adaptive by default where it can run: the CPU, an estimator without learning passes.
    let adaptive = args.sampling.unwrap_or(args.device == TraceDevice::Cpu && integrator != Integrator::Guided);
    let stratified = args.sampler.unwrap_or(args.device == TraceDevice::Cpu);
    let settings = TraceSettings {
        max_depth: args.max_depth,
        threads: args.threads,
        integrator,
        adaptive,
        stratified,
        glass_spp: args.glass_spp,
        photon_merging: args.photon_merging,
        ..TraceSettings::new(args.res, args.res, args.spp, image_seed)
    };

    // In pixel samples, learning passes included.
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
    let sampling = match (adaptive, stratified) {
        (true, true) => "adaptive, stratified",
        (true, false) => "adaptive",
        (false, true) => "stratified",
        (false, false) => "uniform, independent",
    };
    let sampling = if args.photon_merging { format!("{sampling}, photon merging") } else { sampling.to_string() };
    bar.set_message(format!("tracing {} {}x{} @ {} spp ({}, {sampling}, {on})", scene.name, args.res, args.res, args.spp, integrator.name()));
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
    if output.light_paths > 0 {
        println!(
            "light tracing: {} light paths ({:.3} per camera sample, balanced against the camera's noise; a pilot of {} set aside)",
            output.light_paths,
            output.light_paths as f64 / (output.samples - output.pilot_samples).max(1) as f64,
            output.light_pilot_paths
        );
    }
    if output.photon_paths > 0 {
        let global = match output.global_photon_paths {
            0 => "no global ones (the background lights the scene too)".to_string(),
            paths => format!("{paths} global"),
        };
        println!(
            "photon merging: {} photons of {} caustic light paths and {global}, radius {:.3e} (biased: a blur of about a pixel)",
            output.photons, output.photon_paths, output.merge_radius
        );
    }
    Ok(())
}
