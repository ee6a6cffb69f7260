//! The bake: a scene to trained models and an honest report. Stages: dataset -> train the
//! naive baseline (-> pixelgen with `baselines`) (-> the ablations) -> train GlassNet, checked
//! against naive on validation half way and at the end, and choose the one to ship
//! (`seed_choice`) -> evaluate (-> path traced + denoised) -> report. Every stage resumes
//! where a killed run stopped and is skipped when already done; each stage's wall time is kept
//! across runs.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

use glassbake_core::output_dir::{claim_output_dir, OutputKind};
use glassbake_core::{Error, Result};
use glassbake_dataset::{fit_glass_budget, DatasetSpec, DatasetStore, Split, TraceDevice};
use glassbake_eval::report::{write_report, ReportInputs, TrainingLog};
use glassbake_eval::score::{noise_floor_row, path_traced_rows, ScoreOptions};
use glassbake_eval::EvaluationSummary;
use glassbake_net::{DeviceChoice, ModelKind};
use glassbake_trace::Estimator;
use indicatif::{ProgressBar, ProgressStyle};

use crate::seed_choice::{choose_glassnet, SeedChoice};
use crate::{evaluate, make_dataset, train_model, Ablation, DatasetRequest, Preset, Progress, TrainRequest};

/// Samples per pixel of the path-traced baseline (`baselines`): the paper's 32.
pub const PATH_TRACED_SPP: u32 = 32;

/// The output-folder kind of a bake: recognised, if made before the marker, by its stage
/// times or its dataset.
const BAKE_DIRECTORY: OutputKind = OutputKind { name: "bake", signatures: &["stage_times.json", "dataset"] };

/// A bake to run (or to continue: the same request in the same folder resumes it).
#[derive(Clone, Debug)]
pub struct BakeRequest {
    /// A built-in scene's name or a path to a manifest, glTF or OBJ file.
    pub scene: String,
    pub preset: Preset,
    /// dataset/, one folder per model, eval/, report/.
    pub out: PathBuf,
    /// Where the networks train and run; `Wgpu` also path-traces the ground truth on the GPU.
    pub device: DeviceChoice,
    /// GPUs of `device`'s kind that share each training batch.
    pub devices: usize,
    /// Also the paper's ablations (no positional encoding; L1 loss only).
    pub ablations: bool,
    /// Also the pixelgen baseline and path tracing at [`PATH_TRACED_SPP`], raw and denoised.
    pub baselines: bool,
    /// LPIPS AlexNet weights (safetensors); without them LPIPS is skipped.
    pub lpips_weights: Option<PathBuf>,
    /// Path-tracer threads for the dataset (`None`: all cores).
    pub threads: Option<usize>,
    /// The ground truth's estimator (`None`: the device's default, or a continued dataset's).
    pub estimator: Option<Estimator>,
    /// How many more GlassNets (the next seeds) to train while every one so far trails naive
    /// on the validation split (`seed_choice`).
    pub seed_retries: u32,
}

impl BakeRequest {
    /// A bake of `scene` at `preset` into `out` on the CPU, without the extra comparisons.
    pub fn new(scene: impl Into<String>, preset: Preset, out: impl Into<PathBuf>) -> BakeRequest {
        BakeRequest {
            scene: scene.into(),
            preset,
            out: out.into(),
            device: DeviceChoice::Cpu,
            devices: 1,
            ablations: false,
            baselines: false,
            lpips_weights: None,
            threads: None,
            estimator: None,
            seed_retries: 1,
        }
    }

    fn trace_device(&self) -> TraceDevice {
        if self.device == DeviceChoice::Wgpu {
            TraceDevice::Wgpu
        } else {
            TraceDevice::Cpu
        }
    }

    fn check(&self) -> Result<()> {
        if self.baselines && !glassbake_eval::denoise::AVAILABLE {
            return Err(Error::bad_input("--baselines", "oidn", format!("{} (or bake without --baselines)", glassbake_eval::denoise::HOW_TO_ENABLE)));
        }
        if let Some(estimator) = self.estimator {
            if self.trace_device() == TraceDevice::Wgpu && estimator != Estimator::PLAIN {
                return Err(Error::bad_input(
                    "bake",
                    "--estimator",
                    format!("{estimator} runs on the CPU only; a bake with --device wgpu traces its ground truth plain on the GPU"),
                ));
            }
        }
        glassbake_scene::load_scene(&self.scene)?;
        Ok(())
    }

    /// The dataset stage: the preset's size, its glass pixels' spp within the preset's
    /// budget, buffers cached, traced on the bake's device.
    pub fn dataset_request(&self) -> Result<DatasetRequest> {
        let size = &self.preset.dataset;
        let device = self.trace_device();
        let mut spec = DatasetSpec {
            glass_spp: size.glass_spp,
            cache_buffers: true,
            device,
            estimator: device.default_estimator(),
            ..DatasetSpec::new(self.scene.clone(), size.resolution, size.spp, [size.train, size.val, size.test])
        };
        if let Some(budget) = size.glass_budget {
            spec = fit_glass_budget(spec, &glassbake_scene::load_scene(&self.scene)?, budget)?;
        }
        Ok(DatasetRequest { estimator: self.estimator, threads: self.threads, ..DatasetRequest::new(spec, self.out.join("dataset")) })
    }

