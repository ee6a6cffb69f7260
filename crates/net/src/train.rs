//! The training loop shared by GlassNet, the baselines and the super-sampler: AdamW, the
//! warm-up + cosine learning-rate schedule, validation every N steps, checkpoints that resume
//! exactly after a kill, `train_log.csv`, and a NaN guard that keeps the last good checkpoint.
//!
//! All randomness is fixed by the seed: the weights are initialised from it, and the data
//! source derives each epoch's order and crops from (seed, epoch). A checkpoint therefore holds
//! the whole training state in the weights, the optimizer moments and (step, epoch, batch).

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamWConfig, GradientsAccumulator, GradientsParams, ModuleOptimizer};
use burn::prelude::*;
use burn::store::{BurnpackStore, ModuleSnapshot};
use serde::{Deserialize, Serialize};

use glassbake_core::checksum::{parse_sha256sum, sha256_hex, sha256sum_line};
use glassbake_core::{Error, Result};

use crate::batch::HostBatch;
use crate::config::TrainConfig;
use crate::loss::training_loss;
use crate::model_dir::{self, ModelFiles};

/// Where training batches come from. Implemented by the CLI over the dataset loader, and by
/// tests over synthetic frames.
pub trait TrainingData {
    /// Batches in one epoch of the training split.
    fn batches_per_epoch(&self) -> usize;
    /// The batches of `epoch` after the first `skip` (used to resume mid-epoch).
    fn epoch(&mut self, epoch: u64, skip: usize) -> Box<dyn Iterator<Item = Result<HostBatch>> + '_>;
    /// The validation batches (the same every call).
    fn validation(&mut self) -> Result<Vec<HostBatch>>;
}

/// A network the loop can train: built from its config, run on a host batch.
pub trait Trainable: Module + ModuleSnapshot + Clone + Sized + 'static {
    /// The network's prediction for a batch, [N, 3, H', W'] tone-mapped RGB.
    fn predict(&self, batch: &HostBatch, device: &Device) -> Tensor<4>;
    /// What the prediction is compared with.
    fn target(&self, batch: &HostBatch, device: &Device) -> Result<Tensor<4>>;
}

/// The position of a run, saved with each checkpoint.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct TrainState {
    /// Optimizer steps taken.
    pub step: u64,
    pub epoch: u64,
    /// Batches of `epoch` already consumed.
    pub batch_in_epoch: usize,
    pub seed: u64,
    pub last_validation_loss: Option<f64>,
    /// Wall time spent training before this checkpoint, summed over resumed runs.
    pub elapsed_seconds: f64,
}

/// What the caller hears after every step (for a progress bar).
#[derive(Clone, Debug)]
pub struct TrainEvent {
    pub step: u64,
    pub steps: u64,
    pub loss: f64,
    pub learning_rate: f64,
    pub validation_loss: Option<f64>,
    /// Set when the step ended in a checkpoint.
    pub checkpointed: bool,
}

#[derive(Clone, Debug)]
pub struct TrainSummary {
    pub steps: u64,
    pub resumed_from: Option<u64>,
    pub final_validation_loss: Option<f64>,
    pub elapsed_seconds: f64,
    pub already_done: bool,
}

/// Knobs that do not change what is trained.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Stop (as if killed) after this many steps, without a checkpoint: for resume tests.
    pub stop_after: Option<u64>,
    /// Stop once this step is trained, validated and checkpointed, to be continued later (by a
    /// run without it) from there; a run already past it returns at once.
    pub pause_at: Option<u64>,
    /// Further devices (of the same kind, with autodiff) that each take a share of every batch
    /// (data parallelism, [`batch_gradients`]); empty: the whole batch on the model's device.
    pub replicas: Vec<Device>,
}

const CHECKPOINT: &str = "checkpoint";
const LOG: &str = "train_log.csv";
/// `validation_psnr` (dB, the prediction clamped to [0, 1] as the tone map does, over all
/// validation pixels) came last so that logs written before it keep their columns.
const LOG_HEADER: &str = "step,epoch,learning_rate,train_loss,validation_loss,elapsed_s,validation_psnr";

