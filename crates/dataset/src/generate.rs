//! Generating a dataset: per frame, the sampled scene instance is path-traced (and, with
//! `cache_buffers`, rasterized) and written atomically. Re-running the same command skips
//! complete frames and redoes missing or corrupt ones; `--shard i/n` makes only the frames
//! whose index mod n is i.

use std::path::Path;
use std::time::{Duration, Instant};

use glassbake_core::image::ExrPrecision;
use glassbake_core::seed::purpose_seed;
use glassbake_core::{Error, Result};
use glassbake_raster::{Rasterizer, RasterizerOptions};
use glassbake_scene::Scene;
use glassbake_trace::{sample_trace_seed, TraceSettings};
use glassbake_trace_gpu::GpuTracer;

use crate::format::{DatasetManifest, DatasetSpec, SampleRecord, Split, TraceDevice};
use crate::store::{write_frame, DatasetStore, FrameStatus};

/// Which frames this machine makes: those whose index mod `count` is `index`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShardSpec {
    pub index: u64,
    pub count: u64,
}

impl ShardSpec {
    pub const ALL: ShardSpec = ShardSpec { index: 0, count: 1 };

    /// Parse `i/n` (0 <= i < n).
    pub fn parse(text: &str) -> Result<ShardSpec> {
        let bad = |why: &str| Error::bad_input("--shard", text, why.to_string());
        let (i, n) = text.split_once('/').ok_or_else(|| bad("expected i/n, e.g. 3/16"))?;
        let index: u64 = i.trim().parse().map_err(|_| bad("i is not a non-negative integer"))?;
        let count: u64 = n.trim().parse().map_err(|_| bad("n is not a positive integer"))?;
        if count == 0 || index >= count {
            return Err(bad("need 0 <= i < n"));
        }
        Ok(ShardSpec { index, count })
    }

    pub fn contains(&self, frame: u64) -> bool {
        frame % self.count == self.index
    }
}

#[derive(Clone, Debug)]
pub struct GenerateOptions {
    pub shard: ShardSpec,
    /// Tracer threads (`None`: all cores). Images do not depend on it.
    pub threads: Option<usize>,
    /// Which Vulkan adapter the rasterizer (and, for `TraceDevice::Wgpu`, the tracer) opens.
    pub rasterizer: RasterizerOptions,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        GenerateOptions { shard: ShardSpec::ALL, threads: None, rasterizer: RasterizerOptions::default() }
    }
}

#[derive(Clone, Debug, Default)]
pub struct GenerateSummary {
    /// Frames of this shard in the dataset.
    pub frames_in_shard: u64,
    /// Frames made by this run.
    pub generated: u64,
    /// Frames that were already complete.
    pub skipped: u64,
    /// Frames whose files were found truncated or corrupt and redone.
    pub redone: u64,
    /// Path samples that came out NaN/inf and were discarded.
    pub discarded_samples: u64,
    pub elapsed: Duration,
    pub disk_bytes: u64,
}

/// Where a generation run is. Frames differ in cost (test frames may be traced at a higher
/// spp), so the work is counted in samples per pixel traced, for an honest ETA.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GenerateProgress {
    /// Frames of this shard finished, and in all.
    pub frames_done: u64,
    pub frames_total: u64,
    /// Samples per pixel traced for this shard's frames so far, and in all.
    pub work_done: u64,
    pub work_total: u64,
}

pub type Progress<'a> = &'a dyn Fn(GenerateProgress);

/// Samples per pixel traced to make frame `sample`; where glass pixels get more, an estimate
/// that counts a quarter of the pixels as glass (which ones is known only once the frame is
/// traced: a fifth on cornellbox, three quarters on bathroom).
fn frame_work(spec: &DatasetSpec, sample: &SampleRecord) -> u64 {
    let with_glass = |spp: u32, glass_spp: u32| u64::from(spp) + u64::from(glass_spp.saturating_sub(spp) / 4);
    let copy = if spec.has_train_spp_copy(sample.split) { with_glass(spec.spp, spec.glass_spp_of(Split::Train)) } else { 0 };
    with_glass(spec.spp_of(sample.split), spec.glass_spp_of(sample.split)) + copy
}

/// Rasterizes frame `sample` of `instance` and stores its buffers as f16 EXR.
fn store_buffers(store: &DatasetStore, rasterizer: &mut Rasterizer, instance: &Scene, sample: &SampleRecord) -> Result<()> {
    let res = store.manifest.spec.resolution;
    let buffers = rasterizer.render(instance, &sample.camera, res, res)?.combined()?;
    write_frame(&store.buffers_path(sample.index), &buffers, ExrPrecision::F16, &store.manifest.frame_label(sample.index))
}

