//! `glassbake bake`: a scene to a trained model and an honest report in one command.
//! Stages: dataset -> train GlassNet -> train the naive baseline (-> pixelgen with
//! `--baselines`) (-> the ablations) -> eval (-> path traced + denoised) -> report. Every
//! stage resumes where a killed run stopped and is skipped when already done.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Result;
use clap::Args;
use glassbake_core::output_dir::{claim_output_dir, OutputKind};
use glassbake_core::Error;
use glassbake_eval::score::{noise_floor_row, path_traced_rows};
use glassbake_eval::EvaluationSummary;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use super::dataset::{default_test_glass_spp, default_test_spp};
use super::dataset::{make_dataset, MakeArgs};
use super::eval::{evaluate, EvalArgs};
use super::train::{train_model, Ablation, CommonTrainArgs, TrainArgs};

#[derive(Args)]
pub struct BakeArgs {
    /// A built-in name or a path to a manifest, glTF or OBJ file.
    pub scene: String,
    /// quick (a CPU bake: 96 px, about half an hour for cornellbox on 2 cores), paper (a GPU bake: 256 px, the paper's network) or
    /// tiny (a smoke test: seconds, meaningless numbers).
    #[arg(long, default_value = "quick")]
    pub preset: String,
    /// Output directory: dataset/, glassnet/, naive/ (pixelgen/, glassnet-*/), eval/, report/.
    #[arg(long, default_value = "bake")]
    pub out: PathBuf,
    /// cpu (burn's flex backend), wgpu (Vulkan) or cuda (a build with the `cuda` feature) for
    /// training and evaluation; wgpu also
    /// path-traces the dataset's ground truth on the GPU (`dataset --device wgpu`).
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Also train and evaluate the paper's ablations (no positional encoding; L1 loss only).
    #[arg(long)]
    pub ablations: bool,
    /// Also the paper's other comparisons: the pixelgen baseline (Active Exploration's
    /// per-pixel MLP) and path tracing at 32 spp, raw and denoised with Open Image Denoise
    /// (needs a build with the `oidn` feature, docs/eval.md).
    #[arg(long)]
    pub baselines: bool,
    /// LPIPS AlexNet weights (safetensors, see docs/eval.md); without it LPIPS is skipped.
    #[arg(long)]
    pub lpips_weights: Option<PathBuf>,
    /// Path-tracer threads for the dataset (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// The ground truth's estimator, as `glassbake dataset --estimator`: by default
    /// `caustic+adaptive+stratified` on the CPU (unbiased) and `plain` with `--device wgpu`;
    /// `caustic+merging+adaptive+stratified` trades a blur of about a pixel for much less
    /// noise behind glass (docs/trace.md). A bake being continued keeps its dataset's estimator.
    #[arg(long, value_parser = super::dataset::parse_estimator)]
    pub estimator: Option<glassbake_trace::Estimator>,
}

/// Dataset size and training preset of a bake preset.
struct BakePreset {
    resolution: u32,
    spp: u32,
    /// On the training frames' glass pixels.
    glass_spp: u32,
    train: u64,
    val: u64,
    test: u64,
    training: &'static str,
}

fn bake_preset(name: &str) -> glassbake_core::Result<BakePreset> {
    Ok(match name {
        "tiny" => BakePreset { resolution: 32, spp: 4, glass_spp: 4, train: 8, val: 2, test: 2, training: "tiny" },
        // Sized to finish in about half an hour on a 2-core CPU on cornellbox (docs/benchmarks.md).
        // 96 px so that text behind the glass is resolvable; the test split at 8x spp. Glass
        // pixels of training frames at 4x spp: at 96 spp what the camera sees through thick
        // glass is mostly noise to learn from (cornellbox8: the training frames' T.PSNR
        // against the reference 31.6 dB, 40.0 with 384 on glass; GlassNet's T.PSNR +0.7 and
        // +1.2 dB for its two seeds; the dataset takes 30 min, docs/benchmarks.md).
        "quick" => BakePreset { resolution: 96, spp: 96, glass_spp: 4 * 96, train: 320, val: 24, test: 24, training: "quick" },
        "paper" => BakePreset { resolution: 256, spp: 512, glass_spp: 512, train: 1800, val: 200, test: 128, training: "paper" },
        _ => return Err(Error::bad_input("--preset", "preset", format!("{name:?} is not tiny, quick or paper"))),
    })
}

/// Samples per pixel of the path-traced baseline (`--baselines`): the paper's 32.
const PATH_TRACED_SPP: u32 = 32;

/// The output-folder kind of a bake: recognised, if made before the marker, by its stage
/// times or its dataset.
const BAKE_DIRECTORY: OutputKind = OutputKind { name: "bake", signatures: &["stage_times.json", "dataset"] };

