//! `glassbake dataset`: make a dataset (resumable, shardable), merge shards, upgrade an older
//! format's dataset in place, describe one.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Result;
use clap::{Args, Subcommand};
use glassbake_core::Error;
use glassbake_dataset::{generate, merge, upgrade, DatasetSpec, DatasetStore, GenerateOptions, GenerateProgress, ShardSpec, TraceDevice, FORMAT_VERSION};
use glassbake_scene::load_scene;
use glassbake_trace::Estimator;
use indicatif::{ProgressBar, ProgressStyle};

#[derive(Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct DatasetArgs {
    #[command(subcommand)]
    command: Option<DatasetCommand>,
    #[command(flatten)]
    make: Option<MakeArgs>,
}

#[derive(Subcommand)]
enum DatasetCommand {
    /// Merge complete shard directories into one dataset (identical to a one-machine run).
    Merge {
        /// The merged dataset directory.
        #[arg(long)]
        out: PathBuf,
        /// Shard directories made with --shard i/n.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
    },
    /// Counts per split, resolution, spp, disk use, scene hash. Reads every frame and compares
    /// it with the checksum recorded when it was written; exits 2 naming any damaged frame.
    Info { dir: PathBuf },
    /// Bring a dataset made by an older glassbake to today's format in place: the ground
    /// truth is kept, the cached buffers are rasterized again (minutes, not hours).
    Upgrade {
        dir: PathBuf,
        /// The scene it was made from (default: the one its manifest names).
        #[arg(long)]
        scene: Option<String>,
    },
}

#[derive(Args, Clone)]
pub struct MakeArgs {
    /// A built-in name or a path to a manifest, glTF or OBJ file.
    pub scene: String,
    /// Dataset directory; re-running the same command there completes it.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 1800)]
    pub train: u64,
    #[arg(long, default_value_t = 200)]
    pub val: u64,
    #[arg(long, default_value_t = 128)]
    pub test: u64,
    /// Square resolution of every frame.
    #[arg(long, default_value_t = 256)]
    pub res: u32,
    /// Path-tracing samples per pixel of the train and validation ground truth.
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// Samples per pixel of the train and validation ground truth on the pixels that show a
    /// transparent object (default: --spp): what the models learn behind glass, where the
    /// path tracer is noisiest, is then less noisy.
    #[arg(long)]
    pub glass_spp: Option<u32>,
    /// Samples per pixel of the test split's ground truth (default: 8 x --spp), so that
    /// models are judged against a converged reference. Each test frame is also traced at
    /// --spp, for the noise floor the evaluation reports.
    #[arg(long)]
    pub test_spp: Option<u32>,
    /// Samples per pixel of the test split's ground truth on the pixels that show a
    /// transparent object (default: 3 x the test spp), where the transparent-pixel metrics
    /// measure. Which pixels those are follows from the geometry, so every pixel stays
    /// unbiased.
    #[arg(long)]
    pub test_glass_spp: Option<u32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also store the rasterized buffers (f16 EXR); otherwise they are rasterized again when
    /// needed, deterministically.
    #[arg(long)]
    pub cache_buffers: bool,
    /// Make only the frames whose index mod n is i, e.g. `--shard 3/16`.
    #[arg(long)]
    pub shard: Option<String>,
    /// Path-tracer threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Where to path-trace the ground truth: `cpu` (bit-identical for any thread count on one machine; other CPUs may differ in the last bits) or `wgpu`
    /// (the GPU tracer on a Vulkan adapter, deterministic on one device; it runs the `plain`
    /// estimator only). A dataset keeps the device it was started with.
    #[arg(long, default_value = "cpu", value_parser = parse_trace_device)]
    pub device: TraceDevice,
    /// The ground truth's estimator, `TRANSPORT[+merging][+adaptive][+stratified]`
    /// (docs/trace.md): TRANSPORT is `caustic` (the path tracer plus a light tracer for the
    /// light that reaches surfaces through glass) or `plain` (the path tracer alone, the only
    /// one with --device wgpu); `+merging` (caustic only) takes what the camera sees through
    /// bending glass from photons: biased, a blur of about a pixel, much less noise on glass;
    /// `+adaptive` spreads the samples by the noise a pilot pass of 1/16 of them measured
    /// (from 256 spp); `+stratified` draws sample values from scrambled Sobol points. Default:
    /// `caustic+adaptive+stratified` on the CPU (unbiased), `plain` with --device wgpu.
    /// Continuing a dataset keeps the estimator it was started with.
    #[arg(long, value_parser = parse_estimator)]
    pub estimator: Option<Estimator>,
}