fn make_frame(
    store: &DatasetStore,
    scene: &Scene,
    sample: &SampleRecord,
    rasterizer: Option<&mut Rasterizer>,
    gpu_tracer: Option<&GpuTracer>,
    threads: Option<usize>,
) -> Result<u64> {
    let res = store.manifest.spec.resolution;
    let instance = scene.instantiate(&sample.values)?;
    if let Some(rasterizer) = rasterizer {
        store_buffers(store, rasterizer, &instance, sample)?;
    }
    let spec = &store.manifest.spec;
    let trace = |spp: u32, glass_spp: u32, seed: u64| -> Result<glassbake_trace::TraceOutput> {
        let mut settings = TraceSettings::new(res, res, spp, seed);
        settings.threads = threads;
        settings.estimator = spec.estimator;
        match gpu_tracer {
            // The GPU tracer draws every pixel at one spp: the glass pixels' for all of them.
            Some(tracer) => {
                settings.spp = glass_spp;
                tracer.render(&instance, &sample.camera, &settings, None)
            }
            None => {
                settings.glass_spp = Some(glass_spp);
                glassbake_trace::render(&instance, &sample.camera, &settings, None)
            }
        }
    };
    let mut discarded = 0;
    if spec.has_train_spp_copy(sample.split) {
        // An independent trace at the training spp (glass pixels at theirs): its error against
        // the high-spp ground truth is the noise floor of what the models learned from.
        let copy = trace(spec.spp, spec.glass_spp_of(Split::Train), purpose_seed(sample.seed, "training-spp copy of a test frame"))?;
        refuse_non_finite(&copy.image, &scene.name, sample.index)?;
        write_frame(&store.train_spp_gt_path(sample.index), &copy.image, ExrPrecision::F32, &store.manifest.frame_label(sample.index))?;
        discarded += copy.discarded_samples;
    }
    let traced = trace(spec.spp_of(sample.split), spec.glass_spp_of(sample.split), sample_trace_seed(sample.seed))?;
    refuse_non_finite(&traced.image, &scene.name, sample.index)?;
    traced.image.write_png_rgb(&store.preview_path(sample.index), [0, 1, 2])?;
    // Ground truth last: it is what marks a frame as started-and-finished for humans too.
    write_frame(&store.gt_path(sample.index), &traced.image, ExrPrecision::F32, &store.manifest.frame_label(sample.index))?;
    Ok(discarded + traced.discarded_samples)
}

/// The most path-tracer threads a dataset run starts.
pub const MAX_THREADS: usize = 1024;

/// Make (or complete) the dataset `spec` of `scene` in `dir`. Its spec and options are checked
/// before anything is written.
pub fn generate(scene: &Scene, spec: &DatasetSpec, dir: &Path, options: &GenerateOptions, progress: Progress) -> Result<GenerateSummary> {
    spec.validate()?;
    if options.threads.is_some_and(|n| n == 0 || n > MAX_THREADS) {
        return Err(Error::bad_input("--threads", "threads", format!("must lie in 1..={MAX_THREADS}")));
    }
    let start = Instant::now();
    let planned = DatasetManifest::plan(spec, scene);
    let store = DatasetStore::create_or_resume(dir, &planned)?;
    for w in scene.warnings() {
        tracing::warn!("{}: {w}", spec.scene);
    }
    let mine: Vec<&SampleRecord> = store.manifest.samples.iter().filter(|s| options.shard.contains(s.index)).collect();
    let mut summary = GenerateSummary { frames_in_shard: mine.len() as u64, ..Default::default() };
    let mut todo = Vec::new();
    for sample in &mine {
        match store.frame_status(sample.index) {
            FrameStatus::Done => summary.skipped += 1,
            FrameStatus::Missing => todo.push(*sample),
            FrameStatus::Corrupt(why) => {
                tracing::warn!("frame {}: {why}; making it again", sample.index);
                summary.redone += 1;
                todo.push(*sample);
            }
        }
    }
    let mut rasterizer = if spec.cache_buffers && !todo.is_empty() { Some(Rasterizer::new(options.rasterizer.clone())?) } else { None };
    let gpu_tracer = if spec.device == TraceDevice::Wgpu && !todo.is_empty() { Some(GpuTracer::new(&options.rasterizer)?) } else { None };
    if let Some(t) = &gpu_tracer {
        tracing::info!("path tracing on {}", t.adapter_name());
    }
    let work_total: u64 = mine.iter().map(|s| frame_work(spec, s)).sum();
    let mut at = GenerateProgress {
        frames_done: summary.skipped,
        frames_total: summary.frames_in_shard,
        work_done: work_total - todo.iter().map(|s| frame_work(spec, s)).sum::<u64>(),
        work_total,
    };
    progress(at);
    for sample in todo {
        summary.discarded_samples += make_frame(&store, scene, sample, rasterizer.as_mut(), gpu_tracer.as_ref(), options.threads)?;
        summary.generated += 1;
        at.frames_done += 1;
        at.work_done += frame_work(spec, sample);
        progress(at);
    }
    summary.elapsed = start.elapsed();
    summary.disk_bytes = store.disk_bytes();
    Ok(summary)
}

