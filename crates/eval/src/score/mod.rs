//! Scoring trained models on a dataset split: each frame rendered by every model (and, on
//! request, path-traced at a low spp and denoised), the noise floor where the split has one,
//! the order test on GlassNet, then `metrics.*`, `frames/`, `grids/` and the report. This is
//! where the evaluation meets the network and dataset crates; the metrics, grids and report
//! it calls see only images.

use std::path::{Path, PathBuf};

use glassbake_core::{Error, PlanarImage, Result};
use glassbake_dataset::{DatasetInfo, DatasetSpec, DatasetStore, Example, Loader, LoaderOptions, Split};
use glassbake_net::burn::prelude::Device;
use glassbake_net::{select_device, DeviceChoice, FrameRef, ModelKind, TrainedModel, TrainedSuperSampler};
use rand::seq::SliceRandom;
use rand::SeedableRng;

mod rows;

use crate::report::{write_report, ReportInputs, TrainingLog};
use crate::rgb::mask_from_planar;
use crate::{Evaluation, EvaluationSummary, Lpips, OrderTest, RgbImage};
use rows::{HalfResolution, Rows};

/// What to score, on what, and where the results go.
#[derive(Clone, Debug)]
pub struct ScoreOptions {
    /// Trained model directories (`glassbake train`).
    pub models: Vec<PathBuf>,
    pub dataset: PathBuf,
    /// Where metrics.json, metrics.csv, frames/, grids/ and report/ go.
    pub out: PathBuf,
    pub split: Split,
    /// Only the first N frames of the split.
    pub frames: Option<usize>,
    pub lpips_weights: Option<PathBuf>,
    pub device: DeviceChoice,
    /// Frame-reading/rasterizing worker threads.
    pub workers: usize,
    /// Also path trace each frame at this spp and denoise it (rows `ptSPP`, `ptSPP+oidn`).
    pub path_traced_baseline: Option<u32>,
    /// A trained x2 super-sampler (`glassbake train-sr`): the first GlassNet among `models`
    /// also renders each frame at half resolution, brought up by the super-sampler and, for
    /// comparison, bilinearly (rows [`half_resolution_rows`]).
    pub super_sampler: Option<PathBuf>,
}

/// What a scoring run produced: the summary, and the report's index page.
pub struct Scored {
    pub summary: EvaluationSummary,
    pub report: PathBuf,
}

/// The metrics rows of the path-traced baseline at `spp`: traced, then traced and denoised.
pub fn path_traced_rows(spp: u32) -> [String; 2] {
    [format!("pt{spp}"), format!("pt{spp}+oidn")]
}

/// The metrics rows of model `name` rendered at half resolution and brought up to the
/// dataset's: by the super-sampler, and bilinearly.
pub fn half_resolution_rows(name: &str) -> [String; 2] {
    [format!("{name}@half+sr"), format!("{name}@half+bilinear")]
}

/// Loads the super-sampler of `options` for the first GlassNet among `models`, checking that
/// it was trained on this scene and that the frames halve to a size GlassNet takes.
fn half_resolution(options: &ScoreOptions, models: &[(String, TrainedModel)], scene_hash: &str, resolution: u32) -> Result<Option<HalfResolution>> {
    let Some(dir) = &options.super_sampler else { return Ok(None) };
    let model = models
        .iter()
        .position(|(_, m)| m.kind() == ModelKind::Glassnet)
        .ok_or_else(|| Error::bad_input("--super-sampler", "models", "needs a GlassNet among the models: it brings up GlassNet's half-resolution image"))?;
    let sampler = TrainedSuperSampler::load(dir, &models[model].1.device)?;
    if sampler.files.config.data.scene_hash != scene_hash {
        return Err(Error::bad_input(
            dir.join("config.json").display(),
            "data.scene_hash",
            format!(
                "the super-sampler was trained on scene {} ({}), the dataset holds scene hash {scene_hash}",
                sampler.files.config.data.scene, sampler.files.config.data.scene_hash
            ),
        ));
    }
    let multiple = 2 * models[model].1.config().size_multiple() as u32;
    if !resolution.is_multiple_of(multiple) {
        return Err(Error::bad_input(
            "--super-sampler",
            "resolution",
            format!("{resolution} px frames halve to a size GlassNet cannot take (need a multiple of {multiple})"),
        ));
    }
    Ok(Some(HalfResolution { sampler, model }))
}

/// The metrics row of the noise floor, where `split` of the dataset has one: its ground truth
/// traced as training frames are, scored against the (higher-spp) ground truth of the same
/// frames: `gt-96spp`, or `gt-96spp-384glass` where training frames' glass pixels get more.
pub fn noise_floor_row(spec: &DatasetSpec, split: Split) -> Option<String> {
    let glass_spp = spec.glass_spp_of(Split::Train);
    let glass = if glass_spp != spec.spp { format!("-{glass_spp}glass") } else { String::new() };
    spec.has_train_spp_copy(split).then(|| format!("gt-{}spp{glass}", spec.spp))
}

fn model_name(dir: &Path) -> String {
    dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| dir.display().to_string())
}

