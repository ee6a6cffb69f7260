//! `glassbake train` and `glassbake train-sr`: connect the dataset loader to the network
//! crate's training loop, with a progress bar and a summary.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Result;
use clap::Args;
use glassbake_core::Error;
use glassbake_dataset::store::manifest_content_sha256;
use glassbake_dataset::{DatasetInfo, DatasetStore, Example, Loader, LoaderOptions, Split};
use glassbake_net::model_dir::{DataSource, ModelConfig, ModelFiles, Network, FORMAT_VERSION};
use glassbake_net::{
    select_device, train, DeviceChoice, FrameRef, GlassNet, HostBatch, ModelKind, NetConfig, RunOptions, SuperSampler, SuperSamplerConfig, TrainConfig,
    TrainEvent, TrainedModel, TrainingData,
};
use glassbake_scene::load_scene;
use indicatif::{ProgressBar, ProgressStyle};

/// Options shared by `train` and `train-sr`.
#[derive(Args, Clone)]
pub struct CommonTrainArgs {
    /// Dataset directory (made by `glassbake dataset`).
    pub dataset: PathBuf,
    /// Model directory; re-running the same command there resumes from its checkpoint.
    #[arg(long)]
    pub out: PathBuf,
    /// tiny (tests), quick (a CPU bake at 64-128 px) or paper (GPU, 256 px).
    #[arg(long, default_value = "quick")]
    pub preset: String,
    /// cpu (burn's flex backend), wgpu (Vulkan) or, in a build with the `cuda` feature, cuda.
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Override the preset's number of optimizer steps.
    #[arg(long)]
    pub steps: Option<u64>,
    /// Override the preset's batch size.
    #[arg(long)]
    pub batch: Option<usize>,
    /// Override the preset's learning rate.
    #[arg(long)]
    pub lr: Option<f64>,
    /// Train on random square crops of this side (default: the preset's, 32 px crops for quick, whole frames for tiny and paper).
    #[arg(long)]
    pub crop: Option<u32>,
    #[arg(long)]
    pub seed: Option<u64>,
    /// Frame-reading/rasterizing worker threads.
    #[arg(long, default_value_t = 2)]
    pub workers: usize,
}

#[derive(Args)]
pub struct TrainArgs {
    #[command(flatten)]
    pub common: CommonTrainArgs,
    /// glassnet, naive (single G-buffer, glass overwrites), concat (buffers concatenated) or
    /// pixelgen (Active Exploration's per-pixel MLP on the naive G-buffer).
    #[arg(long, default_value = "glassnet")]
    pub model: String,
    /// Positional-encoding frequencies (0 = the paper's "without positional encoding" ablation).
    #[arg(long)]
    pub encoding_frequencies: Option<usize>,
    /// Weight of the (1 - SSIM) term (0 = the paper's "L1 only" ablation).
    #[arg(long)]
    pub ssim_weight: Option<f64>,
    /// An ablation: the paper's (Table 2) no-encoding (no positional encoding) or l1-only;
    /// front-through (the naive baseline also reading the through buffer of the transparent
    /// object in front: GlassNet's input without its architecture); or no-through (GlassNet
    /// without the through buffers, as the paper's: what seeing through the glass adds).
    #[arg(long)]
    pub ablation: Option<String>,
    /// What the renderer R predicts: `rgb` (the image directly, as the paper; the default) or
    /// `demodulated` (light that multiplies the G-buffer's albedo, plus a free RGB term).
    #[arg(long)]
    pub renderer_output: Option<String>,
    /// How world positions enter F and h: `fourier` (the paper's sinusoids, as every other
    /// channel) or `hash-grid` (a trainable multiresolution grid over the scene's bounds).
    #[arg(long)]
    pub position_encoding: Option<String>,
}