/// The test split's ground truth is traced at this many times the training spp by default:
/// its own noise is then well below the error being measured (at least 8x).
const DEFAULT_TEST_SPP_FACTOR: u32 = 8;

/// The test split's spp when `--test-spp` is not given.
pub fn default_test_spp(spp: u32) -> u32 {
    spp.saturating_mul(DEFAULT_TEST_SPP_FACTOR)
}

/// The test split's glass pixels get this many times its spp by default: the
/// transparent-pixel metrics are then measured against a reference whose own noise is a
/// third of the uniform one's (in variance), at about +50% of the test split's trace time on
/// cornellbox and +120% on bathroom, whose partition fills most of the view (docs/trace.md).
const DEFAULT_TEST_GLASS_SPP_FACTOR: u32 = 3;

/// The test split's spp on glass pixels when `--test-glass-spp` is not given.
pub fn default_test_glass_spp(test_spp: u32) -> u32 {
    test_spp.saturating_mul(DEFAULT_TEST_GLASS_SPP_FACTOR)
}

/// `--estimator` of `trace`, `dataset` and `bake`: one vocabulary (`glassbake_trace::estimator`).
pub(super) fn parse_estimator(name: &str) -> std::result::Result<Estimator, String> {
    Estimator::parse(name)
}

/// clap's parser for `--device` of `dataset` and `trace`.
pub fn parse_trace_device(name: &str) -> std::result::Result<TraceDevice, String> {
    TraceDevice::parse(name).map_err(|_| format!("unknown device {name:?}: expected cpu or wgpu"))
}

fn human_bytes(bytes: u64) -> String {
    let mut value = bytes as f64;
    for unit in ["B", "KiB", "MiB", "GiB"] {
        if value < 1024.0 {
            return format!("{value:.1} {unit}");
        }
        value /= 1024.0;
    }
    format!("{value:.1} TiB")
}

pub fn run(args: DatasetArgs) -> Result<()> {
    match (args.command, args.make) {
        (Some(DatasetCommand::Info { dir }), _) => {
            let info = DatasetStore::open(&dir)?.info();
            println!("dataset {}", dir.display());
            println!("  scene {} (hash {})", info.scene_name, info.scene_hash);
            println!(
                "  {}x{} px, {} spp{}{} (traced on {}, {} estimator, {}), seed {}, {} transparent objects",
                info.resolution,
                info.resolution,
                info.spp,
                if info.glass_spp != info.spp { format!(" ({} on glass pixels)", info.glass_spp) } else { String::new() },
                match (info.test_spp != info.spp, info.test_glass_spp != info.test_spp) {
                    (_, true) => format!(", test split {} spp ({} on glass pixels)", info.test_spp, info.test_glass_spp),
                    (true, false) => format!(", test split {} spp", info.test_spp),
                    (false, false) => String::new(),
                },
                info.device.name(),
                info.estimator,
                match (info.tracer_revision, &info.ray_caster) {
                    (None, _) => "tracer revision not recorded".to_string(),
                    (Some(r), None) => format!("tracer revision {r}"),
                    (Some(r), Some(caster)) => format!("tracer revision {r}, rays cast by {caster}"),
                },
                info.seed,
                info.transparent_objects
            );
            println!("  buffers {}", if info.cache_buffers { "cached (f16 EXR)" } else { "rasterized on demand" });
            for (split, planned, done) in &info.splits {
                println!("  {:<6} {done}/{planned} frames complete", format!("{split:?}").to_lowercase());
            }
            for damaged in &info.damaged {
                println!("  damaged {damaged}");
            }
            if info.without_checksum > 0 {
                println!("  {} frame(s) written before checksums were recorded: checked by decoding alone", info.without_checksum);
            }
            println!("  disk {}", human_bytes(info.disk_bytes));
            if !info.damaged.is_empty() {
                return Err(Error::bad_input(
                    dir.display(),
                    "frames",
                    format!("{} damaged frame(s){}; `glassbake dataset` with the same arguments makes them again", info.damaged.len(), info.damaged_summary()),
                )
                .into());
            }
        }
        (Some(DatasetCommand::Upgrade { dir, scene }), _) => {
            let store = DatasetStore::open(&dir)?;
            let scene = load_scene(scene.as_deref().unwrap_or(&store.manifest.spec.scene))?;
            drop(store);
            let bar = ProgressBar::new(0);
            bar.set_style(
                ProgressStyle::with_template("{spinner} rasterizing buffers [{elapsed_precise}] {wide_bar} {pos}/{len}")
                    .expect("static template")
                    .progress_chars("=> "),
            );
            let progress = |done: u64, total: u64| {
                bar.set_length(total);
                bar.set_position(done);
            };
            let summary = upgrade(&dir, &scene, &Default::default(), &progress);
            bar.finish_and_clear();
            let summary = summary?;
            if summary.from_version == FORMAT_VERSION {
                println!("dataset {} is already format {FORMAT_VERSION}: nothing to do", dir.display());
            } else {
                println!(
                    "dataset {}: format {} -> {FORMAT_VERSION}, buffers of {} frame(s) rasterized again in {:.1} s, ground truth kept",
                    dir.display(),
                    summary.from_version,
                    summary.rasterized,
                    summary.elapsed.as_secs_f64()
                );
            }
        }
        (Some(DatasetCommand::Merge { out, shards }), _) => {
            let shard_paths: Vec<&std::path::Path> = shards.iter().map(|p| p.as_path()).collect();
            let copied = merge(&out, &shard_paths)?;
            println!("merged {} shard(s) into {} ({copied} frames copied)", shards.len(), out.display());
        }
        (None, Some(make)) => {
            let bar = ProgressBar::new(0);
            let result = make_dataset(&make, &bar);
            bar.finish_and_clear();
            result?;
        }
        (None, None) => {
            return Err(glassbake_core::Error::bad_input(
                "glassbake dataset",
                "arguments",
                "give a scene and --out, or a subcommand (see glassbake dataset --help)",
            )
            .into())
        }
    }
    Ok(())
}

