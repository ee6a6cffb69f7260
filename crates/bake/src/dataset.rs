//! A scene's dataset made (or completed) with progress: `glassbake dataset` and a bake's first
//! stage.

use std::path::PathBuf;
use std::time::Duration;

use glassbake_core::Result;
use glassbake_dataset::store::human_bytes;
use glassbake_dataset::{generate, DatasetSpec, DatasetStore, GenerateOptions, GenerateProgress, GenerateSummary, ShardSpec};
use glassbake_scene::load_scene;
use glassbake_trace::Estimator;
use indicatif::ProgressStyle;

use crate::Progress;

/// A dataset to make: what it holds (`spec`) and how this run makes it.
#[derive(Clone, Debug)]
pub struct DatasetRequest {
    /// What the dataset holds. Its estimator is a new dataset's: a dataset being continued
    /// keeps the one it was started with, unless `estimator` names one.
    pub spec: DatasetSpec,
    pub out: PathBuf,
    /// The estimator asked for, for a new dataset and a continued one alike.
    pub estimator: Option<Estimator>,
    /// Make only this shard's frames.
    pub shard: ShardSpec,
    /// Path-tracer threads (`None`: all cores).
    pub threads: Option<usize>,
}

impl DatasetRequest {
    /// `spec` into `out`, every frame, on all cores.
    pub fn new(spec: DatasetSpec, out: impl Into<PathBuf>) -> DatasetRequest {
        DatasetRequest { spec, out: out.into(), estimator: None, shard: ShardSpec::ALL, threads: None }
    }

    /// The spec this run traces: its estimator resolved.
    pub fn resolved_spec(&self) -> DatasetSpec {
        let continued = || DatasetStore::open(&self.out).ok().map(|existing| existing.manifest.spec.estimator);
        let estimator = self.estimator.or_else(continued).unwrap_or(self.spec.estimator);
        DatasetSpec { estimator, ..self.spec.clone() }
    }
}

/// Makes (or completes) the dataset of `request`, counting samples traced on the progress
/// bar. Returns what was done.
pub fn make_dataset(request: &DatasetRequest, progress: &Progress) -> Result<GenerateSummary> {
    let scene = load_scene(&request.spec.scene)?;
    let spec = request.resolved_spec();
    let options = GenerateOptions { shard: request.shard, threads: request.threads, ..Default::default() };
    let bar = progress.bar();
    bar.set_length(0);
    bar.set_position(0);
    // The bar counts samples per pixel traced (test frames cost more), the message frames.
    bar.set_style(
        ProgressStyle::with_template("{spinner} frames {msg} [{elapsed_precise}] {wide_bar} ETA {eta}").expect("static template").progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(250));
    let on_progress = |p: GenerateProgress| {
        bar.set_length(p.work_total);
        bar.set_message(format!("{}/{}", p.frames_done, p.frames_total));
        if bar.position() == 0 && p.work_done > 0 {
            // Frames already complete do not count towards the ETA.
            bar.reset_eta();
        }
        bar.set_position(p.work_done);
    };
    let summary = generate(&scene, &spec, &request.out, &options, &on_progress)?;
    let secs = summary.elapsed.as_secs_f64();
    progress.say(&format!(
        "dataset {}: {} frame(s) made, {} already complete{}, in {:.1} s{}",
        request.out.display(),
        summary.generated,
        summary.skipped,
        if summary.redone > 0 { format!(" ({} corrupt, redone)", summary.redone) } else { String::new() },
        secs,
        if summary.generated > 0 { format!(" ({:.0} frames/hour)", summary.generated as f64 * 3600.0 / secs) } else { String::new() },
    ));
    if request.shard != ShardSpec::ALL {
        progress.say(&format!("  shard {}/{}: {} frame(s) of this shard", request.shard.index, request.shard.count, summary.frames_in_shard));
    }
    if summary.discarded_samples > 0 {
        progress.say(&format!("  {} NaN/inf path sample(s) discarded", summary.discarded_samples));
    }
    progress.say(&format!("  disk {} ({} per frame)", human_bytes(summary.disk_bytes), human_bytes(summary.disk_bytes / summary.frames_in_shard.max(1))));
    Ok(summary)
}
