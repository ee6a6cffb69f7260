//! What half precision would cost a trained model in quality, before a backend runs it: the
//! dataset's test split scored with the model as trained, with its weights rounded to f16,
//! and with its weights and every convolution's input and output rounded to f16
//! (`glassbake_net::precision`: f16 storage, f32 arithmetic, the transparency sum in f32).
//!
//! ```sh
//! cargo run --release -p glassbake-eval --example half_precision -- MODEL DATASET OUT [FRAMES]
//! ```

use std::path::{Path, PathBuf};

use glassbake_core::{Error, Result};
use glassbake_dataset::Split;
use glassbake_eval::score::{score_models, ScoreOptions};
use glassbake_net::model_dir::{read_weights, write_weights, ModelFiles};
use glassbake_net::precision::{round_weights_to_f16, set_f16_activations};
use glassbake_net::{select_device, with_new_model, DeviceChoice, ModelTask, SceneModel, Trainable, TrainedModel};

fn score(model: &Path, dataset: &Path, out: PathBuf, frames: Option<usize>) -> Result<(f64, Option<f64>)> {
    let options = ScoreOptions {
        models: vec![model.to_path_buf()],
        dataset: dataset.to_path_buf(),
        out,
        split: Split::Test,
        frames,
        lpips_weights: None,
        device: DeviceChoice::Cpu,
        workers: 1,
        path_traced_baseline: None,
        super_sampler: None,
    };
    let scored = score_models(&options, &[], &mut |_, _| {})?;
    let metrics = &scored.summary.models[0];
    Ok((metrics.psnr, metrics.t_psnr))
}

/// Reads a model's weights, rounds them to f16 and writes them into another model directory.
struct RoundToF16<'a> {
    from: &'a ModelFiles,
    to: &'a ModelFiles,
}

impl ModelTask for RoundToF16<'_> {
    type Output = Result<()>;
    fn run<M: SceneModel + Trainable>(self, mut model: M) -> Result<()> {
        read_weights(&mut model, &self.from.weights_path())?;
        write_weights(&round_weights_to_f16(model), self.to, 0)
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, dataset, out] = [0, 1, 2].map(|i| args.get(i).map(PathBuf::from));
    let (Some(model), Some(dataset), Some(out)) = (model, dataset, out) else {
        return Err(Error::bad_input("half_precision", "arguments", "MODEL DATASET OUT [FRAMES]"));
    };
    let frames =
        args.get(3).map(|f| f.parse::<usize>().map_err(|_| Error::bad_input("half_precision", "FRAMES", format!("{f:?} is not a count")))).transpose()?;

    // The same model with its weights rounded to f16, in a model directory of its own.
    let device = select_device(DeviceChoice::Cpu, 0, false);
    let trained = TrainedModel::load(&model, &device)?;
    let rounded_dir = out.join("model-f16-weights");
    let files = ModelFiles::prepare(&rounded_dir, trained.files.config.clone())?;
    with_new_model(trained.config(), 0, &device, RoundToF16 { from: &trained.files, to: &files })??;
    if let Ok(log) = std::fs::read(model.join("train_log.csv")) {
        std::fs::write(rounded_dir.join("train_log.csv"), log).map_err(|e| Error::io(&rounded_dir, e))?;
    }

    let full = score(&model, &dataset, out.join("f32"), frames)?;
    let weights = score(&rounded_dir, &dataset, out.join("f16-weights"), frames)?;
    set_f16_activations(true);
    let half = score(&rounded_dir, &dataset, out.join("f16-weights-and-activations"), frames)?;
    set_f16_activations(false);

    let t = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    println!("| network | PSNR (dB) | T.PSNR (dB) | PSNR change | T.PSNR change |");
    println!("|---|---|---|---|---|");
    for (name, (psnr, t_psnr)) in [("f32", full), ("f16 weights", weights), ("f16 weights and activations", half)] {
        let change = |a: Option<f64>, b: Option<f64>| a.zip(b).map_or("-".to_string(), |(a, b)| format!("{:+.3}", a - b));
        println!("| {name} | {psnr:.3} | {} | {} | {} |", t(t_psnr), change(Some(psnr), Some(full.0)), change(t_psnr, full.1));
    }
    Ok(())
}
