//! The training loop: a tiny model overfits one frame, a killed run resumes to the same
//! weights as an uninterrupted one (and so does a paused one continued), a NaN loss stops with
//! the last good checkpoint kept.

mod common;

use burn::optim::GradientsParams;
use burn::prelude::*;
use glassbake_core::Result;
use glassbake_net::model_dir::{weights_step, ModelConfig, ModelFiles, Network, FORMAT_VERSION};
use glassbake_net::train::{batch_gradients, logged_validations};
use glassbake_net::{
    burn, train, with_new_model, GlassNet, ModelKind, ModelTask, NetConfig, RunOptions, SceneModel, TrainConfig, TrainSummary, Trainable, TrainingData,
};

fn files(dir: &std::path::Path, net: &NetConfig, train: &TrainConfig) -> ModelFiles {
    ModelFiles::prepare(
        dir,
        ModelConfig { format_version: FORMAT_VERSION, network: Network::Glassnet(net.clone()), train: train.clone(), data: common::synthetic_source() },
    )
    .unwrap()
}

/// The weights in `run`'s folder are bit for bit those in `uninterrupted`'s, tensor by tensor
/// (the file's metadata order is not fixed, so its bytes can differ).
fn assert_same_weights(uninterrupted: &ModelFiles, run: &ModelFiles, how: &str) {
    let (a, b) = (std::fs::read(uninterrupted.weights_path()).unwrap(), std::fs::read(run.weights_path()).unwrap());
    let (a, b) = (safetensors::SafeTensors::deserialize(&a).unwrap(), safetensors::SafeTensors::deserialize(&b).unwrap());
    assert_eq!(a.len(), b.len());
    for name in a.names() {
        assert!(a.tensor(name).unwrap().data() == b.tensor(name).unwrap().data(), "{name}: the {how} run's weights differ from the uninterrupted run's");
    }
}

fn model(net: &NetConfig, seed: u64) -> (GlassNet, Device) {
    let device = Device::flex();
    device.seed(seed);
    let device = device.autodiff();
    (GlassNet::new(net, seed, &device).unwrap(), device)
}

/// Trains a new network of `net`'s kind, weights drawn from `seed`.
fn train_new(net: &NetConfig, seed: u64, files: &ModelFiles, config: &TrainConfig, data: &mut dyn TrainingData, losses: &mut Vec<f64>) -> Result<TrainSummary> {
    struct Train<'a> {
        files: &'a ModelFiles,
        config: &'a TrainConfig,
        device: &'a Device,
        data: &'a mut dyn TrainingData,
        losses: &'a mut Vec<f64>,
    }
    impl ModelTask for Train<'_> {
        type Output = Result<TrainSummary>;
        fn run<M: SceneModel + Trainable>(self, model: M) -> Self::Output {
            train(model, self.files, self.config, self.device, self.data, &RunOptions::default(), &mut |e| self.losses.push(e.loss))
        }
    }
    let device = Device::flex();
    device.seed(seed);
    let device = device.autodiff();
    with_new_model(net, seed, &device, Train { files, config, device: &device, data, losses }).unwrap()
}

/// Trains a tiny `kind` (reading through buffers or not) for 500 steps on one frame; returns
/// the first loss and the mean of the last ten.
fn overfit_one_frame(kind: ModelKind, objects: usize, through: bool) -> (f64, f64) {
    let net = NetConfig { through, ..common::small_net(kind, 1, objects) };
    let config = TrainConfig {
        steps: 500,
        batch_size: 1,
        learning_rate: 1e-2,
        warmup_steps: 10,
        validate_every: 500,
        checkpoint_every: 500,
        ..common::small_training()
    };
    let mut data = common::SyntheticData { frames: vec![common::frame(42, 16, objects, 1)], batch_size: 1, seed: 0, poison_from_epoch: None };
    let dir = tempfile::tempdir().unwrap();
    let files = files(dir.path(), &net, &config);
    let mut losses = Vec::new();
    train_new(&net, 1, &files, &config, &mut data, &mut losses).unwrap();
    (losses[0], losses[losses.len() - 10..].iter().sum::<f64>() / 10.0)
}

#[test]
fn a_tiny_model_overfits_one_frame() {
    let (first, last) = overfit_one_frame(ModelKind::Glassnet, 2, false);
    assert!(last * 10.0 < first, "loss went from {first} to {last}: not down 10x");
}

