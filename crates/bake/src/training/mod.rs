//! Training a model on a dataset (`glassbake train`, a bake's model stages) and the x2
//! super-sampler on a trained GlassNet's images (`glassbake train-sr`): a preset's settings
//! with the caller's changes, the dataset's frames as batches, the network crate's training
//! loop, previews. A model directory resumes where a killed run stopped.

mod data;
mod preview;

use std::path::{Path, PathBuf};
use std::time::Duration;

use glassbake_core::{Error, Result};
use glassbake_dataset::DatasetStore;
use glassbake_net::hash_grid::HashGridConfig;
use glassbake_net::model_dir::{ModelConfig, ModelFiles, Network, FORMAT_VERSION};
use glassbake_net::{
    select_device, select_devices, train, with_new_model, DeviceChoice, ModelKind, ModelTask, NetConfig, RunOptions, SceneModel, SuperSampler, TrainConfig,
    TrainEvent, TrainSummary, Trainable, TrainedModel,
};
use glassbake_scene::load_scene;
use indicatif::{ProgressBar, ProgressStyle};

pub use data::{data_source, loaders, open_dataset, outdated_buffers_notice, DatasetData};

use crate::{Ablation, Preset, Progress};

/// Changes to a preset's training settings.
#[derive(Clone, Debug, Default)]
pub struct TrainOverrides {
    pub steps: Option<u64>,
    pub batch_size: Option<usize>,
    pub learning_rate: Option<f64>,
    /// Square random crops of this side (the preset's otherwise).
    pub crop: Option<u32>,
    pub seed: Option<u64>,
}

impl TrainOverrides {
    /// `preset`'s training settings with these changes, checked.
    pub fn apply(&self, preset: &Preset) -> Result<TrainConfig> {
        let mut config = preset.training.clone();
        config.steps = self.steps.unwrap_or(config.steps);
        config.batch_size = self.batch_size.unwrap_or(config.batch_size);
        config.learning_rate = self.learning_rate.unwrap_or(config.learning_rate);
        config.crop = self.crop.or(config.crop);
        config.seed = self.seed.unwrap_or(config.seed);
        config.warmup_steps = config.warmup_steps.min(config.steps / 10);
        config.check("command line")?;
        Ok(config)
    }
}

/// How world positions enter F and h.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PositionEncoding {
    /// The paper's sinusoids, as every other channel.
    Fourier,
    /// A trainable multiresolution grid over the scene's bounds.
    HashGrid,
}

impl PositionEncoding {
    pub fn parse(text: &str) -> Result<PositionEncoding> {
        match text {
            "fourier" => Ok(PositionEncoding::Fourier),
            "hash-grid" => Ok(PositionEncoding::HashGrid),
            other => Err(Error::bad_input("--position-encoding", "position_encoding", format!("{other:?} is not fourier or hash-grid"))),
        }
    }
}

/// What the renderer R predicts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RendererOutput {
    /// The image directly, as the paper.
    Rgb,
    /// Light that multiplies the G-buffer's albedo, plus a free RGB term.
    Demodulated,
    /// GlassNet's transmitted terms as light that multiplies the through buffers' albedo,
    /// plus a free RGB term; the direct term RGB.
    ThroughDemodulated,
    /// The direct term demodulated by the G-buffer's albedo, the transmitted terms by the
    /// through buffers'.
    DemodulatedThrough,
}

impl RendererOutput {
    pub fn parse(text: &str) -> Result<RendererOutput> {
        match text {
            "rgb" => Ok(RendererOutput::Rgb),
            "demodulated" => Ok(RendererOutput::Demodulated),
            "through-demodulated" => Ok(RendererOutput::ThroughDemodulated),
            "demodulated-through" => Ok(RendererOutput::DemodulatedThrough),
            other => Err(Error::bad_input(
                "--renderer-output",
                "renderer_output",
                format!("{other:?} is not rgb, demodulated, through-demodulated or demodulated-through"),
            )),
        }
    }
}

