//! The real-time commands: `glassbake render` (one frame), `glassbake bench` (frame times and
//! memory over resolutions x object counts) and `glassbake view` (the interactive viewer).

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::{ArgGroup, Args};
use glassbake_core::Error;
use glassbake_eval::plot::{line_chart, Series};
use glassbake_net::DeviceChoice;
use glassbake_realtime::bench::{describe_run, marginal_ms_per_object, table};
#[cfg(feature = "viewer")]
use glassbake_realtime::viewer::{check_display, run_viewer, ViewerOptions};
use glassbake_realtime::{open_pipeline, run_bench, BenchOptions, OpenedPipeline, Output, PipelineRequest, ThroughRays};

/// The model (and optional companions) a real-time command runs.
#[derive(Args, Clone)]
pub struct PipelineArgs {
    /// A trained GlassNet model directory (from `glassbake train` or `glassbake bake`).
    pub model: PathBuf,
    /// A trained naive baseline to switch to (`view`, `render --output naive`).
    #[arg(long)]
    pub naive: Option<PathBuf>,
    /// A trained x2 super-sampler (`glassbake train-sr`): the network runs at half the
    /// resolution and the super-sampler brings it up.
    #[arg(long)]
    pub sr: Option<PathBuf>,
    /// The scene, when the model's training dataset is not at hand (must be the same scene).
    #[arg(long)]
    pub scene: Option<String>,
    /// cpu (burn's flex backend), wgpu (Vulkan) or cuda (a build with the `cuda` feature) for the networks. With wgpu the rasterizer
    /// and the networks share one device and buffers never leave the GPU.
    #[arg(long, default_value = "cpu")]
    pub device: DeviceChoice,
    /// With --device wgpu: keep separate devices and pass buffers through host memory (for
    /// comparison).
    #[arg(long)]
    pub host_copy: bool,
    /// Samples per pixel side for the lights' coverage of each pixel in a scene with emissive
    /// meshes (rectangle lights alone are covered exactly): 4, as the datasets hold it, or
    /// fewer for a faster frame; 1 samples each pixel's centre, lights drawn whole pixels at a
    /// time.
    #[arg(long, default_value_t = glassbake_raster::light_coverage::LIGHT_COVERAGE_FACTOR, value_parser = clap::value_parser!(u32).range(1..=4))]
    pub light_coverage_samples: u32,
    /// Where the through buffers' refracted rays are cast, for a model that reads them: auto
    /// (a wgpu compute pass on a GPU adapter, the CPU on a CPU adapter such as lavapipe,
    /// where it is the faster), cpu or gpu.
    #[arg(long, default_value = "auto")]
    pub through_rays: String,
}

impl PipelineArgs {
    fn open(&self) -> Result<OpenedPipeline> {
        let request = PipelineRequest {
            naive: self.naive.clone(),
            super_sampler: self.sr.clone(),
            scene: self.scene.clone(),
            host_copy: self.host_copy,
            light_coverage_samples: self.light_coverage_samples,
            through_rays: ThroughRays::parse(&self.through_rays)?,
            ..PipelineRequest::new(&self.model, self.device)
        };
        Ok(open_pipeline(&request)?)
    }
}

#[derive(Args)]
#[command(group(ArgGroup::new("view").required(true).args(["sample", "camera"])))]
pub struct RenderArgs {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Render sample i of the model's dataset (its camera and variable values).
    #[arg(long)]
    pub sample: Option<u64>,
    /// Camera as px,py,pz,tx,ty,tz[,fov_x_deg].
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Variable values for --camera, NAME=VALUE (others take their defaults).
    #[arg(long = "set", requires = "camera")]
    pub set: Vec<String>,
    #[arg(long, default_value_t = 256)]
    pub res: u32,
    /// glassnet, naive, or a buffer attribute LAYER.ATTRIBUTE (opaque.albedo, transparent.0.coverage).
    #[arg(long, default_value = "glassnet")]
    pub output: String,
    /// The PNG to write.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn render(args: RenderArgs) -> Result<()> {
    let output = Output::parse(&args.output)?;
    if args.out.extension().and_then(|e| e.to_str()) != Some("png") {
        return Err(Error::bad_input(args.out.display(), "--out", "write a .png file").into());
    }
    let mut opened = args.pipeline.open()?;
    let scene = &opened.pipeline.scene;
    let (camera, values) = match (args.sample, &args.camera) {
        (Some(i), _) => {
            let drawn = scene.sample(opened.dataset_seed, i);
            (drawn.camera, drawn.values)
        }
        (None, Some(text)) => (scene.camera.camera_from_text(text)?, scene.values_from_assignments(&args.set)?),
        (None, None) => unreachable!("clap requires --sample or --camera"),
    };
    let (image, times) = opened.pipeline.render(&camera, &values, args.res, args.res, &output)?;
    image.write_png_rgb(&args.out, [0, 1, 2])?;
    println!("{} ({}x{}, {}): {times} (first frame, includes warm-up)", args.out.display(), args.res, args.res, args.output);
    Ok(())
}