/// The synthetic frame's ground truth does not depend on the through buffers, whose 17
/// channels per object (random here) h must first learn to ignore: down 8.8x where the
/// network without them goes down more than 10x.
#[test]
fn a_tiny_model_reading_through_buffers_overfits_one_frame() {
    let (first, last) = overfit_one_frame(ModelKind::Glassnet, 2, true);
    assert!(last * 5.0 < first, "loss went from {first} to {last}: not down 5x");
}

#[test]
fn a_tiny_pixelgen_overfits_one_frame() {
    let (first, last) = overfit_one_frame(ModelKind::Pixelgen, 0, false);
    assert!(last * 5.0 < first, "loss went from {first} to {last}: not down 5x");
}

#[test]
fn a_killed_run_resumes_to_the_weights_of_an_uninterrupted_one() {
    let net = common::small_net(ModelKind::Glassnet, 1, 2);
    let config = TrainConfig { steps: 12, batch_size: 2, checkpoint_every: 4, validate_every: 3, ..common::small_training() };
    let data = || common::SyntheticData { frames: (0..5).map(|i| common::frame(i, 16, 2, 1)).collect(), batch_size: 2, seed: 3, poison_from_epoch: None };

    let straight = tempfile::tempdir().unwrap();
    let f = files(straight.path(), &net, &config);
    let (m, d) = model(&net, 7);
    train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();

    // Killed after step 6 (between the checkpoints at 4 and 8), then started again: the second
    // run resumes from step 4, mid-epoch (3 batches per epoch), and redoes steps 5 and 6.
    let killed = tempfile::tempdir().unwrap();
    let f2 = files(killed.path(), &net, &config);
    let (m, d) = model(&net, 7);
    train(m, &f2, &config, &d, &mut data(), &RunOptions { stop_after: Some(6), ..RunOptions::default() }, &mut |_| {}).unwrap();
    let (m, d) = model(&net, 99); // the checkpoint, not the seed, decides the weights now
    let summary = train(m, &f2, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();
    assert_eq!(summary.resumed_from, Some(4));
    assert_eq!(summary.steps, 12);

    assert_same_weights(&f, &f2, "resumed");
    let log = |dir: &std::path::Path| std::fs::read_to_string(dir.join("train_log.csv")).unwrap();
    let steps = |text: String| text.lines().skip(1).map(|l| l.split(',').next().unwrap().to_string()).collect::<Vec<_>>();
    assert_eq!(steps(log(straight.path())), steps(log(killed.path())), "the resumed log must not repeat or skip rows");

    // A finished run is not trained again.
    let (m, d) = model(&net, 7);
    assert!(train(m, &f2, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap().already_done);
}

#[test]
fn a_paused_run_is_validated_and_checkpointed_there_and_continues_to_the_uninterrupted_weights() {
    let net = common::small_net(ModelKind::Glassnet, 1, 2);
    // Step 5 is neither a validation (every 3) nor a checkpoint (every 4) step.
    let config = TrainConfig { steps: 9, batch_size: 2, checkpoint_every: 4, validate_every: 3, ..common::small_training() };
    let data = || common::SyntheticData { frames: (0..5).map(|i| common::frame(i, 16, 2, 1)).collect(), batch_size: 2, seed: 3, poison_from_epoch: None };
    let straight = tempfile::tempdir().unwrap();
    let f = files(straight.path(), &net, &config);
    let (m, d) = model(&net, 7);
    train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();

    let paused = tempfile::tempdir().unwrap();
    let f2 = files(paused.path(), &net, &config);
    let pause = RunOptions { pause_at: Some(5), ..RunOptions::default() };
    let (m, d) = model(&net, 7);
    let summary = train(m, &f2, &config, &d, &mut data(), &pause, &mut |_| {}).unwrap();
    assert_eq!((summary.steps, summary.already_done), (5, false));
    assert_eq!(weights_step(&f2.weights_path()), Some(5));
    let validated: Vec<u64> = logged_validations(paused.path()).unwrap().iter().map(|(step, _)| *step).collect();
    assert_eq!(validated, [3, 5]);
    // Paused again, it trains nothing; then it continues from step 5, not from 4.
    let (m, d) = model(&net, 99);
    assert_eq!(train(m, &f2, &config, &d, &mut data(), &pause, &mut |_| {}).unwrap().steps, 5);
    let (m, d) = model(&net, 99);
    let summary = train(m, &f2, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();
    assert_eq!((summary.resumed_from, summary.steps), (Some(5), 9));
    assert_same_weights(&f, &f2, "paused");
    // The pause's validation is a row of its own: the uninterrupted log plus step 5.
    let validated: Vec<u64> = logged_validations(paused.path()).unwrap().iter().map(|(step, _)| *step).collect();
    assert_eq!(validated, [3, 5, 6, 9]);
}

#[test]
fn a_nan_loss_stops_with_a_clear_message_and_keeps_the_last_checkpoint() {
    let net = common::small_net(ModelKind::Naive, 1, 1);
    let config = TrainConfig { steps: 20, batch_size: 1, checkpoint_every: 2, validate_every: 2, ..common::small_training() };
    let mut data = common::SyntheticData { frames: (0..3).map(|i| common::frame(i, 16, 1, 1)).collect(), batch_size: 1, seed: 0, poison_from_epoch: Some(1) };
    let dir = tempfile::tempdir().unwrap();
    let f = files(dir.path(), &net, &config);
    let err = train_new(&net, 1, &f, &config, &mut data, &mut Vec::new()).unwrap_err();
    let message = err.to_string();
    assert!(message.contains("NaN") && message.contains("step 4") && message.contains("last good checkpoint"), "{message}");
    let state: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("checkpoint/state.json")).unwrap()).unwrap();
    assert_eq!(state["step"], 2, "the checkpoint of step 2 (the last before the NaN) is kept");
    assert!(f.weights_path().is_file());
}

#[test]
fn a_damaged_checkpoint_is_named_not_trained_on() {
    let net = common::small_net(ModelKind::Glassnet, 1, 2);
    let config = TrainConfig { steps: 8, batch_size: 2, checkpoint_every: 4, validate_every: 4, ..common::small_training() };
    let data = || common::SyntheticData { frames: (0..4).map(|i| common::frame(i, 16, 2, 1)).collect(), batch_size: 2, seed: 3, poison_from_epoch: None };
    let dir = tempfile::tempdir().unwrap();
    let f = files(dir.path(), &net, &config);
    let (m, d) = model(&net, 7);
    train(m, &f, &config, &d, &mut data(), &RunOptions { stop_after: Some(4), ..RunOptions::default() }, &mut |_| {}).unwrap();

    // One bit of the optimizer's moments flipped (bit rot): resuming on it would train on
    // garbage. The resume refuses, naming the file, and leaves everything as it was.
    let optimizer = dir.path().join("checkpoint/optimizer.bpk");
    let good = std::fs::read(&optimizer).unwrap();
    let mut bad = good.clone();
    let at = bad.len() - 64;
    bad[at] ^= 0x40;
    std::fs::write(&optimizer, &bad).unwrap();
    let (m, d) = model(&net, 7);
    let err = train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap_err();
    match &err {
        glassbake_core::Error::BadInput { file, message, .. } => {
            assert!(file.ends_with("optimizer.bpk") && message.contains("SHA-256"), "{err}");
        }
        other => panic!("expected bad input, got {other}"),
    }
    assert_eq!(std::fs::read(&optimizer).unwrap(), bad);

    std::fs::write(&optimizer, &good).unwrap();
    let (m, d) = model(&net, 7);
    let summary = train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();
    assert_eq!((summary.resumed_from, summary.steps), (Some(4), 8));
}

#[test]
fn a_directory_holding_a_different_run_is_refused() {
    let net = common::small_net(ModelKind::Glassnet, 1, 2);
    let config = common::small_training();
    let dir = tempfile::tempdir().unwrap();
    files(dir.path(), &net, &config);
    let other = TrainConfig { learning_rate: 0.5, ..config };
    let err = ModelFiles::prepare(
        dir.path(),
        ModelConfig { format_version: FORMAT_VERSION, network: Network::Glassnet(net), train: other, data: common::synthetic_source() },
    )
    .unwrap_err();
    assert!(err.to_string().contains("config.json") && err.to_string().contains("train"), "{err}");
}

#[test]
fn validation_psnr_is_that_of_the_clamped_prediction_over_all_pixels() {
    use glassbake_net::train::{validate, Trainable};
    let net = common::small_net(ModelKind::Glassnet, 1, 2);
    let (model, device) = model(&net, 3);
    let frames: Vec<_> = (0..3).map(|i| common::frame(i, 16, 2, 1)).collect();
    let batches = vec![common::batch(&frames[..2]), common::batch(&frames[2..])];
    let scores = validate(&model, &batches, &device, 1.0).unwrap().unwrap();
    // The same figure on the host, in f64.
    let (valid, inner) = (model.valid(), device.clone().inner());
    let (mut squared, mut count) = (0.0f64, 0usize);
    for batch in &batches {
        let prediction = valid.predict(batch, &inner).into_data().try_to_vec::<f32>().unwrap();
        let target = valid.target(batch, &inner).unwrap().into_data().try_to_vec::<f32>().unwrap();
        for (p, t) in prediction.iter().zip(&target) {
            squared += (p.clamp(0.0, 1.0) as f64 - *t as f64).powi(2);
            count += 1;
        }
    }
    let expected = 10.0 * (count as f64 / squared).log10();
    assert!((scores.psnr - expected).abs() < 1e-3, "{} vs {expected}", scores.psnr);
    assert!(scores.loss.is_finite() && scores.loss > 0.0);
}

/// A finished run whose weights file is not the final step's (a kill between writing the
/// checkpoint and the weights, by a glassbake that wrote them in that order, or a file
/// replaced since) is repaired when `train` runs again, instead of "nothing to do" leaving
/// eval and render on stale weights for good.
#[test]
fn a_finished_run_repairs_weights_that_are_not_its_final_steps() {
    let net = common::small_net(ModelKind::Glassnet, 1, 1);
    let config = TrainConfig { steps: 8, batch_size: 1, checkpoint_every: 4, validate_every: 4, ..common::small_training() };
    let data = || common::SyntheticData { frames: (0..3).map(|i| common::frame(i, 16, 1, 1)).collect(), batch_size: 1, seed: 0, poison_from_epoch: None };
    let finished = tempfile::tempdir().unwrap();
    let f = files(finished.path(), &net, &config);
    let (m, d) = model(&net, 5);
    train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();
    assert_eq!(weights_step(&f.weights_path()), Some(8));
    let final_weights = std::fs::read(f.weights_path()).unwrap();

    // The stale state: the same run's weights from step 4, the checkpoint saying step 8.
    let early = tempfile::tempdir().unwrap();
    let f4 = files(early.path(), &net, &config);
    let (m, d) = model(&net, 5);
    train(m, &f4, &config, &d, &mut data(), &RunOptions { stop_after: Some(4), ..RunOptions::default() }, &mut |_| {}).unwrap();
    assert_eq!(weights_step(&f4.weights_path()), Some(4));
    std::fs::copy(f4.weights_path(), f.weights_path()).unwrap();

    let (m, d) = model(&net, 99);
    let summary = train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();
    assert!(summary.already_done);
    assert_eq!(weights_step(&f.weights_path()), Some(8), "the stale weights were left in place");
    let (a, b) = (std::fs::read(f.weights_path()).unwrap(), final_weights);
    let (a, b) = (safetensors::SafeTensors::deserialize(&a).unwrap(), safetensors::SafeTensors::deserialize(&b).unwrap());
    for name in b.names() {
        assert!(a.tensor(name).unwrap().data() == b.tensor(name).unwrap().data(), "{name}: not the final step's weights");
    }
    // Nothing to repair: a second run leaves the file alone.
    let written = std::fs::metadata(f.weights_path()).unwrap().modified().unwrap();
    let (m, d) = model(&net, 99);
    train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();
    assert_eq!(std::fs::metadata(f.weights_path()).unwrap().modified().unwrap(), written);
}

/// Two runs never train into one model directory at once: the second is refused while the
/// first holds the directory (as a concurrent process would), and a run on another
/// dataset's samples (another sample seed) is refused as a different run.
#[test]
fn a_model_directory_has_one_writer_and_one_dataset() {
    let net = common::small_net(ModelKind::Glassnet, 1, 1);
    let config = TrainConfig { steps: 2, batch_size: 1, checkpoint_every: 2, validate_every: 2, ..common::small_training() };
    let data = || common::SyntheticData { frames: (0..2).map(|i| common::frame(i, 16, 1, 1)).collect(), batch_size: 1, seed: 0, poison_from_epoch: None };
    let dir = tempfile::tempdir().unwrap();
    let f = files(dir.path(), &net, &config);
    let held = glassbake_core::lock::lock_dir_for_writing(dir.path(), "--out", "model directory").unwrap();
    let (m, d) = model(&net, 5);
    let err = train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap_err();
    assert!(err.is_user_error() && err.to_string().contains("another glassbake process"), "{err}");
    assert!(!dir.path().join("train_log.csv").exists(), "the refused run wrote its log");
    drop(held);
    let (m, d) = model(&net, 5);
    train(m, &f, &config, &d, &mut data(), &RunOptions::default(), &mut |_| {}).unwrap();

    let mut other = f.config.clone();
    other.data.sample_seed = Some(7);
    let mut recorded = f.config.clone();
    recorded.data.sample_seed = Some(1);
    let seeded = tempfile::tempdir().unwrap();
    ModelFiles::prepare(seeded.path(), recorded).unwrap();
    let err = ModelFiles::prepare(seeded.path(), other).unwrap_err();
    assert!(err.is_user_error() && err.to_string().contains("data"), "{err}");
}

/// The largest difference between two sets of gradients of `model`'s parameters, and the
/// largest gradient, over every parameter.
fn gradient_difference(model: &impl burn::module::Module, a: &GradientsParams, b: &GradientsParams) -> (f32, f32) {
    struct Compare<'a> {
        a: &'a GradientsParams,
        b: &'a GradientsParams,
        difference: f32,
        largest: f32,
        compared: usize,
    }
    impl burn::module::ModuleVisitor for Compare<'_> {
        fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
            let values = |g: &GradientsParams| g.get::<D>(param.id).expect("every parameter has a gradient").into_data().try_to_vec::<f32>().unwrap();
            let (a, b) = (values(self.a), values(self.b));
            for (x, y) in a.iter().zip(&b) {
                self.difference = self.difference.max((x - y).abs());
                self.largest = self.largest.max(x.abs());
            }
            self.compared += 1;
        }
    }
    let mut compare = Compare { a, b, difference: 0.0, largest: 0.0, compared: 0 };
    model.visit(&mut compare);
    assert!(compare.compared > 10, "compared {} parameters", compare.compared);
    (compare.difference, compare.largest)
}

