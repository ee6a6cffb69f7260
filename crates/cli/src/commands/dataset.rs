//! `glassbake dataset`: make a dataset (resumable, shardable), merge shards, upgrade an older
//! format's dataset in place, describe one.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Subcommand};
use glassbake_bake::{make_dataset, DatasetRequest, Progress};
use glassbake_core::Error;
use glassbake_dataset::{merge, upgrade, DatasetSpec, DatasetStore, ShardSpec, TraceDevice};
use glassbake_scene::load_scene;
use glassbake_trace::Estimator;

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

/// `--estimator` of `trace`, `dataset` and `bake`: one vocabulary (`glassbake_trace::estimator`).
pub(super) fn parse_estimator(name: &str) -> std::result::Result<Estimator, String> {
    Estimator::parse(name)
}

/// clap's parser for `--device` of `dataset` and `trace`.
pub fn parse_trace_device(name: &str) -> std::result::Result<TraceDevice, String> {
    TraceDevice::parse(name).map_err(|_| format!("unknown device {name:?}: expected cpu or wgpu"))
}

pub fn run(args: DatasetArgs) -> Result<()> {
    match (args.command, args.make) {
        (Some(DatasetCommand::Info { dir }), _) => {
            let info = DatasetStore::open(&dir)?.info();
            println!("dataset {}", dir.display());
            print!("{info}");
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
            let (bar, progress) = super::counting_bar("rasterizing buffers of frames");
            let summary = upgrade(&dir, &scene, &Default::default(), &progress);
            bar.finish_and_clear();
            println!("dataset {}: {}", dir.display(), summary?);
        }
        (Some(DatasetCommand::Merge { out, shards }), _) => {
            let shard_paths: Vec<&std::path::Path> = shards.iter().map(|p| p.as_path()).collect();
            let copied = merge(&out, &shard_paths)?;
            println!("merged {} shard(s) into {} ({copied} frames copied)", shards.len(), out.display());
        }
        (None, Some(make)) => {
            let request = make.request()?;
            Progress::printing_while(|progress| make_dataset(&request, progress))?;
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

impl MakeArgs {
    fn request(&self) -> Result<DatasetRequest> {
        let spec = DatasetSpec::new(self.scene.clone(), self.res, self.spp, [self.train, self.val, self.test]);
        let test_spp = self.test_spp.unwrap_or(DatasetSpec::default_test_spp(self.spp));
        let spec = DatasetSpec {
            glass_spp: self.glass_spp,
            test_spp: Some(test_spp),
            test_glass_spp: Some(self.test_glass_spp.unwrap_or_else(|| DatasetSpec::default_test_glass_spp(test_spp))),
            seed: self.seed,
            cache_buffers: self.cache_buffers,
            device: self.device,
            estimator: self.device.default_estimator(),
            ..spec
        };
        Ok(DatasetRequest {
            estimator: self.estimator,
            shard: self.shard.as_deref().map(ShardSpec::parse).transpose()?.unwrap_or(ShardSpec::ALL),
            threads: self.threads,
            ..DatasetRequest::new(spec, self.out.clone())
        })
    }
}