/// What [`upgrade`] did.
#[derive(Clone, Debug, Default)]
pub struct UpgradeSummary {
    /// The format the dataset had.
    pub from_version: u32,
    /// Frames whose cached buffers were rasterized again.
    pub rasterized: u64,
    pub elapsed: Duration,
}

impl std::fmt::Display for UpgradeSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let now = crate::FORMAT_VERSION;
        if self.from_version == now {
            return write!(f, "already format {now}: nothing to do");
        }
        let seconds = self.elapsed.as_secs_f64();
        write!(f, "format {} -> {now}, buffers of {} frame(s) rasterized again in {seconds:.1} s, ground truth kept", self.from_version, self.rasterized)
    }
}

/// Bring a dataset of an older format to [`crate::FORMAT_VERSION`] in place: its ground truth
/// (the expensive part) is kept, the cached buffers of its finished frames are rasterized again
/// from `scene`, and the manifest is rewritten last, so an interrupted upgrade leaves the old
/// format, whose cached buffers are never read, and can be run again. Refused if `scene` is
/// not the scene the dataset was made from. `progress(done, total)` counts frames.
pub fn upgrade(dir: &Path, scene: &Scene, options: &RasterizerOptions, progress: &dyn Fn(u64, u64)) -> Result<UpgradeSummary> {
    let start = Instant::now();
    let existing = crate::store::read_manifest(dir)?;
    let mut summary = UpgradeSummary { from_version: existing.format_version, ..Default::default() };
    if existing.format_version == crate::FORMAT_VERSION {
        return Ok(summary);
    }
    let mut planned = DatasetManifest::plan(&existing.spec, scene);
    // The ground truth stays, and with it the revision that traced it.
    planned.tracer_revision = existing.tracer_revision;
    planned.ray_caster = existing.ray_caster.clone();
    // Frames traced before they were labelled stay unlabelled.
    planned.frames_labelled = existing.frames_labelled;
    let mut as_today = existing.clone();
    as_today.format_version = crate::FORMAT_VERSION;
    if let Some(why) = as_today.mismatch(&planned) {
        return Err(Error::bad_input(dir.join("manifest.json").display(), "dataset", format!("cannot upgrade it with this scene: {why}")));
    }
    let mut store = DatasetStore::create_or_resume(dir, &existing)?;
    if existing.spec.cache_buffers {
        // Frames not finished yet keep whatever they have; `generate` completes them.
        let finished: Vec<&SampleRecord> = existing.samples.iter().filter(|s| store.gt_path(s.index).is_file()).collect();
        let mut rasterizer = Rasterizer::new(options.clone())?;
        progress(0, finished.len() as u64);
        for (done, sample) in finished.iter().enumerate() {
            store_buffers(&store, &mut rasterizer, &scene.instantiate(&sample.values)?, sample)?;
            summary.rasterized += 1;
            progress(done as u64 + 1, finished.len() as u64);
        }
    }
    store.manifest = planned;
    store.write_manifest()?;
    summary.elapsed = start.elapsed();
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_parsing_and_membership() {
        let s = ShardSpec::parse("2/5").unwrap();
        assert!(s.contains(2) && s.contains(7) && !s.contains(3));
        for bad in ["5/5", "1", "a/3", "1/0", "-1/3"] {
            assert!(ShardSpec::parse(bad).is_err(), "{bad}");
        }
        // Every frame belongs to exactly one shard.
        for frame in 0..50 {
            assert_eq!((0..4).filter(|&i| ShardSpec { index: i, count: 4 }.contains(frame)).count(), 1);
        }
    }
}

/// A traced frame with NaN or infinite values is not stored: training and evaluation would
/// read it as ground truth, and every later run would trace it again identically.
fn refuse_non_finite(image: &glassbake_core::PlanarImage, scene: &str, index: u64) -> Result<()> {
    let bad = image.data().iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        return Err(Error::bad_input(
            scene,
            format!("frame {index:06}"),
            format!("the path tracer produced {bad} non-finite pixel values (radiance too large for f32?); the frame was not stored"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod non_finite_tests {
    use super::refuse_non_finite;
    use glassbake_core::PlanarImage;

    #[test]
    fn frames_with_non_finite_values_are_refused_naming_scene_frame_and_count() {
        let mut image = PlanarImage::new(2, 2, vec!["R".into(), "G".into(), "B".into()]);
        assert!(refuse_non_finite(&image, "scene", 3).is_ok());
        image.set(0, 1, 0, f32::INFINITY);
        image.set(2, 0, 1, f32::NAN);
        let err = refuse_non_finite(&image, "bright", 3).unwrap_err();
        let text = err.to_string();
        assert!(err.is_user_error() && text.contains("bright") && text.contains("frame 000003") && text.contains("2 non-finite"), "{text}");
    }
}