/// The models a bake trains: (directory name, model kind, ablation).
fn models(ablations: bool, baselines: bool) -> Vec<(String, &'static str, Option<Ablation>)> {
    let mut list = vec![("glassnet".to_string(), "glassnet", None), ("naive".to_string(), "naive", None)];
    if baselines {
        list.push(("pixelgen".to_string(), "pixelgen", None));
    }
    if ablations {
        list.extend(Ablation::PAPER.map(|a| (format!("glassnet-{}", a.name()), "glassnet", Some(a))));
    }
    list
}

fn modified(path: &Path) -> Option<std::time::SystemTime> {
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

pub fn run(args: BakeArgs) -> Result<()> {
    let preset = bake_preset(&args.preset)?;
    glassbake_net::DeviceChoice::parse(&args.device)?;
    if args.baselines && !glassbake_eval::denoise::AVAILABLE {
        return Err(Error::bad_input("--baselines", "oidn", format!("{} (or bake without --baselines)", glassbake_eval::denoise::HOW_TO_ENABLE)).into());
    }
    let trace_device = if args.device == "wgpu" { glassbake_dataset::TraceDevice::Wgpu } else { glassbake_dataset::TraceDevice::Cpu };
    if let Some(estimator) = args.estimator {
        if trace_device == glassbake_dataset::TraceDevice::Wgpu && estimator != glassbake_trace::Estimator::PLAIN {
            return Err(Error::bad_input(
                "bake",
                "--estimator",
                format!("{estimator} runs on the CPU only; a bake with --device wgpu traces its ground truth plain on the GPU"),
            )
            .into());
        }
    }
    glassbake_scene::load_scene(&args.scene)?;
    claim_output_dir(&args.out, BAKE_DIRECTORY, "--out")?;
    let started = Instant::now();
    let dataset_dir = args.out.join("dataset");
    let models = models(args.ablations, args.baselines);
    let model_dirs: Vec<PathBuf> = models.iter().map(|m| args.out.join(&m.0)).collect();

    let multi = MultiProgress::new();
    let stages = 1 + models.len() + 1;
    let overall = multi.add(ProgressBar::new(stages as u64));
    overall.set_style(ProgressStyle::with_template("bake {prefix} [{elapsed_precise}] stage {pos}/{len}: {msg}").expect("static template"));
    overall.set_prefix(args.scene.clone());
    overall.enable_steady_tick(Duration::from_millis(500));
    let bar = multi.add(ProgressBar::new(0));
    let estimator_flag = args.estimator.map(|e| format!(" --estimator {}", e.name())).unwrap_or_default();
    let mut facts = vec![format!("`glassbake bake {} --preset {}{estimator_flag}` on {}", args.scene, args.preset, args.device)];
    // Wall time of each stage when it last did its work, kept across runs so that a resumed
    // or repeated bake still reports what the stages cost.
    let times_path = args.out.join("stage_times.json");
    let mut times: BTreeMap<String, f64> = std::fs::read_to_string(&times_path).ok().and_then(|t| serde_json::from_str(&t).ok()).unwrap_or_default();
    let mut stage = |name: String, work: &mut dyn FnMut() -> Result<bool>| -> Result<()> {
        overall.set_message(name.clone());
        let t0 = Instant::now();
        let worked = work()?;
        let seconds = t0.elapsed().as_secs_f64();
        if worked {
            // A resumed stage records only its last run's share.
            times.insert(name.clone(), seconds);
            let json = serde_json::to_string_pretty(&times).map_err(|e| Error::Internal(e.to_string()))?;
            glassbake_core::image::write_bytes_atomically(&times_path, json.as_bytes())?;
        }
        facts.push(match (worked, times.get(&name)) {
            (true, _) => format!("{name}: {seconds:.0} s"),
            (false, Some(recorded)) => format!("{name}: {recorded:.0} s (done earlier; {seconds:.0} s to check now)"),
            (false, None) => format!("{name}: done earlier (time not recorded; {seconds:.0} s to check now)"),
        });
        overall.inc(1);
        Ok(())
    };

    let make = MakeArgs {
        scene: args.scene.clone(),
        out: dataset_dir.clone(),
        train: preset.train,
        val: preset.val,
        test: preset.test,
        res: preset.resolution,
        spp: preset.spp,
        glass_spp: (preset.glass_spp != preset.spp).then_some(preset.glass_spp),
        test_spp: None,
        test_glass_spp: None,
        seed: 0,
        cache_buffers: true,
        shard: None,
        threads: args.threads,
        // A bake on the GPU path-traces its ground truth there too.
        device: trace_device,
        estimator: args.estimator,
    };
    stage(
        format!(
            "dataset ({} frames, {} px, {} spp ({} on glass), test split {} spp ({} on glass))",
            preset.train + preset.val + preset.test,
            preset.resolution,
            preset.spp,
            preset.glass_spp,
            default_test_spp(preset.spp),
            default_test_glass_spp(default_test_spp(preset.spp))
        ),
        &mut || make_dataset(&make, &bar),
    )?;
    for ((name, kind, ablation), dir) in models.iter().zip(&model_dirs) {
        let train = TrainArgs {
            common: CommonTrainArgs {
                dataset: dataset_dir.clone(),
                out: dir.clone(),
                preset: preset.training.into(),
                device: args.device.clone(),
                steps: None,
                batch: None,
                lr: None,
                crop: None,
                seed: None,
                workers: 2,
            },
            model: kind.to_string(),
            encoding_frequencies: None,
            ssim_weight: None,
            ablation: ablation.map(|a| a.name().to_string()),
            renderer_output: None,
            position_encoding: None,
        };
        stage(format!("train {name}"), &mut || train_model(&train, &bar))?;
    }
    let eval_dir = args.out.join("eval");
    let mut paths = model_dirs.clone();
    paths.push(dataset_dir.clone());
    let path_traced_baseline = args.baselines.then_some(PATH_TRACED_SPP);
    let eval = EvalArgs {
        paths,
        out: eval_dir.clone(),
        split: "test".into(),
        frames: None,
        lpips_weights: args.lpips_weights.clone(),
        device: args.device.clone(),
        workers: 2,
        path_traced_baseline,
        super_sampler: None,
    };
    let mut summary = None;
    let mut extra_rows: Vec<String> = path_traced_baseline.map(|spp| path_traced_rows(spp).to_vec()).unwrap_or_default();
    let noise_floor = noise_floor_row(&glassbake_dataset::DatasetStore::open(&dataset_dir)?.manifest.spec, glassbake_dataset::Split::Test);
    extra_rows.extend(noise_floor.clone());
    let current = evaluation_is_current(&eval_dir, &model_dirs, &extra_rows, args.lpips_weights.is_some());
    stage("evaluate and report".into(), &mut || {
        if current {
            bar.suspend(|| println!("{} is up to date with the models; not evaluated again", eval_dir.join("metrics.json").display()));
            summary = Some(EvaluationSummary::read(&eval_dir.join("metrics.json"))?);
            Ok(false)
        } else {
            summary = Some(evaluate(&eval, &bar, &[])?);
            Ok(true)
        }
    })?;
    facts.push(format!("this run: {:.0} s", started.elapsed().as_secs_f64()));
    // The bake's report: the evaluation's, with the stage times.
    let report = glassbake_eval::report::write_report(
        &args.out.join("report"),
        &glassbake_eval::report::ReportInputs {
            title: format!("glassbake bake: {}", args.scene),
            facts,
            eval_dir: Some(eval_dir.clone()),
            training_logs: models
                .iter()
                .zip(&model_dirs)
                .map(|(m, d)| glassbake_eval::report::TrainingLog { name: m.0.clone(), path: d.join("train_log.csv") })
                .collect(),
            bench: Some(args.out.join("bench.json")),
        },
    )?;
    overall.finish_and_clear();
    bar.finish_and_clear();
    let summary = summary.expect("the evaluation stage ran");
    println!("\nbake of {} done in {:.1} min: {}", args.scene, started.elapsed().as_secs_f64() / 60.0, args.out.display());
    println!("  report {}\n", report.display());
    println!("{} frames of the test split, {} px:", summary.frames.len(), summary.resolution);
    print!("{}", summary.text_table());
    if let (Some(g), Some(n)) = (summary.models.iter().find(|m| m.model == "glassnet"), summary.models.iter().find(|m| m.model == "naive")) {
        if let (Some(gt), Some(nt)) = (g.t_psnr, n.t_psnr) {
            let interval =
                n.versus.as_ref().and_then(|v| v.differences.get("t_psnr")).map(|d| format!(", 95% [{:+.2}, {:+.2}]", -d.high, -d.low)).unwrap_or_default();
            println!("GlassNet vs Naive on transparent pixels: T.PSNR {gt:.2} vs {nt:.2} dB ({:+.2} dB{interval})", gt - nt);
        }
    }
    for sentence in summary.not_leading() {
        println!("warning: {sentence}");
    }
    if let Some(floor) = noise_floor.as_ref().and_then(|row| summary.models.iter().find(|m| &m.model == row)) {
        println!(
            "Noise floor ({}: the training-spp ground truth against the test split's): PSNR {:.2} dB, T.PSNR {}",
            floor.model,
            floor.psnr,
            floor.t_psnr.map(|t| format!("{t:.2} dB")).unwrap_or_else(|| "-".into())
        );
    }
    Ok(())
}