/// The paper's ablations (Table 2) as changes to a preset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ablation {
    /// Buffers enter the networks raw, without positional encoding.
    NoEncoding,
    /// L1 loss only, no SSIM term.
    L1Only,
    /// The naive baseline given what is seen through the front-most transparent object (its
    /// through buffer), which tells GlassNet's input from its architecture.
    FrontThrough,
    /// GlassNet without the through buffers (the paper's inputs), which tells what the
    /// refracted hits add.
    NoThrough,
}

impl Ablation {
    pub const ALL: [Ablation; 4] = [Ablation::NoEncoding, Ablation::L1Only, Ablation::FrontThrough, Ablation::NoThrough];
    /// The paper's ablations of GlassNet (Table 2), which `bake --ablations` trains.
    pub const PAPER: [Ablation; 2] = [Ablation::NoEncoding, Ablation::L1Only];

    pub fn name(self) -> &'static str {
        match self {
            Ablation::NoEncoding => "no-encoding",
            Ablation::L1Only => "l1-only",
            Ablation::FrontThrough => "front-through",
            Ablation::NoThrough => "no-through",
        }
    }

    pub fn parse(text: &str) -> glassbake_core::Result<Ablation> {
        Ablation::ALL
            .into_iter()
            .find(|a| a.name() == text)
            .ok_or_else(|| Error::bad_input("--ablation", "ablation", format!("{text:?} is not no-encoding, l1-only, front-through or no-through")))
    }
}

#[derive(Args)]
pub struct TrainSrArgs {
    #[command(flatten)]
    pub common: CommonTrainArgs,
    /// The trained GlassNet whose images are super-sampled (trained at half this dataset's
    /// resolution or on the same scene).
    #[arg(long)]
    pub glassnet: PathBuf,
}

fn train_config(args: &CommonTrainArgs) -> Result<TrainConfig> {
    let mut config = TrainConfig::preset(&args.preset)?;
    if let Some(v) = args.steps {
        config.steps = v;
    }
    if let Some(v) = args.batch {
        config.batch_size = v;
    }
    if let Some(v) = args.lr {
        config.learning_rate = v;
    }
    if args.crop.is_some() {
        config.crop = args.crop;
    }
    if let Some(v) = args.seed {
        config.seed = v;
    }
    config.warmup_steps = config.warmup_steps.min(config.steps / 10);
    config.check("command line")?;
    Ok(config)
}

/// The default hash grid over `scene`'s bounds, widened by a tenth on each side for variables
/// that move objects: 8 levels of 2 features, 4 to 64 cells across, 2^15 entries a level
/// (levels up to 31 cells are dense).
fn position_grid(scene: &str) -> Result<glassbake_net::hash_grid::HashGridConfig> {
    let scene = load_scene(scene)?;
    let (lo, hi) = scene.bounds().ok_or_else(|| Error::bad_input(scene.name.clone(), "objects", "an empty scene has no bounds for a position grid"))?;
    let margin = (hi - lo).max(glam::Vec3::splat(1e-3)) * 0.1;
    Ok(glassbake_net::hash_grid::HashGridConfig {
        levels: 8,
        features: 2,
        log2_table_size: 15,
        base_resolution: 4,
        finest_resolution: 64,
        bounds_min: (lo - margin).to_array(),
        bounds_max: (hi + margin).to_array(),
    })
}

/// Opens a dataset whose training and validation frames are all complete and intact (every
/// frame read and its checksum compared).
fn open_dataset(dir: &Path) -> Result<(DatasetStore, DatasetInfo, Option<glassbake_scene::Scene>)> {
    let store = DatasetStore::open(dir)?;
    let info = store.info();
    for (split, planned, done) in &info.splits {
        if matches!(split, Split::Train | Split::Val) && done < planned {
            return Err(Error::bad_input(
                dir.display(),
                "frames",
                format!(
                    "{split:?} split is incomplete ({done}/{planned}){}; finish it by re-running `glassbake dataset` (it makes damaged frames again)",
                    info.damaged_summary()
                ),
            )
            .into());
        }
    }
    let scene = if store.manifest.reads_cached_buffers() { None } else { Some(load_scene(&store.manifest.spec.scene)?) };
    Ok((store, info, scene))
}