/// A batch cut across devices (here 2 frames on the first, 1 on the second, and 1 + 1 + 1 on
/// three) gives the whole batch's loss and gradients: each share's loss weighted by its frames.
fn shares_give_the_whole_batchs_gradients(device: &Device, replicas: &[Device]) {
    let net = common::small_net(ModelKind::Glassnet, 1, 2);
    let model = GlassNet::new(&net, 3, device).unwrap();
    let frames: Vec<_> = (0..3).map(|i| common::frame(20 + i, 16, 2, 1)).collect();
    let batch = common::batch(&frames);
    let (whole_loss, whole) = batch_gradients(&model, &batch, device, &[], 1.0).unwrap();
    for count in 1..=replicas.len() {
        let (loss, shared) = batch_gradients(&model, &batch, device, &replicas[..count], 1.0).unwrap();
        assert!((loss - whole_loss).abs() <= 1e-6 * whole_loss, "{} devices: loss {loss} against {whole_loss}", count + 1);
        let (difference, largest) = gradient_difference(&model, &whole, &shared);
        // f32 sums in another order: a few ulps of the largest gradient.
        assert!(difference <= 1e-5 * largest, "{} devices: gradients differ by {difference} (largest {largest})", count + 1);
    }
}

#[test]
fn a_batch_shared_across_devices_gives_the_whole_batchs_gradients_on_the_cpu() {
    let device = Device::flex().autodiff();
    shares_give_the_whole_batchs_gradients(&device, &[device.clone(), device.clone()]);
}