/// Largest |a - b| over two equally long slices (infinite when their lengths differ).
fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    if a.len() != b.len() {
        return f32::INFINITY;
    }
    a.iter().zip(b).map(|(x, y)| if x.to_bits() == y.to_bits() { 0.0 } else { (x - y).abs().max(f32::MIN_POSITIVE) }).fold(0.0, f32::max)
}

/// Refuses a split with frames missing or damaged.
fn check_split_complete(dataset: &Path, info: &DatasetInfo, split: Split) -> Result<()> {
    let split_name = split_name(split);
    if let Some((_, planned, done)) = info.splits.iter().find(|s| s.0 == split) {
        if done < planned {
            return Err(Error::bad_input(
                dataset.display(),
                "frames",
                format!(
                    "the {split_name} split is incomplete ({done}/{planned}){}; finish it with `glassbake dataset` (it makes damaged frames again)",
                    info.damaged_summary()
                ),
            ));
        }
    }
    Ok(())
}

/// The dataset's scene where it is needed: to rasterize uncached buffers (the loader checks it
/// then) and to path trace (which must see the scene the dataset was made from).
fn scene_if_needed(options: &ScoreOptions, store: &DatasetStore) -> Result<Option<glassbake_scene::Scene>> {
    let scene = if !store.manifest.reads_cached_buffers() || options.path_traced_baseline.is_some() {
        Some(glassbake_scene::load_scene(&store.manifest.spec.scene)?)
    } else {
        None
    };
    if let (Some(scene), Some(_)) = (&scene, options.path_traced_baseline) {
        if scene.content_hash() != store.manifest.scene.hash {
            return Err(Error::bad_input(
                &store.manifest.spec.scene,
                "scene",
                format!(
                    "has changed since the dataset {} was made (scene hash {} now, {} then)",
                    options.dataset.display(),
                    scene.content_hash(),
                    store.manifest.scene.hash
                ),
            ));
        }
    }
    Ok(scene)
}

/// The options that can be refused before any file is read.
fn check_options(options: &ScoreOptions) -> Result<()> {
    if options.path_traced_baseline.is_some() && !crate::denoise::AVAILABLE {
        return Err(Error::bad_input("--path-traced-baseline", "oidn", crate::denoise::HOW_TO_ENABLE));
    }
    if options.path_traced_baseline == Some(0) {
        return Err(Error::bad_input("--path-traced-baseline", "spp", "must be at least 1"));
    }
    if options.frames == Some(0) {
        return Err(Error::bad_input("--frames", "frames", "must be at least 1 (a run of no frames has no metrics)"));
    }
    Ok(())
}

/// The models in `model_dirs`, each checked to be of the dataset's scene, with their row names
/// (a directory's name; repeats numbered).
fn load_models(model_dirs: &[PathBuf], store: &DatasetStore, device: &Device) -> Result<Vec<(String, TrainedModel)>> {
    let mut models: Vec<(String, TrainedModel)> = Vec::new();
    for dir in model_dirs {
        let model = TrainedModel::load(dir, device)?;
        let data = &model.files.config.data;
        if data.scene_hash != store.manifest.scene.hash {
            return Err(Error::bad_input(
                dir.join("config.json").display(),
                "data.scene_hash",
                format!(
                    "the model was trained on scene {} ({}), the dataset holds {} ({})",
                    data.scene, data.scene_hash, store.manifest.scene.name, store.manifest.scene.hash
                ),
            ));
        }
        let mut name = model_name(dir);
        if models.iter().any(|(n, _)| *n == name) {
            name = format!("{name}-{}", models.len());
        }
        models.push((name, model));
    }
    Ok(models)
}

fn split_name(split: Split) -> &'static str {
    match split {
        Split::Train => "train",
        Split::Val => "val",
        Split::Test => "test",
    }
}

/// The evaluation's own report (`OUT/report/`): the dataset, the noise floor's meaning and
/// `facts`, then the metrics and the models' training curves.
fn write_evaluation_report(
    options: &ScoreOptions,
    store: &DatasetStore,
    info: &DatasetInfo,
    names: &[String],
    noise_floor: Option<&str>,
    facts: &[String],
) -> Result<PathBuf> {
    let (dataset, split) = (&options.dataset, options.split);
    let split_name = split_name(split);
    let training_logs = options.models.iter().zip(names).map(|(dir, name)| TrainingLog { name: name.clone(), path: dir.join("train_log.csv") }).collect();
    let spec = &store.manifest.spec;
    let glass_spp = spec.glass_spp_of(split);
    let truth_spp = if glass_spp != spec.spp_of(split) {
        format!("{} spp, {glass_spp} on pixels showing glass", spec.spp_of(split))
    } else {
        format!("{} spp", spec.spp_of(split))
    };
    let mut report_facts = vec![format!(
        "dataset {} ({} transparent objects, {} px, {} spp; the {} split's ground truth at {truth_spp})",
        dataset.display(),
        info.transparent_objects,
        info.resolution,
        info.spp,
        split_name,
    )];
    if let Some(row) = noise_floor {
        report_facts.push(format!(
            "noise floor: row {row} is the ground truth traced again at the training spp ({}) with other random numbers, scored against the ground truth ({truth_spp}): how far the frames the models learned from are from converged",
            info.spp,
        ));
    }
    report_facts.extend(facts.iter().cloned());
    write_report(
        &options.out.join("report"),
        &ReportInputs {
            title: format!("glassbake: {}", store.manifest.scene.name),
            facts: report_facts,
            eval_dir: Some(options.out.clone()),
            training_logs,
            bench: None,
        },
    )
}