fn data_source(dir: &Path, store: &DatasetStore) -> Result<DataSource> {
    Ok(DataSource {
        dataset: dir.display().to_string(),
        scene: store.manifest.scene.name.clone(),
        scene_hash: store.manifest.scene.hash.clone(),
        resolution: store.manifest.spec.resolution,
        scene_argument: Some(store.manifest.spec.scene.clone()),
        sample_seed: Some(store.manifest.spec.seed),
        dataset_sha256: Some(manifest_content_sha256(&store.manifest)?),
    })
}

/// Turns `bar` into a training-step bar of `steps` steps.
fn step_bar(bar: &ProgressBar, steps: u64) {
    bar.set_length(steps);
    bar.set_position(0);
    bar.set_style(
        ProgressStyle::with_template("{spinner} step {pos}/{len} [{elapsed_precise}] {wide_bar} ETA {eta} {msg}")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(250));
}

fn on_event(bar: &ProgressBar) -> impl FnMut(&TrainEvent) + '_ {
    let mut last_validation = None;
    let mut first = true;
    move |e: &TrainEvent| {
        if first {
            // Steps done before a resume do not count towards the ETA.
            bar.set_position(e.step.saturating_sub(1));
            bar.reset_eta();
            first = false;
        }
        if e.validation_loss.is_some() {
            last_validation = e.validation_loss;
        }
        bar.set_position(e.step);
        bar.set_message(format!("loss {:.4} lr {:.1e}{}", e.loss, e.learning_rate, last_validation.map(|v| format!(" val {v:.4}")).unwrap_or_default()));
    }
}

/// Frames of one dataset split as network batches.
struct DatasetData {
    train: Loader,
    val: Loader,
    validation_frames: Option<usize>,
    batch_size: usize,
    /// Feed the naive G-buffer instead of the opaque one.
    naive: bool,
    /// Feed the transparent objects' buffers (`NetConfig::reads_object_buffers`).
    objects: bool,
    /// For the super-sampler: GlassNet renders the low-resolution image of each frame.
    low_res: Option<TrainedModel>,
}

fn host_batch(examples: &[Example], naive: bool, objects: bool, low_res: Option<&TrainedModel>) -> glassbake_core::Result<HostBatch> {
    let refs: Vec<FrameRef> = examples
        .iter()
        .map(|e| {
            let (gbuffer, light_coverage) = e.gbuffer(naive);
            FrameRef {
                gbuffer,
                light_coverage: Some(light_coverage),
                transparent: if objects { &e.transparent } else { &[] },
                values: &e.values,
                ground_truth: Some(&e.ground_truth),
            }
        })
        .collect();
    let mut batch = HostBatch::from_frames(&refs)?;
    if let Some(model) = low_res {
        let mut low = Vec::new();
        for e in examples {
            let (gbuffer, light_coverage) = e.gbuffer(model.kind().reads_naive_gbuffer());
            let frame = FrameRef { gbuffer, light_coverage: Some(light_coverage), transparent: &e.transparent, values: &e.values, ground_truth: None };
            let image = model.render_half(frame)?;
            for name in glassbake_core::layout::GROUND_TRUTH_CHANNELS {
                low.extend_from_slice(image.plane_by_name(name).expect("render writes R, G, B"));
            }
        }
        batch.low_res_image = Some(low);
    }
    Ok(batch)
}

impl TrainingData for DatasetData {
    fn batches_per_epoch(&self) -> usize {
        self.train.len().div_ceil(self.batch_size)
    }