/// Trains `model` into `files.dir`, resuming from its checkpoint when there is one.
/// `model` must live on an autodiff device; `device` is that device.
pub fn train<M>(
    mut model: M,
    files: &ModelFiles,
    config: &TrainConfig,
    device: &Device,
    data: &mut dyn TrainingData,
    options: &RunOptions,
    on_event: &mut dyn FnMut(&TrainEvent),
) -> Result<TrainSummary>
where
    M: Trainable,
{
    config.check("train config")?;
    // One run at a time in a model directory: two would interleave train_log.csv and
    // overwrite each other's checkpoints.
    let _writer_lock = glassbake_core::lock::lock_dir_for_writing(&files.dir, "--out", "model directory")?;
    let batches_per_epoch = data.batches_per_epoch();
    if batches_per_epoch == 0 {
        return Err(Error::bad_input(files.dir.display(), "dataset", "the training split has no frames"));
    }
    let mut optimizer = AdamWConfig::new().with_weight_decay(config.weight_decay as f32).init();
    let mut state = TrainState { seed: config.seed, ..TrainState::default() };
    let checkpoint_dir = files.dir.join(CHECKPOINT);
    let resumed_from = if let Some(found) = existing_checkpoint(&files.dir) {
        let (m, o, s) = load_checkpoint(model, optimizer, &found)?;
        (model, optimizer, state) = (m, o, s);
        truncate_log(&files.dir.join(LOG), state.step)?;
        Some(state.step)
    } else {
        write_log_header(&files.dir.join(LOG))?;
        None
    };
    if state.step >= config.steps {
        // Finished: the weights must be the checkpoint's (a run killed between the two
        // writes by an older glassbake, or a weights file replaced since, is repaired here).
        if model_dir::weights_step(&files.weights_path()) != Some(state.step) {
            model_dir::write_weights(&model.valid(), files, state.step)?;
        }
        return Ok(TrainSummary {
            steps: state.step,
            resumed_from,
            final_validation_loss: state.last_validation_loss,
            elapsed_seconds: state.elapsed_seconds,
            already_done: true,
        });
    }

    let validation = data.validation()?;
    let started = Instant::now();
    let elapsed_before = state.elapsed_seconds;
    let mut losses_since_log = Vec::new();
    'epochs: loop {
        let epoch = state.epoch;
        let skip = state.batch_in_epoch;
        let mut batches = data.epoch(epoch, skip);
        loop {
            let stop = options.stop_after.into_iter().chain(options.pause_at).any(|s| state.step >= s);
            if state.step >= config.steps || stop {
                break 'epochs;
            }
            let Some(batch) = batches.next() else { break };
            let batch = batch?;
            let learning_rate = config.learning_rate_at(state.step);
            let (loss_value, gradients) = batch_gradients(&model, &batch, device, &options.replicas, config.ssim_weight)?;
            if !loss_value.is_finite() {
                return Err(Error::Internal(format!(
                    "the training loss became {loss_value} at step {} (epoch {epoch}); stopped without saving, so {} keeps the last good checkpoint{}. Try a lower learning rate.",
                    state.step + 1,
                    files.dir.display(),
                    if checkpoint_dir.exists() { "" } else { " (there is none yet)" }
                )));
            }
            model = optimizer.step(learning_rate, model, gradients);
            state.step += 1;
            state.batch_in_epoch += 1;
            losses_since_log.push(loss_value);

            let mut validation_loss = None;
            let pausing = options.pause_at == Some(state.step);
            if state.step.is_multiple_of(config.validate_every) || state.step == config.steps || pausing {
                let scores = validate(&model, &validation, device, config.ssim_weight)?;
                validation_loss = scores.map(|s| s.loss);
                state.last_validation_loss = validation_loss;
                let train_loss = losses_since_log.iter().sum::<f64>() / losses_since_log.len().max(1) as f64;
                losses_since_log.clear();
                let seconds = elapsed_before + started.elapsed().as_secs_f64();
                append_log(&files.dir.join(LOG), &log_line(&state, learning_rate, train_loss, scores, seconds))?;
            }
            let checkpointed = state.step.is_multiple_of(config.checkpoint_every) || state.step == config.steps || pausing;
            if checkpointed {
                let seconds = elapsed_before + started.elapsed().as_secs_f64();
                save_step(&model, &optimizer, &state, batches_per_epoch, seconds, files)?;
            }
            on_event(&TrainEvent { step: state.step, steps: config.steps, loss: loss_value, learning_rate, validation_loss, checkpointed });
        }
        drop(batches);
        if state.batch_in_epoch == 0 {
            return Err(Error::Internal(format!("epoch {epoch} produced no batches")));
        }
        state.epoch += 1;
        state.batch_in_epoch = 0;
    }
    Ok(TrainSummary {
        steps: state.step,
        resumed_from,
        final_validation_loss: state.last_validation_loss,
        elapsed_seconds: elapsed_before + started.elapsed().as_secs_f64(),
        already_done: false,
    })
}