/// A model to train on a dataset.
#[derive(Clone, Debug)]
pub struct TrainRequest {
    /// The dataset directory.
    pub dataset: PathBuf,
    /// The model directory; training again there resumes from its checkpoint.
    pub out: PathBuf,
    pub preset: Preset,
    pub model: ModelKind,
    pub device: DeviceChoice,
    /// GPUs of `device`'s kind that share every batch (data parallelism); 1 on the CPU.
    pub devices: usize,
    pub overrides: TrainOverrides,
    /// Frame-reading and rasterizing threads.
    pub workers: usize,
    pub ablation: Option<Ablation>,
    /// Positional-encoding frequencies instead of the preset's.
    pub encoding_frequencies: Option<usize>,
    /// The (1 - SSIM) term's weight instead of the preset's.
    pub ssim_weight: Option<f64>,
    pub renderer_output: Option<RendererOutput>,
    pub position_encoding: Option<PositionEncoding>,
    /// Stop once this step is trained and validated (the bake's half-way check against naive);
    /// a later request without it continues from there.
    pub pause_at: Option<u64>,
}

impl TrainRequest {
    /// `model` of `preset` trained on `dataset` into `out` on the CPU, as the preset says.
    pub fn new(dataset: impl Into<PathBuf>, out: impl Into<PathBuf>, preset: Preset, model: ModelKind) -> TrainRequest {
        TrainRequest {
            dataset: dataset.into(),
            out: out.into(),
            preset,
            model,
            device: DeviceChoice::Cpu,
            devices: 1,
            overrides: TrainOverrides::default(),
            workers: 2,
            ablation: None,
            encoding_frequencies: None,
            ssim_weight: None,
            renderer_output: None,
            position_encoding: None,
            pause_at: None,
        }
    }
}

/// The network `request` trains, for a dataset of `variables` variables and
/// `transparent_objects` objects made from `scene`.
fn network_config(request: &TrainRequest, variables: usize, transparent_objects: usize, scene: &str) -> Result<NetConfig> {
    let kind = request.model;
    let mut config = NetConfig::new(&request.preset.network, &request.preset.name, kind, variables, transparent_objects)?;
    match request.ablation {
        Some(Ablation::NoEncoding) => config.encoding_frequencies = 0,
        Some(Ablation::FrontThrough) if kind != ModelKind::Naive => {
            return Err(Error::bad_input("--ablation", "ablation", format!("front-through is an ablation of the naive baseline, not of {}", kind.name())))
        }
        Some(Ablation::FrontThrough) => config.through = true,
        Some(Ablation::NoThrough) if kind != ModelKind::Glassnet => {
            return Err(Error::bad_input("--ablation", "ablation", format!("no-through is an ablation of GlassNet, not of {}", kind.name())))
        }
        Some(Ablation::NoThrough) => config.through = false,
        Some(Ablation::L1Only) | None => {}
    }
    if let Some(f) = request.encoding_frequencies {
        config.encoding_frequencies = f;
        config.check("--encoding-frequencies")?;
    }
    match request.position_encoding {
        None => {}
        Some(PositionEncoding::Fourier) => config.position_grid = None,
        Some(PositionEncoding::HashGrid) => config.position_grid = Some(position_grid(scene)?),
    }
    if let Some(output) = request.renderer_output {
        (config.demodulated, config.through_demodulated) = match output {
            RendererOutput::Rgb => (false, false),
            RendererOutput::Demodulated => (true, false),
            RendererOutput::ThroughDemodulated => (false, true),
            RendererOutput::DemodulatedThrough => (true, true),
        };
        config.check("--renderer-output")?;
    }
    config.check("command line")?;
    Ok(config)
}

/// The default hash grid over `scene`'s bounds, widened by a tenth on each side for variables
/// that move objects: 8 levels of 2 features, 4 to 64 cells across, 2^15 entries a level
/// (levels up to 31 cells are dense).
fn position_grid(scene: &str) -> Result<HashGridConfig> {
    let scene = load_scene(scene)?;
    let (lo, hi) = scene.bounds().ok_or_else(|| Error::bad_input(scene.name.clone(), "objects", "an empty scene has no bounds for a position grid"))?;
    let margin = (hi - lo).max(glam::Vec3::splat(1e-3)) * 0.1;
    Ok(HashGridConfig {
        levels: 8,
        features: 2,
        log2_table_size: 15,
        base_resolution: 4,
        finest_resolution: 64,
        bounds_min: (lo - margin).to_array(),
        bounds_max: (hi + margin).to_array(),
    })
}