    fn epoch(&mut self, epoch: u64, skip: usize) -> Box<dyn Iterator<Item = glassbake_core::Result<HostBatch>> + '_> {
        let (naive, objects, low_res) = (self.naive, self.objects, self.low_res.as_ref());
        Box::new(self.train.epoch_iter(epoch).skip(skip).map(move |examples| host_batch(&examples?, naive, objects, low_res)))
    }

    fn validation(&mut self) -> glassbake_core::Result<Vec<HostBatch>> {
        let limit = self.validation_frames.unwrap_or(usize::MAX).min(self.val.len());
        let mut batches = Vec::new();
        let mut taken = 0;
        let (naive, objects, low_res) = (self.naive, self.objects, self.low_res.as_ref());
        for examples in self.val.epoch_iter(0) {
            let mut examples = examples?;
            examples.truncate(limit - taken);
            taken += examples.len();
            batches.push(host_batch(&examples, naive, objects, low_res)?);
            if taken >= limit {
                break;
            }
        }
        Ok(batches)
    }
}

fn loaders(dir: &Path, scene: Option<glassbake_scene::Scene>, config: &TrainConfig, workers: usize, naive: bool) -> Result<(Loader, Loader)> {
    let train = Loader::new(
        dir,
        scene.clone(),
        LoaderOptions {
            split: Split::Train,
            batch_size: config.batch_size,
            crop: config.crop,
            seed: config.seed,
            shuffle: true,
            workers,
            naive,
            ..Default::default()
        },
    )?;
    let val = Loader::new(
        dir,
        scene,
        LoaderOptions { split: Split::Val, batch_size: config.batch_size, crop: None, seed: config.seed, shuffle: false, workers, naive, ..Default::default() },
    )?;
    Ok((train, val))
}

pub fn run(args: TrainArgs) -> Result<()> {
    let bar = ProgressBar::new(0);
    let result = train_model(&args, &bar);
    bar.finish_and_clear();
    result.map(|_| ())
}

/// Trains one model as `glassbake train` does, showing progress on `bar`. Returns whether
/// any step was trained (false: the model was already trained).
pub fn train_model(args: &TrainArgs, bar: &ProgressBar) -> Result<bool> {
    let kind = ModelKind::parse(&args.model)
        .ok_or_else(|| Error::bad_input("--model", "model", format!("{:?} is not glassnet, naive, concat or pixelgen", args.model)))?;
    let device_choice = DeviceChoice::parse(&args.common.device)?;
    let mut train_config = train_config(&args.common)?;
    let ablation = args.ablation.as_deref().map(Ablation::parse).transpose()?;
    if ablation == Some(Ablation::L1Only) {
        train_config.ssim_weight = 0.0;
    }
    if let Some(w) = args.ssim_weight {
        train_config.ssim_weight = w;
        train_config.check("--ssim-weight")?;
    }
    let (store, info, scene) = open_dataset(&args.common.dataset)?;
    let variables = store.manifest.samples.first().map_or(0, |s| s.values.len());
    let mut net_config = NetConfig::preset(&args.common.preset, kind, variables, info.transparent_objects)?;
    if ablation == Some(Ablation::NoEncoding) {
        net_config.encoding_frequencies = 0;
    }
    if ablation == Some(Ablation::FrontThrough) {
        if kind != ModelKind::Naive {
            return Err(
                Error::bad_input("--ablation", "ablation", format!("front-through is an ablation of the naive baseline, not of {}", kind.name())).into()
            );
        }
        net_config.through = true;
    }
    if ablation == Some(Ablation::NoThrough) {
        if kind != ModelKind::Glassnet {
            return Err(Error::bad_input("--ablation", "ablation", format!("no-through is an ablation of GlassNet, not of {}", kind.name())).into());
        }
        net_config.through = false;
    }
    if let Some(f) = args.encoding_frequencies {
        net_config.encoding_frequencies = f;
        net_config.check("--encoding-frequencies")?;
    }
    match args.position_encoding.as_deref() {
        None => {}
        Some("fourier") => net_config.position_grid = None,
        Some("hash-grid") => net_config.position_grid = Some(position_grid(&store.manifest.spec.scene)?),
        Some(other) => return Err(Error::bad_input("--position-encoding", "position_encoding", format!("{other:?} is not fourier or hash-grid")).into()),
    }
    net_config.check("command line")?;
    match args.renderer_output.as_deref() {
        None => {}
        Some("demodulated") => net_config.demodulated = true,
        Some("rgb") => net_config.demodulated = false,
        Some(other) => return Err(Error::bad_input("--renderer-output", "renderer_output", format!("{other:?} is not demodulated or rgb")).into()),
    }
    let side = train_config.crop.unwrap_or(info.resolution) as usize;
    if !side.is_multiple_of(net_config.size_multiple()) {
        return Err(
            Error::bad_input("--crop", "resolution", format!("training frames of {side} px are not a multiple of {}", net_config.size_multiple())).into()
        );
    }
    // The loaders check their options before the model directory is written.
    let naive = kind.reads_naive_gbuffer();
    let (train_loader, val) = loaders(&args.common.dataset, scene, &train_config, args.common.workers, naive)?;
    let files = ModelFiles::prepare(
        &args.common.out,
        ModelConfig {
            format_version: FORMAT_VERSION,
            network: Network::Glassnet(net_config.clone()),
            train: train_config.clone(),
            data: data_source(&args.common.dataset, &store)?,
        },
    )?;
    let mut data = DatasetData {
        train: train_loader,
        val,
        validation_frames: train_config.validation_frames,
        batch_size: train_config.batch_size,
        naive,
        objects: net_config.reads_object_buffers(),
        low_res: None,
    };
    let device = select_device(device_choice, train_config.seed, true);
    let model = GlassNet::new(&net_config, train_config.seed, &device)?;
    let message = format!(
        "training {}{} ({} preset, {} parameters) on {} ({} train frames, {} px{}), {} steps on {}",
        kind.name(),
        ablation.map(|a| format!(" ({} ablation)", a.name())).unwrap_or_default(),
        args.common.preset,
        glassbake_net::burn::module::Module::num_params(&model),
        args.common.dataset.display(),
        data.train.len(),
        info.resolution,
        train_config.crop.map(|c| format!(", {c} px crops")).unwrap_or_default(),
        train_config.steps,
        device_choice.name()
    );
    bar.suspend(|| println!("{message}"));
    step_bar(bar, train_config.steps);
    let summary = train(model, &files, &train_config, &device, &mut data, &RunOptions::default(), &mut on_event(bar))?;
    let already_done = summary.already_done;
    bar.suspend(|| report(summary, &files));
    if already_done && files.dir.join("preview").exists() {
        return Ok(false);
    }
    let previews = write_previews(&files, &mut data.val, naive, net_config.reads_object_buffers(), device_choice)?;
    bar.suspend(|| println!("  preview {} (model | ground truth)", previews.display()));
    Ok(!already_done)
}