/// The training loss of `batch` and its gradients for `model`, on `device` or, with `replicas`,
/// the batch cut into a share of frames per device ([`HostBatch::split`]): each device runs the
/// model on its share, its loss weighted by the share's part of the frames (the loss is a mean
/// over frames, so the weighted losses add up to the whole batch's), and the gradients are
/// summed on `device`. Every device's work is queued before any is waited for, so GPUs run side
/// by side.
pub fn batch_gradients<M: Trainable>(model: &M, batch: &HostBatch, device: &Device, replicas: &[Device], ssim_weight: f64) -> Result<(f64, GradientsParams)> {
    if replicas.is_empty() {
        let loss = training_loss(model.predict(batch, device), model.target(batch, device)?, ssim_weight);
        let loss_value = loss.clone().into_scalar::<f32>() as f64;
        return Ok((loss_value, GradientsParams::from_grads(loss.backward(), model)));
    }
    let devices: Vec<&Device> = std::iter::once(device).chain(replicas).collect();
    let mut shares = Vec::new();
    for (shard, shard_device) in batch.split(devices.len()).iter().zip(devices) {
        // The model's weights as they are now, on that device (parameter ids kept).
        let replica = model.clone().fork(shard_device);
        let loss = training_loss(replica.predict(shard, shard_device), replica.target(shard, shard_device)?, ssim_weight);
        let loss = loss.mul_scalar(shard.frames as f64 / batch.frames as f64);
        let gradients = GradientsParams::from_grads(loss.clone().backward(), &replica);
        shares.push((loss.detach(), gradients, replica));
    }
    let mut sum = GradientsAccumulator::new();
    let mut loss_value = 0.0;
    for (loss, gradients, replica) in shares {
        loss_value += loss.into_scalar::<f32>() as f64;
        sum.accumulate(model, gradients.to_device(device, &replica));
    }
    Ok((loss_value, sum.grads()))
}

/// The log line of `state.step` (`step,epoch,learning_rate,train_loss,validation_loss,elapsed_s,validation_psnr`).
fn log_line(state: &TrainState, learning_rate: f64, train_loss: f64, scores: Option<ValidationScores>, seconds: f64) -> String {
    format!(
        "{},{},{:.6e},{:.6},{},{:.1},{}",
        state.step,
        state.epoch,
        learning_rate,
        train_loss,
        scores.map(|s| format!("{:.6}", s.loss)).unwrap_or_default(),
        seconds,
        scores.map(|s| format!("{:.3}", s.psnr)).unwrap_or_default(),
    )
}

/// Writes the weights after `state.step`, then the checkpoint to resume from.
fn save_step<M: Trainable>(
    model: &M,
    optimizer: &ModuleOptimizer,
    state: &TrainState,
    batches_per_epoch: usize,
    seconds: f64,
    files: &ModelFiles,
) -> Result<()> {
    // A checkpoint taken at the end of an epoch resumes at the next one.
    let mut saved = state.clone();
    if saved.batch_in_epoch >= batches_per_epoch {
        saved.epoch += 1;
        saved.batch_in_epoch = 0;
    }
    saved.elapsed_seconds = seconds;
    // The weights first: a checkpoint must never claim a step the weights file has not
    // reached (a kill between the two then only repeats the last steps).
    model_dir::write_weights(&model.valid(), files, state.step)?;
    save_checkpoint(model, optimizer, &saved, &files.dir)
}

/// How a network does on the validation frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValidationScores {
    /// Mean training loss over the frames.
    pub loss: f64,
    /// PSNR (dB) over all their pixels of the prediction clamped to [0, 1], what a user sees.
    pub psnr: f64,
}

/// Scores on the validation batches, on the model without autodiff.
pub fn validate<M: Trainable>(model: &M, batches: &[HostBatch], device: &Device, ssim_weight: f64) -> Result<Option<ValidationScores>> {
    if batches.is_empty() {
        return Ok(None);
    }
    let (model, device) = (model.valid(), device.clone().inner());
    let (mut total, mut squared_error, mut values) = (0.0, 0.0, 0usize);
    let mut frames = 0;
    for batch in batches {
        let prediction = model.predict(batch, &device);
        let target = model.target(batch, &device)?;
        values += prediction.dims().iter().product::<usize>();
        let difference = prediction.clone().clamp(0.0, 1.0) - target.clone();
        squared_error += (difference.clone() * difference).sum().into_scalar::<f32>() as f64;
        total += training_loss(prediction, target, ssim_weight).into_scalar::<f32>() as f64 * batch.frames as f64;
        frames += batch.frames;
    }
    let mse = squared_error / values.max(1) as f64;
    Ok(Some(ValidationScores { loss: total / frames as f64, psnr: 10.0 * (1.0 / mse.max(1e-12)).log10() }))
}