    /// The models the bake trains, each with its folder's name.
    pub fn models(&self) -> Vec<(String, TrainRequest)> {
        let dataset = self.out.join("dataset");
        let request = |name: &str, kind: ModelKind, ablation: Option<Ablation>| {
            let mut train = TrainRequest::new(&dataset, self.out.join(name), self.preset.clone(), kind);
            train.device = self.device;
            train.devices = self.devices;
            train.ablation = ablation;
            (name.to_string(), train)
        };
        let mut list = vec![request("glassnet", ModelKind::Glassnet, None), request("naive", ModelKind::Naive, None)];
        if self.baselines {
            list.push(request("pixelgen", ModelKind::Pixelgen, None));
        }
        if self.ablations {
            list.extend(Ablation::PAPER.map(|a| request(&format!("glassnet-{}", a.name()), ModelKind::Glassnet, Some(a))));
        }
        list
    }

    /// The evaluation stage: every model, then the dataset's test split.
    fn score_options(&self, models: &[(String, TrainRequest)]) -> ScoreOptions {
        ScoreOptions {
            models: models.iter().map(|(_, m)| m.out.clone()).collect(),
            dataset: self.out.join("dataset"),
            out: self.out.join("eval"),
            split: Split::Test,
            frames: None,
            lpips_weights: self.lpips_weights.clone(),
            device: self.device,
            workers: 2,
            path_traced_baseline: self.baselines.then_some(PATH_TRACED_SPP),
            super_sampler: None,
        }
    }

    fn command_line(&self) -> String {
        let estimator = self.estimator.map(|e| format!(" --estimator {}", e.name())).unwrap_or_default();
        format!("`glassbake bake {} --preset {}{estimator}` on {}", self.scene, self.preset.name, self.device.name())
    }
}

/// What a bake produced.
pub struct BakeResult {
    /// The test split's scores, as `eval/metrics.json`.
    pub summary: EvaluationSummary,
    /// The report's index page.
    pub report: PathBuf,
    /// This run's wall time.
    pub elapsed: Duration,
    /// The row of `summary` that is the noise floor (the ground truth at the training spp).
    pub noise_floor: Option<String>,
    /// The GlassNets trained and the one shipped (`None`: no validation frames to choose by).
    pub glassnet_choice: Option<SeedChoice>,
}

/// Runs (or continues) the bake of `request`.
pub fn bake(request: &BakeRequest, progress: &Progress) -> Result<BakeResult> {
    request.check()?;
    claim_output_dir(&request.out, BAKE_DIRECTORY, "--out")?;
    let started = Instant::now();
    let models = request.models();
    let mut stages = Stages::new(request, 1 + models.len() + 1, progress);

    let dataset = request.dataset_request()?;
    let spec = &dataset.spec;
    stages.run(
        format!(
            "dataset ({} frames, {} px, {} spp ({} on glass), test split {} spp ({} on glass))",
            spec.total(),
            spec.resolution,
            spec.spp,
            spec.glass_spp_of(Split::Train),
            spec.spp_of(Split::Test),
            spec.glass_spp_of(Split::Test)
        ),
        &mut || Ok(make_dataset(&dataset, progress)?.generated > 0),
    )?;
    // Naive (and the other models) first: GlassNet is checked against naive as it trains.
    let is_main_glassnet = |train: &TrainRequest| train.model == ModelKind::Glassnet && train.ablation.is_none();
    for (name, train) in models.iter().filter(|(_, train)| !is_main_glassnet(train)) {
        stages.run(format!("train {name}"), &mut || train_model(train, progress))?;
    }
    let mut glassnet_choice = None;
    stages.run("train glassnet, checked against naive on validation".into(), &mut || {
        let glassnet = &models.iter().find(|(_, train)| is_main_glassnet(train)).expect("the bake trains GlassNet").1;
        let naive = &models.iter().find(|(_, train)| train.model == ModelKind::Naive).expect("the bake trains naive").1;
        let (choice, worked) = choose_glassnet(&request.out, glassnet, &naive.out, request.seed_retries, progress)?;
        if let Some(choice) = &choice {
            progress.say(&format!("GlassNet: {}", choice.describe()));
        }
        glassnet_choice = choice;
        Ok(worked)
    })?;
    let options = request.score_options(&models);
    let mut extra_rows: Vec<String> = options.path_traced_baseline.map(|spp| path_traced_rows(spp).to_vec()).unwrap_or_default();
    let noise_floor = noise_floor_row(&DatasetStore::open(&options.dataset)?.manifest.spec, Split::Test);
    extra_rows.extend(noise_floor.clone());
    let current = evaluation_is_current(&options.out, &options.models, &extra_rows, options.lpips_weights.is_some());
    let metrics = options.out.join("metrics.json");
    let mut summary = None;
    stages.run("evaluate and report".into(), &mut || {
        if current {
            progress.say(&format!("{} is up to date with the models; not evaluated again", metrics.display()));
            summary = Some(EvaluationSummary::read(&metrics)?);
            Ok(false)
        } else {
            summary = Some(evaluate(&options, &[], progress)?);
            Ok(true)
        }
    })?;
    let mut facts = stages.finish();
    facts.push(format!("this run: {:.0} s", started.elapsed().as_secs_f64()));
    if let Some(choice) = &glassnet_choice {
        facts.push(format!("GlassNet shipped by {}", choice.describe()));
    }
    // The bake's report: the evaluation's, with the stage times.
    let report = write_report(
        &request.out.join("report"),
        &ReportInputs {
            title: format!("glassbake bake: {}", request.scene),
            facts,
            eval_dir: Some(options.out.clone()),
            training_logs: models.iter().map(|(name, m)| TrainingLog { name: name.clone(), path: m.out.join("train_log.csv") }).collect(),
            bench: Some(request.out.join("bench.json")),
        },
    )?;
    progress.finish();
    Ok(BakeResult { summary: summary.expect("the evaluation stage ran"), report, elapsed: started.elapsed(), noise_floor, glassnet_choice })
}