/// `DIR/preview/val_NNN.png`: the model's image beside the path-traced ground truth for the
/// first validation frames, so a run can be looked at, not only read off a loss.
fn write_previews(files: &ModelFiles, val: &mut Loader, naive: bool, objects: bool, device_choice: DeviceChoice) -> Result<PathBuf> {
    const FRAMES: usize = 4;
    let model = TrainedModel::load(&files.dir, &select_device(device_choice, 0, false))?;
    let dir = files.dir.join("preview");
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let mut written = 0;
    for examples in val.epoch_iter(0) {
        for e in examples? {
            if written == FRAMES {
                break;
            }
            let (gbuffer, light_coverage) = e.gbuffer(naive);
            let transparent: &[glassbake_core::PlanarImage] = if objects { &e.transparent } else { &[] };
            let image = model.render(FrameRef { gbuffer, light_coverage: Some(light_coverage), transparent, values: &e.values, ground_truth: None })?;
            let pair = side_by_side(&image, &e.ground_truth)?;
            pair.write_png_rgb(&dir.join(format!("val_{:03}.png", e.index)), [0, 1, 2])?;
            written += 1;
        }
        if written == FRAMES {
            break;
        }
    }
    Ok(dir)
}

fn side_by_side(left: &glassbake_core::PlanarImage, right: &glassbake_core::PlanarImage) -> glassbake_core::Result<glassbake_core::PlanarImage> {
    let (w, h) = (left.width() as usize, left.height() as usize);
    let mut data = Vec::with_capacity(6 * w * h);
    for name in glassbake_core::layout::GROUND_TRUTH_CHANNELS {
        let (l, r) = (left.plane_by_name(name).expect("RGB"), right.plane_by_name(name).expect("RGB"));
        for y in 0..h {
            data.extend_from_slice(&l[y * w..(y + 1) * w]);
            data.extend_from_slice(&r[y * w..(y + 1) * w]);
        }
    }
    glassbake_core::PlanarImage::from_planes(
        2 * w as u32,
        h as u32,
        glassbake_core::layout::GROUND_TRUTH_CHANNELS.iter().map(|s| s.to_string()).collect(),
        data,
    )
}