fn existing_checkpoint(dir: &Path) -> Option<PathBuf> {
    // A crash between the two renames of `save_checkpoint` leaves only `.old`.
    [CHECKPOINT, "checkpoint.old"].iter().map(|n| dir.join(n)).find(|p| p.join("state.json").is_file())
}

fn save_checkpoint<M: Module + ModuleSnapshot>(model: &M, optimizer: &ModuleOptimizer, state: &TrainState, dir: &Path) -> Result<()> {
    let tmp = dir.join("checkpoint.tmp");
    let _ = fs::remove_dir_all(&tmp);
    fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let mut store = BurnpackStore::from_file(tmp.join("model.bpk")).overwrite(true);
    model.save_into(&mut store).map_err(|e| Error::Internal(format!("saving the model checkpoint: {e}")))?;
    optimizer.save(tmp.join("optimizer.bpk")).map_err(|e| Error::Internal(format!("saving the optimizer state: {e:?}")))?;
    let json = serde_json::to_vec_pretty(state).expect("state serialises");
    fs::write(tmp.join("state.json"), json).map_err(|e| Error::io(&tmp.join("state.json"), e))?;
    // The checksums of what a resume trusts, so that a damaged file is named rather than
    // surfacing as a NaN loss steps later.
    let mut sums = String::new();
    for name in CHECKSUMMED {
        let path = tmp.join(name);
        sums.push_str(&sha256sum_line(&fs::read(&path).map_err(|e| Error::io(&path, e))?, name));
    }
    fs::write(tmp.join(CHECKSUMS), sums).map_err(|e| Error::io(&tmp.join(CHECKSUMS), e))?;
    let current = dir.join(CHECKPOINT);
    let old = dir.join("checkpoint.old");
    let _ = fs::remove_dir_all(&old);
    if current.exists() {
        fs::rename(&current, &old).map_err(|e| Error::io(&current, e))?;
    }
    fs::rename(&tmp, &current).map_err(|e| Error::io(&current, e))?;
    let _ = fs::remove_dir_all(&old);
    Ok(())
}

/// The checkpoint files whose SHA-256 `save_checkpoint` records in [`CHECKSUMS`].
const CHECKSUMMED: [&str; 3] = ["model.bpk", "optimizer.bpk", "state.json"];
const CHECKSUMS: &str = "sha256";

/// Compares a checkpoint's files with the checksums recorded when it was written (checkpoints
/// from before checksums were recorded have none, and are trusted as before).
fn verify_checkpoint(dir: &Path) -> Result<()> {
    let sums = dir.join(CHECKSUMS);
    let text = match fs::read_to_string(&sums) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(&sums, e)),
    };
    for (digest, name) in parse_sha256sum(&text) {
        let path = dir.join(&name);
        let bytes = fs::read(&path).map_err(|e| Error::io(&path, e))?;
        if sha256_hex(&bytes) != digest {
            return Err(Error::bad_input(
                path.display(),
                "checkpoint",
                format!(
                    "changed since training wrote it (its SHA-256 differs from the one in {}): a damaged checkpoint; \
                     remove {} to train from the start",
                    sums.display(),
                    dir.display()
                ),
            ));
        }
    }
    Ok(())
}

fn load_checkpoint<M: Module + ModuleSnapshot>(mut model: M, optimizer: ModuleOptimizer, dir: &Path) -> Result<(M, ModuleOptimizer, TrainState)> {
    verify_checkpoint(dir)?;
    let state_path = dir.join("state.json");
    let text = fs::read_to_string(&state_path).map_err(|e| Error::io(&state_path, e))?;
    let state: TrainState = serde_json::from_str(&text).map_err(|e| Error::bad_input(state_path.display(), "state", e.to_string()))?;
    let mut store = BurnpackStore::from_file(dir.join("model.bpk"));
    let applied = model.load_from(&mut store).map_err(|e| Error::bad_input(dir.join("model.bpk").display(), "weights", e.to_string()))?;
    if !applied.missing.is_empty() || !applied.errors.is_empty() {
        return Err(Error::bad_input(
            dir.join("model.bpk").display(),
            "weights",
            format!("does not fit this network ({} missing, {} errors)", applied.missing.len(), applied.errors.len()),
        ));
    }
    let optimizer =
        optimizer.load(dir.join("optimizer.bpk")).map_err(|e| Error::bad_input(dir.join("optimizer.bpk").display(), "optimizer", format!("{e:?}")))?;
    Ok((model, optimizer, state))
}