/// The bake's stages on a bar of their own, each one's wall time recorded in
/// `stage_times.json` when it did its work and kept across runs, so that a resumed or repeated
/// bake still reports what the stages cost.
struct Stages {
    overall: ProgressBar,
    times_path: PathBuf,
    times: BTreeMap<String, f64>,
    /// Lines for the report: the command, then each stage's time.
    facts: Vec<String>,
}

impl Stages {
    fn new(request: &BakeRequest, count: usize, progress: &Progress) -> Stages {
        let overall = progress.add_bar_above(count as u64);
        overall.set_style(ProgressStyle::with_template("bake {prefix} [{elapsed_precise}] stage {pos}/{len}: {msg}").expect("static template"));
        overall.set_prefix(request.scene.clone());
        overall.enable_steady_tick(Duration::from_millis(500));
        let times_path = request.out.join("stage_times.json");
        let times = std::fs::read_to_string(&times_path).ok().and_then(|t| serde_json::from_str(&t).ok()).unwrap_or_default();
        Stages { overall, times_path, times, facts: vec![request.command_line()] }
    }

    /// Runs one stage; `work` returns whether it did anything (false: done earlier).
    fn run(&mut self, name: String, work: &mut dyn FnMut() -> Result<bool>) -> Result<()> {
        self.overall.set_message(name.clone());
        let t0 = Instant::now();
        let worked = work()?;
        let seconds = t0.elapsed().as_secs_f64();
        if worked {
            // A resumed stage records only its last run's share.
            self.times.insert(name.clone(), seconds);
            let json = serde_json::to_string_pretty(&self.times).map_err(|e| Error::Internal(e.to_string()))?;
            glassbake_core::image::write_bytes_atomically(&self.times_path, json.as_bytes())?;
        }
        self.facts.push(match (worked, self.times.get(&name)) {
            (true, _) => format!("{name}: {seconds:.0} s"),
            (false, Some(recorded)) => format!("{name}: {recorded:.0} s (done earlier; {seconds:.0} s to check now)"),
            (false, None) => format!("{name}: done earlier (time not recorded; {seconds:.0} s to check now)"),
        });
        self.overall.inc(1);
        Ok(())
    }

    fn finish(self) -> Vec<String> {
        self.overall.finish_and_clear();
        self.facts
    }
}

fn modified(path: &Path) -> Option<SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

/// True when `eval/metrics.json` is newer than every model's weights and lists exactly these
/// rows (the models, then `extra_rows`) with the same LPIPS setting.
fn evaluation_is_current(eval_dir: &Path, model_dirs: &[PathBuf], extra_rows: &[String], lpips: bool) -> bool {
    let metrics = eval_dir.join("metrics.json");
    let (Some(written), Ok(summary)) = (modified(&metrics), EvaluationSummary::read(&metrics)) else {
        return false;
    };
    let mut names: Vec<String> = model_dirs.iter().map(|d| d.file_name().unwrap_or_default().to_string_lossy().into_owned()).collect();
    names.extend(extra_rows.iter().cloned());
    summary.models.iter().map(|m| &m.model).eq(names.iter())
        && summary.lpips.starts_with("AlexNet") == lpips
        && model_dirs.iter().all(|d| modified(&d.join("glassnet.safetensors")).is_some_and(|w| w <= written))
        // A bake killed between the metrics and their report evaluates again.
        && modified(&eval_dir.join("report").join("index.html")).is_some_and(|r| r >= written)
}