/// Makes (or completes) a dataset as `glassbake dataset` does, showing progress on `bar`.
/// Returns whether any frame was made.
pub fn make_dataset(args: &MakeArgs, bar: &ProgressBar) -> Result<bool> {
    let scene = load_scene(&args.scene)?;
    let shard = match &args.shard {
        Some(text) => ShardSpec::parse(text)?,
        None => ShardSpec::ALL,
    };
    let test_spp = args.test_spp.unwrap_or_else(|| default_test_spp(args.spp));
    let spec = DatasetSpec {
        scene: args.scene.clone(),
        resolution: args.res,
        spp: args.spp,
        glass_spp: args.glass_spp,
        test_spp: Some(test_spp),
        test_glass_spp: Some(args.test_glass_spp.unwrap_or_else(|| default_test_glass_spp(test_spp))),
        seed: args.seed,
        train: args.train,
        val: args.val,
        test: args.test,
        cache_buffers: args.cache_buffers,
        device: args.device,
        // A dataset being continued keeps its estimator; a new one gets the device's default.
        estimator: args.estimator.unwrap_or_else(|| match DatasetStore::open(&args.out) {
            Ok(existing) => existing.manifest.spec.estimator,
            Err(_) => args.device.default_estimator(),
        }),
    };
    let options = GenerateOptions { shard, threads: args.threads, ..Default::default() };
    bar.set_length(0);
    bar.set_position(0);
    // The bar counts samples per pixel traced (test frames cost more), the message frames.
    bar.set_style(
        ProgressStyle::with_template("{spinner} frames {msg} [{elapsed_precise}] {wide_bar} ETA {eta}").expect("static template").progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(250));
    let progress = |p: GenerateProgress| {
        bar.set_length(p.work_total);
        bar.set_message(format!("{}/{}", p.frames_done, p.frames_total));
        if bar.position() == 0 && p.work_done > 0 {
            // Frames already complete do not count towards the ETA.
            bar.reset_eta();
        }
        bar.set_position(p.work_done);
    };
    let summary = generate(&scene, &spec, &args.out, &options, &progress)?;
    bar.suspend(|| {
        let secs = summary.elapsed.as_secs_f64();
        println!(
            "dataset {}: {} frame(s) made, {} already complete{}, in {:.1} s{}",
            args.out.display(),
            summary.generated,
            summary.skipped,
            if summary.redone > 0 { format!(" ({} corrupt, redone)", summary.redone) } else { String::new() },
            secs,
            if summary.generated > 0 { format!(" ({:.0} frames/hour)", summary.generated as f64 * 3600.0 / secs) } else { String::new() },
        );
        if shard != ShardSpec::ALL {
            println!("  shard {}/{}: {} frame(s) of this shard", shard.index, shard.count, summary.frames_in_shard);
        }
        if summary.discarded_samples > 0 {
            println!("  {} NaN/inf path sample(s) discarded", summary.discarded_samples);
        }
        println!("  disk {} ({} per frame)", human_bytes(summary.disk_bytes), human_bytes(summary.disk_bytes / summary.frames_in_shard.max(1)));
    });
    Ok(summary.generated > 0)
}