#[derive(Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Square resolutions, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "256,512")]
    pub res: Vec<u32>,
    /// Transparent-object counts, comma-separated (scenes synthesised from the model's).
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8")]
    pub objects: Vec<usize>,
    /// Timed frames per configuration (the median is reported).
    #[arg(long, default_value_t = 20)]
    pub frames: usize,
    /// Untimed frames before each configuration.
    #[arg(long, default_value_t = 3)]
    pub warmup: usize,
    /// Hold the scene's variables at the first frame's values and move only the camera, as a
    /// viewer orbiting a still scene does: the through rays' BVHs are then built once and not
    /// refit per frame.
    #[arg(long)]
    pub camera_only: bool,
    /// bench.json path (default: beside the model directory, where `glassbake bake` reports
    /// look for it); a plot goes next to it as bench.png.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn bench(args: BenchArgs) -> Result<()> {
    if args.frames == 0 || args.res.is_empty() || args.objects.is_empty() || args.objects.contains(&0) {
        return Err(
            Error::bad_input("glassbake bench", "--frames/--res/--objects", "need at least one frame, one resolution and object counts of at least 1").into()
        );
    }
    let out = args.out.clone().unwrap_or_else(|| args.pipeline.model.parent().unwrap_or(Path::new(".")).join("bench.json"));
    let mut opened = args.pipeline.open()?;
    let options = BenchOptions {
        resolutions: args.res.clone(),
        objects: args.objects.clone(),
        warmup: args.warmup,
        frames: args.frames,
        seed: opened.dataset_seed,
        camera_only: args.camera_only,
    };
    let (bar, progress) = super::counting_bar("frames");
    let device = describe_run(&opened.pipeline, &opened.device, args.camera_only);
    let report = run_bench(&mut opened.pipeline, &device, &options, &|done, total| progress(done as u64, total as u64));
    bar.finish_and_clear();
    let report = report?;
    let json = serde_json::to_string_pretty(&report).map_err(|e| Error::Internal(e.to_string()))?;
    glassbake_core::image::write_bytes_atomically(&out, json.as_bytes())?;
    println!("{}", report.heading());
    print!("{}", table(&report));
    if opened.pipeline.glassnet_frames_zero_copy() {
        // Nothing is read back between the stages, so their clocks stop when the work is
        // handed to the GPU; what still runs is waited for at the end, inside `network`.
        println!("  (one device: raster and through rays time their CPU work and submission; the GPU's own time shows in network and the frame time)");
    }
    let series: Vec<Series> = args
        .res
        .iter()
        .map(|&res| Series {
            name: format!("{res}x{res}"),
            points: report.rows.iter().filter(|r| r.resolution == res).map(|r| (r.objects as f64, r.ms_per_frame)).collect(),
            dashed: false,
        })
        .collect();
    let plot_path = out.with_extension("png");
    if let Some(plot) = line_chart("Frame time", "transparent objects", "ms / frame (median)", &series)? {
        glassbake_core::image::write_bytes_atomically(&plot_path, &plot.png)?;
        println!("  plot  {}", plot_path.display());
    }
    println!("  table {}", out.display());
    for &res in &args.res {
        if let Some(slope) = marginal_ms_per_object(&report, res) {
            println!("  {res}x{res}: {slope:+.2} ms per extra transparent object");
        }
    }
    Ok(())
}

#[derive(Args)]
pub struct ViewArgs {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Starting frame resolution.
    #[arg(long, default_value_t = 128)]
    pub res: u32,
    /// Save a screenshot of the window here after --screenshot-after frames, then quit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    #[arg(long, default_value_t = 5, requires = "screenshot")]
    pub screenshot_after: usize,
}

#[cfg(not(feature = "viewer"))]
pub fn view(_args: ViewArgs) -> Result<()> {
    Err(Error::bad_input("glassbake", "view", "this glassbake was built without the viewer (cargo feature `viewer`)").into())
}

#[cfg(feature = "viewer")]
pub fn view(args: ViewArgs) -> Result<()> {
    check_display()?;
    let opened = args.pipeline.open()?;
    let title = format!("glassbake view: {}", opened.pipeline.scene.name);
    let options = ViewerOptions { resolution: args.res, screenshot: args.screenshot.clone(), screenshot_after: args.screenshot_after, title };
    if let Some(path) = run_viewer(opened.pipeline, options)? {
        println!("screenshot {}", path.display());
    }
    Ok(())
}