pub fn run_super_sampler(args: TrainSrArgs) -> Result<()> {
    let device_choice = DeviceChoice::parse(&args.common.device)?;
    let train_config = train_config(&args.common)?;
    let (store, _, scene) = open_dataset(&args.common.dataset)?;
    let inference_device = select_device(device_choice, train_config.seed, false);
    let glassnet = TrainedModel::load(&args.glassnet, &inference_device)?;
    let side = train_config.crop.unwrap_or(store.manifest.spec.resolution) as usize;
    if !side.is_multiple_of(2 * glassnet.config().size_multiple()) {
        return Err(Error::bad_input(
            "--crop",
            "resolution",
            format!("{side} px frames halve to a size GlassNet cannot take (need a multiple of {})", 2 * glassnet.config().size_multiple()),
        )
        .into());
    }
    let glassnet_scene = ModelFiles::open(&args.glassnet)?.config.data;
    if glassnet_scene.scene_hash != store.manifest.scene.hash {
        return Err(Error::bad_input(
            args.glassnet.display(),
            "scene",
            format!(
                "this GlassNet was trained on {} (another scene than the dataset's {}); train the super-sampler on its own scene's dataset",
                glassnet_scene.scene, store.manifest.scene.name
            ),
        )
        .into());
    }
    let sr_config = SuperSamplerConfig::preset(&args.common.preset)?;
    let naive = glassnet.kind().reads_naive_gbuffer();
    let (train_loader, val) = loaders(&args.common.dataset, scene, &train_config, args.common.workers, naive)?;
    let files = ModelFiles::prepare(
        &args.common.out,
        ModelConfig {
            format_version: FORMAT_VERSION,
            network: Network::SuperSampler(sr_config.clone()),
            train: train_config.clone(),
            data: data_source(&args.common.dataset, &store)?,
        },
    )?;
    let mut data = DatasetData {
        train: train_loader,
        val,
        validation_frames: train_config.validation_frames,
        batch_size: train_config.batch_size,
        naive: false,
        objects: true,
        low_res: Some(glassnet),
    };
    let device = select_device(device_choice, train_config.seed, true);
    let model = SuperSampler::new(&sr_config, train_config.seed, &device);
    println!(
        "training the x2 super-sampler ({} preset) on {}, {} steps on {}",
        args.common.preset,
        args.common.dataset.display(),
        train_config.steps,
        device_choice.name()
    );
    let bar = ProgressBar::new(0);
    step_bar(&bar, train_config.steps);
    let summary = train(model, &files, &train_config, &device, &mut data, &RunOptions::default(), &mut on_event(&bar));
    bar.finish_and_clear();
    report(summary?, &files);
    Ok(())
}

fn report(summary: glassbake_net::TrainSummary, files: &ModelFiles) {
    if summary.already_done {
        println!("{} is already trained ({} steps); nothing to do", files.dir.display(), summary.steps);
    } else {
        println!(
            "trained {} steps{} in {:.1} s; validation loss {}",
            summary.steps,
            summary.resumed_from.map(|s| format!(" (resumed from step {s})")).unwrap_or_default(),
            summary.elapsed_seconds,
            summary.final_validation_loss.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into())
        );
    }
    println!("  weights {}", files.weights_path().display());
    println!("  log     {}", files.dir.join("train_log.csv").display());
}