/// Scores `options.models` on the dataset split, writes `OUT/metrics.*`, `OUT/frames`,
/// `OUT/grids` and `OUT/report/`. `facts` are extra lines for the report (the bake's stage
/// times); `progress(done, total)` is called after every frame.
pub fn score_models(options: &ScoreOptions, facts: &[String], progress: &mut dyn FnMut(usize, usize)) -> Result<Scored> {
    let dataset = &options.dataset;
    let split = options.split;
    check_options(options)?;
    let store = DatasetStore::open(dataset)?;
    let info = store.info();
    check_split_complete(dataset, &info, split)?;
    let device = select_device(options.device, 0, false);
    let models = load_models(&options.models, &store, &device)?;
    let half = half_resolution(options, &models, &store.manifest.scene.hash, store.manifest.spec.resolution)?;
    let lpips = options.lpips_weights.as_deref().map(Lpips::load).transpose()?;
    let needs_naive = options.path_traced_baseline.is_some() || models.iter().any(|(_, m)| m.net.reads_naive_gbuffer());
    let scene = scene_if_needed(options, &store)?;
    let loader_scene = if store.manifest.reads_cached_buffers() { None } else { scene.clone() };
    let rows = Rows { models, half, path_traced: options.path_traced_baseline.zip(scene), noise_floor: noise_floor_row(&store.manifest.spec, split) };
    let names = rows.names();
    let mut loader = Loader::new(
        dataset,
        loader_scene,
        LoaderOptions { split, batch_size: 1, crop: None, seed: 0, shuffle: false, workers: options.workers, naive: needs_naive, ..Default::default() },
    )?;
    let total = options.frames.unwrap_or(usize::MAX).min(loader.len());
    let mut evaluation = Evaluation::new(&options.out, names.clone(), lpips, dataset.display().to_string(), split_name(split).to_string())?;
    // The order test runs on the first model that sums transparency buffers (GlassNet).
    let order_model = rows.models.iter().find(|(_, m)| m.kind() == ModelKind::Glassnet);
    let mut order = order_model.map(|(name, _)| OrderTest { model: name.clone(), frames: 0, reversed_max_abs_diff: 0.0, shuffled_max_abs_diff: 0.0 });
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x0dde_0b1e);

    progress(0, total);
    let mut done = 0;
    'frames: for examples in loader.epoch_iter(0) {
        for e in examples? {
            if done == total {
                break 'frames;
            }
            let predictions = rows.predict(&e, &store)?;
            if let (Some((_, model)), Some(order)) = (order_model, order.as_mut()) {
                add_order_test_frame(order, model, &e, &mut rng)?;
            }
            for (row, prediction) in predictions.iter().enumerate() {
                if let Some(s) = prediction.seconds {
                    evaluation.add_render_time(row, s);
                }
            }
            let images: Vec<RgbImage> = predictions.into_iter().map(|p| p.image).collect();
            evaluation.add_frame(e.index, &RgbImage::from_planar(&e.ground_truth)?, &mask_from_planar(&e.mask), &images)?;
            done += 1;
            progress(done, total);
        }
    }
    if let Some(order) = order {
        evaluation.set_order_test(order);
    }
    let summary = evaluation.finish()?;
    let index = write_evaluation_report(options, &store, &info, &names, rows.noise_floor.as_deref(), facts)?;
    Ok(Scored { summary, report: index })
}

/// Renders frame `e` with `model` (GlassNet) with its transparency buffers as given, reversed
/// and shuffled, and records the largest difference in `order`.
fn add_order_test_frame(order: &mut OrderTest, model: &TrainedModel, e: &Example, rng: &mut rand_chacha::ChaCha8Rng) -> Result<()> {
    let (gbuffer, light_coverage) = e.gbuffer(false);
    let frame = |transparent: &[PlanarImage]| {
        model.render_raw(FrameRef { gbuffer, light_coverage: Some(light_coverage), transparent, values: &e.values, ground_truth: None })
    };
    let original = frame(&e.transparent)?;
    let mut reversed = e.transparent.clone();
    reversed.reverse();
    let mut shuffled = e.transparent.clone();
    shuffled.shuffle(rng);
    order.reversed_max_abs_diff = order.reversed_max_abs_diff.max(max_abs_diff(&original, &frame(&reversed)?));
    order.shuffled_max_abs_diff = order.shuffled_max_abs_diff.max(max_abs_diff(&original, &frame(&shuffled)?));
    order.frames += 1;
    Ok(())
}