/// Trains the model of `request`, showing its steps on the progress bar. Returns whether
/// any step was trained (false: the model was already trained).
pub fn train_model(request: &TrainRequest, progress: &Progress) -> Result<bool> {
    let mut train_config = request.overrides.apply(&request.preset)?;
    if request.ablation == Some(Ablation::L1Only) {
        train_config.ssim_weight = 0.0;
    }
    if let Some(w) = request.ssim_weight {
        train_config.ssim_weight = w;
        train_config.check("--ssim-weight")?;
    }
    let (store, info, scene) = open_dataset(&request.dataset)?;
    if let Some(notice) = outdated_buffers_notice(&request.dataset, &store) {
        progress.say(&notice);
    }
    let variables = store.manifest.samples.first().map_or(0, |s| s.values.len());
    let net_config = network_config(request, variables, info.transparent_objects, &store.manifest.spec.scene)?;
    let side = train_config.crop.unwrap_or(info.resolution) as usize;
    if !side.is_multiple_of(net_config.size_multiple()) {
        return Err(Error::bad_input("--crop", "resolution", format!("training frames of {side} px are not a multiple of {}", net_config.size_multiple())));
    }
    check_devices(request.devices, &train_config)?;
    let devices = select_devices(request.device, request.devices, train_config.seed)?;
    let task = TrainTask { request, progress, train_config: &train_config, store: &store, scene, resolution: info.resolution, devices: &devices };
    with_new_model(&net_config, train_config.seed, &devices[0], task)?
}

/// The rest of [`train_model`] once its network is built, for each type of network.
struct TrainTask<'a> {
    request: &'a TrainRequest,
    progress: &'a Progress,
    train_config: &'a TrainConfig,
    store: &'a DatasetStore,
    scene: Option<glassbake_scene::Scene>,
    resolution: u32,
    /// The model's device first, then the replicas'.
    devices: &'a [glassbake_net::burn::prelude::Device],
}

impl ModelTask for TrainTask<'_> {
    type Output = Result<bool>;

    fn run<M: SceneModel + Trainable>(self, model: M) -> Result<bool> {
        let TrainTask { request, progress, train_config, store, scene, resolution, devices } = self;
        // The loaders check their options before the model directory is written.
        let (naive, objects) = (model.reads_naive_gbuffer(), model.reads_object_buffers());
        let (train_loader, val) = loaders(&request.dataset, scene, train_config, request.workers, naive)?;
        let files = model_files(&request.out, Network::Glassnet(model.config().clone()), train_config, &request.dataset, store)?;
        let mut data = DatasetData::new(train_loader, val, train_config, naive, objects, None);
        progress.say(&format!(
            "training {}{} ({} preset, {} parameters) on {} ({} train frames, {} px{}), {} steps on {}",
            model.kind().name(),
            request.ablation.map(|a| format!(" ({} ablation)", a.name())).unwrap_or_default(),
            request.preset.name,
            model.num_params(),
            request.dataset.display(),
            data.train.len(),
            resolution,
            train_config.crop.map(|c| format!(", {c} px crops")).unwrap_or_default(),
            train_config.steps,
            if devices.len() > 1 {
                format!("{} {} devices sharing each batch", devices.len(), request.device.name())
            } else {
                request.device.name().to_string()
            }
        ));
        step_bar(progress.bar(), train_config.steps);
        let options = RunOptions { replicas: devices[1..].to_vec(), pause_at: request.pause_at, ..RunOptions::default() };
        let summary = train(model, &files, train_config, &devices[0], &mut data, &options, &mut on_event(progress.bar()))?;
        let already_done = summary.already_done;
        if summary.steps < train_config.steps {
            progress.say(&format!("{} paused at step {} of {}", files.dir.display(), summary.steps, train_config.steps));
            return Ok(summary.resumed_from != Some(summary.steps));
        }
        report(&summary, &files, progress);
        if already_done && files.dir.join("preview").exists() {
            return Ok(false);
        }
        let previews = preview::write_previews(&files, &mut data.val, naive, objects, request.device)?;
        progress.say(&format!("  preview {} (model | ground truth)", previews.display()));
        Ok(!already_done)
    }
}

/// A x2 super-sampler to train from a trained GlassNet's images to a dataset's ground truth.
#[derive(Clone, Debug)]
pub struct SuperSamplerRequest {
    /// The dataset directory, at twice the resolution GlassNet renders (or the same scene).
    pub dataset: PathBuf,
    /// The trained GlassNet whose images are super-sampled.
    pub glassnet: PathBuf,
    pub out: PathBuf,
    pub preset: Preset,
    pub device: DeviceChoice,
    /// GPUs of `device`'s kind that share every batch.
    pub devices: usize,
    pub overrides: TrainOverrides,
    pub workers: usize,
}