fn write_log_header(path: &Path) -> Result<()> {
    fs::write(path, format!("{LOG_HEADER}\n")).map_err(|e| Error::io(path, e))
}

fn append_log(path: &Path, line: &str) -> Result<()> {
    let mut file = fs::OpenOptions::new().append(true).create(true).open(path).map_err(|e| Error::io(path, e))?;
    writeln!(file, "{line}").map_err(|e| Error::io(path, e))
}

/// The last validation scores a model directory's training log holds, with their step: what
/// its weights score once training has finished (the last step is always validated). `None`
/// when no step was validated (no validation frames) or the log predates `validation_psnr`.
pub fn logged_validation(model_dir: &Path) -> Result<Option<(u64, ValidationScores)>> {
    Ok(logged_validations(model_dir)?.pop())
}

/// Every validated step's scores in a model directory's training log, in step order (empty
/// when none was validated, or the log predates `validation_psnr`).
pub fn logged_validations(model_dir: &Path) -> Result<Vec<(u64, ValidationScores)>> {
    let path = model_dir.join(LOG);
    let text = fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name);
    let (Some(step_at), Some(loss_at), Some(psnr_at)) = (column("step"), column("validation_loss"), column("validation_psnr")) else {
        return Ok(Vec::new());
    };
    let bad_row = |row: &str| Error::bad_input(path.display(), "validation_psnr", format!("a row that is not a training log's: {row:?}"));
    let mut scores = Vec::new();
    for row in lines {
        let fields: Vec<&str> = row.split(',').collect();
        let field = |at: usize| fields.get(at).copied().unwrap_or_default();
        if field(psnr_at).is_empty() {
            continue;
        }
        let step = field(step_at).parse::<u64>().map_err(|_| bad_row(row))?;
        let loss = field(loss_at).parse::<f64>().map_err(|_| bad_row(row))?;
        let psnr = field(psnr_at).parse::<f64>().map_err(|_| bad_row(row))?;
        scores.push((step, ValidationScores { loss, psnr }));
    }
    Ok(scores)
}

/// Drops log rows written after the checkpoint a run resumes from. A header that today's
/// extends (a log from before a column was added) becomes today's: old rows keep their cells.
fn truncate_log(path: &Path, step: u64) -> Result<()> {
    let Ok(text) = fs::read_to_string(path) else {
        return write_log_header(path);
    };
    let kept: Vec<&str> = text
        .lines()
        .enumerate()
        .map(|(i, line)| if i == 0 && LOG_HEADER.starts_with(line) { LOG_HEADER } else { line })
        .filter(|line| match line.split(',').next().and_then(|s| s.parse::<u64>().ok()) {
            Some(row_step) => row_step <= step,
            None => true,
        })
        .collect();
    glassbake_core::image::write_bytes_atomically(path, format!("{}\n", kept.join("\n")).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn logged(text: &str) -> Result<Option<(u64, ValidationScores)>> {
        let dir = tempfile::tempdir().unwrap();
        fs::write(dir.path().join(LOG), text).unwrap();
        logged_validation(dir.path())
    }

    #[test]
    fn the_last_validated_row_is_read_and_rows_without_validation_are_skipped() {
        let log = format!("{LOG_HEADER}\n10,0,1e-3,0.5,0.45,1.0,20.125\n20,0,1e-3,0.4,0.35,2.0,21.5\n25,1,1e-3,0.3,,2.5,\n");
        assert_eq!(logged(&log).unwrap(), Some((20, ValidationScores { loss: 0.35, psnr: 21.5 })));
        let no_validation = format!("{LOG_HEADER}\n10,0,1e-3,0.5,,1.0,\n");
        assert_eq!(logged(&no_validation).unwrap(), None);
        // A log from before validation_psnr was written has nothing to choose by.
        assert_eq!(logged("step,epoch,learning_rate,train_loss,validation_loss,elapsed_s\n10,0,1e-3,0.5,0.45,1.0\n").unwrap(), None);
    }

    #[test]
    fn a_damaged_row_is_refused_naming_the_log() {
        let error = logged(&format!("{LOG_HEADER}\n10,0,1e-3,0.5,0.45,1.0,twenty\n")).unwrap_err().to_string();
        assert!(error.contains(LOG) && error.contains("twenty"), "{error}");
    }
}