/// Two wgpu devices on one adapter (lavapipe's, in CI): the default device and the CPU-kind one.
#[test]
fn a_batch_shared_across_two_wgpu_devices_gives_the_whole_batchs_gradients() {
    if !common::wgpu_adapter_exists() {
        return;
    }
    let first = Device::wgpu(Default::default()).autodiff();
    let second = Device::wgpu(burn::tensor::DeviceKind::Cpu).autodiff();
    shares_give_the_whole_batchs_gradients(&first, &[second]);
}

/// Training with a replica device takes the same steps as training on one: the loss and the
/// weights after a few steps match the single-device run's.
#[test]
fn training_on_two_devices_follows_training_on_one() {
    let net = common::small_net(ModelKind::Glassnet, 1, 2);
    let config = TrainConfig { steps: 4, batch_size: 3, checkpoint_every: 4, validate_every: 4, ..common::small_training() };
    let data = || common::SyntheticData { frames: (0..6).map(|i| common::frame(i, 16, 2, 1)).collect(), batch_size: 3, seed: 2, poison_from_epoch: None };
    let run = |replicas: Vec<Device>| {
        let dir = tempfile::tempdir().unwrap();
        let f = files(dir.path(), &net, &config);
        let (m, d) = model(&net, 5);
        let mut losses = Vec::new();
        train(m, &f, &config, &d, &mut data(), &RunOptions { replicas, ..RunOptions::default() }, &mut |e| losses.push(e.loss)).unwrap();
        (losses, std::fs::read(f.weights_path()).unwrap())
    };
    let (one_losses, one) = run(Vec::new());
    let (two_losses, two) = run(vec![Device::flex().autodiff()]);
    for (step, (a, b)) in one_losses.iter().zip(&two_losses).enumerate() {
        assert!((a - b).abs() <= 1e-5 * a, "step {}: loss {b} on two devices, {a} on one", step + 1);
    }
    let (one, two) = (safetensors::SafeTensors::deserialize(&one).unwrap(), safetensors::SafeTensors::deserialize(&two).unwrap());
    for name in one.names() {
        let values = |t: &safetensors::SafeTensors| -> Vec<f32> { bytemuck::cast_slice(t.tensor(name).unwrap().data()).to_vec() };
        let largest = values(&one).iter().zip(values(&two)).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        // 4 AdamW steps at the test's learning rate (1e-3, warming up) move a weight by at
        // most 4e-3; the two runs must agree far more closely.
        assert!(largest <= 1e-4, "{name}: weights differ by {largest} after 4 steps");
    }
}