/// Trains the super-sampler of `request`, showing its steps on the progress bar.
pub fn train_super_sampler(request: &SuperSamplerRequest, progress: &Progress) -> Result<()> {
    let train_config = request.overrides.apply(&request.preset)?;
    let (store, _, scene) = open_dataset(&request.dataset)?;
    if let Some(notice) = outdated_buffers_notice(&request.dataset, &store) {
        progress.say(&notice);
    }
    let inference_device = select_device(request.device, train_config.seed, false);
    let glassnet = TrainedModel::load(&request.glassnet, &inference_device)?;
    let side = train_config.crop.unwrap_or(store.manifest.spec.resolution) as usize;
    if !side.is_multiple_of(2 * glassnet.config().size_multiple()) {
        return Err(Error::bad_input(
            "--crop",
            "resolution",
            format!("{side} px frames halve to a size GlassNet cannot take (need a multiple of {})", 2 * glassnet.config().size_multiple()),
        ));
    }
    let glassnet_scene = ModelFiles::open(&request.glassnet)?.config.data;
    if glassnet_scene.scene_hash != store.manifest.scene.hash {
        return Err(Error::bad_input(
            request.glassnet.display(),
            "scene",
            format!(
                "this GlassNet was trained on {} (another scene than the dataset's {}); train the super-sampler on its own scene's dataset",
                glassnet_scene.scene, store.manifest.scene.name
            ),
        ));
    }
    let sr_config = request.preset.super_sampler.clone();
    let naive = glassnet.net.reads_naive_gbuffer();
    let (train_loader, val) = loaders(&request.dataset, scene, &train_config, request.workers, naive)?;
    let files = model_files(&request.out, Network::SuperSampler(sr_config.clone()), &train_config, &request.dataset, &store)?;
    let mut data = DatasetData::new(train_loader, val, &train_config, false, true, Some(glassnet));
    check_devices(request.devices, &train_config)?;
    let devices = select_devices(request.device, request.devices, train_config.seed)?;
    let model = SuperSampler::new(&sr_config, train_config.seed, &devices[0]);
    progress.say(&format!(
        "training the x2 super-sampler ({} preset) on {}, {} steps on {}",
        request.preset.name,
        request.dataset.display(),
        train_config.steps,
        request.device.name()
    ));
    step_bar(progress.bar(), train_config.steps);
    let options = RunOptions { replicas: devices[1..].to_vec(), ..RunOptions::default() };
    let summary = train(model, &files, &train_config, &devices[0], &mut data, &options, &mut on_event(progress.bar()))?;
    report(&summary, &files, progress);
    Ok(())
}

/// Refuses more devices than a batch has frames: each device takes at least one.
fn check_devices(devices: usize, train: &TrainConfig) -> Result<()> {
    if devices > train.batch_size {
        return Err(Error::bad_input(
            "--devices",
            "devices",
            format!("{devices} devices for batches of {} frames: each device takes at least one frame", train.batch_size),
        ));
    }
    Ok(())
}

/// The model directory `out` for `network` trained as `train` says on the dataset in
/// `dataset` (opened as `store`): made, or checked to be this model's when resuming.
fn model_files(out: &Path, network: Network, train: &TrainConfig, dataset: &Path, store: &DatasetStore) -> Result<ModelFiles> {
    ModelFiles::prepare(out, ModelConfig { format_version: FORMAT_VERSION, network, train: train.clone(), data: data_source(dataset, store)? })
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

fn report(summary: &TrainSummary, files: &ModelFiles, progress: &Progress) {
    if summary.already_done {
        progress.say(&format!("{} is already trained ({} steps); nothing to do", files.dir.display(), summary.steps));
    } else {
        progress.say(&format!(
            "trained {} steps{} in {:.1} s; validation loss {}",
            summary.steps,
            summary.resumed_from.map(|s| format!(" (resumed from step {s})")).unwrap_or_default(),
            summary.elapsed_seconds,
            summary.final_validation_loss.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into())
        ));
    }
    progress.say(&format!("  weights {}", files.weights_path().display()));
    progress.say(&format!("  log     {}", files.dir.join("train_log.csv").display()));
}