/// A training batch leaves out the objects none of its frames show (`HostBatch::shows_object`):
/// with GlassNet's terms masked by coverage such an object adds exactly 0, so the loss and
/// every gradient are bit for bit those of the whole network. Without the mask the same object
/// does change the image, so the equality is the mask's doing, not the data's.
#[test]
fn objects_a_batch_does_not_show_are_left_out_without_changing_a_bit() {
    let device = Device::flex().autodiff();
    let config = common::small_net(ModelKind::Glassnet, 1, 3);
    assert!(config.terms_masked_by_coverage);
    let model = glassbake_net::init::initialize(GlassNet::new(&config, 8, &device).unwrap(), 8);
    assert!(model.unseen_objects_add_nothing());
    // Object 1 unseen, then none of the three (every parameter, h's too, must still get its
    // gradient: `gradient_difference` asks each for one).
    for unseen in [vec![1], vec![0, 1, 2]] {
        let mut frames: Vec<_> = (0..2).map(|i| common::frame(60 + i, 16, 3, 1)).collect();
        for frame in &mut frames {
            // They cover nothing; their other channels stay as random as the others'.
            for &k in &unseen {
                frame.transparent[k].plane_mut(glassbake_core::layout::transparent::COVERAGE).fill(0.0);
            }
        }
        let batch = common::batch(&frames);
        assert!((0..3).all(|k| batch.shows_object(k) != unseen.contains(&k)));
        let (loss, left_out) = batch_gradients(&model, &batch, &device, &[], 1.0).unwrap();
        let whole_loss = glassbake_net::loss::training_loss(model.forward(&batch.inputs(&device)), model.target(&batch, &device).unwrap(), 1.0);
        let whole_loss_value = whole_loss.clone().into_scalar::<f32>() as f64;
        let whole = GradientsParams::from_grads(whole_loss.backward(), &model);
        assert_eq!(loss.to_bits(), whole_loss_value.to_bits(), "objects {unseen:?} unseen: loss {loss} against {whole_loss_value}");
        let (difference, largest) = gradient_difference(&model, &whole, &left_out);
        assert!(difference == 0.0 && largest > 0.0, "objects {unseen:?} unseen: gradients differ by {difference} (largest {largest})");
    }
    let batch = {
        let mut frames: Vec<_> = (0..2).map(|i| common::frame(60 + i, 16, 3, 1)).collect();
        frames.iter_mut().for_each(|f| f.transparent[1].plane_mut(glassbake_core::layout::transparent::COVERAGE).fill(0.0));
        common::batch(&frames)
    };

    let unmasked = NetConfig { terms_masked_by_coverage: false, ..config };
    let model = glassbake_net::init::initialize(GlassNet::new(&unmasked, 8, &device).unwrap(), 8);
    assert!(!model.unseen_objects_add_nothing());
    let image = |leave_out: bool| {
        let inputs = batch.inputs(&device);
        let prediction = model.forward_streaming(inputs.gbuffer, inputs.light_coverage, inputs.values, 3, &mut |k| {
            (!(leave_out && k == 1)).then(|| inputs.transparent[k].clone())
        });
        prediction.into_data().try_to_vec::<f32>().unwrap()
    };
    assert_ne!(image(true), image(false), "without the mask an unseen object's term is not 0");
}
