//! `glassbake eval`: score trained models on a dataset split (glassbake_eval::score), with a
//! progress bar and a summary on the terminal.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Result;
use clap::Args;
use glassbake_dataset::Split;
use glassbake_eval::score::{score_models, ScoreOptions};
use glassbake_eval::EvaluationSummary;
use glassbake_net::DeviceChoice;
use indicatif::{ProgressBar, ProgressStyle};

#[derive(Args, Clone)]
pub struct EvalArgs {
    /// One or more model directories (from `glassbake train`), then the dataset directory.
    #[arg(required = true, num_args = 2.., value_name = "MODEL_DIR... DATASET")]
    pub paths: Vec<PathBuf>,
    /// Where metrics.json, metrics.csv, frames/, grids/ and report/ go.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Evaluate only the first N frames of the split.
    #[arg(long)]
    pub frames: Option<usize>,
    /// LPIPS AlexNet weights (safetensors, see docs/eval.md); without it LPIPS is skipped.
    #[arg(long)]
    pub lpips_weights: Option<PathBuf>,
    /// cpu (burn's flex backend), wgpu (Vulkan) or, in a build with the `cuda` feature, cuda.
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Frame-reading/rasterizing worker threads.
    #[arg(long, default_value_t = 2)]
    pub workers: usize,
    /// Also path trace each frame at SPP samples per pixel and denoise it with Intel Open
    /// Image Denoise (the naive G-buffer's albedo and normals as guides): rows `ptSPP` and
    /// `ptSPP+oidn` (the paper used 32). Needs a build with the `oidn` feature (docs/eval.md).
    #[arg(long, value_name = "SPP")]
    pub path_traced_baseline: Option<u32>,
    /// A trained x2 super-sampler (`glassbake train-sr`): the first GlassNet listed also
    /// renders each frame at half resolution (box-filtered buffers), brought up by the
    /// super-sampler and, for comparison, bilinearly (rows `NAME@half+sr`, `NAME@half+bilinear`).
    #[arg(long, value_name = "SR_DIR")]
    pub super_sampler: Option<PathBuf>,
}

pub fn run(args: EvalArgs) -> Result<()> {
    let bar = ProgressBar::new(0);
    let summary = evaluate(&args, &bar, &[])?;
    bar.finish_and_clear();
    println!("{}", summary.text_table());
    Ok(())
}

fn frame_style() -> ProgressStyle {
    ProgressStyle::with_template("{spinner} frames {pos}/{len} [{elapsed_precise}] {wide_bar} ETA {eta}").expect("static template").progress_chars("=> ")
}

/// Scores the models of `args` with `bar` as the frame counter; `facts` are extra lines for
/// the report (the bake's stage times).
pub fn evaluate(args: &EvalArgs, bar: &ProgressBar, facts: &[String]) -> Result<EvaluationSummary> {
    let (dataset, models) = args.paths.split_last().expect("clap requires two paths");
    let options = ScoreOptions {
        models: models.to_vec(),
        dataset: dataset.clone(),
        out: args.out.clone(),
        split: Split::parse(&args.split)?,
        frames: args.frames,
        lpips_weights: args.lpips_weights.clone(),
        device: DeviceChoice::parse(&args.device)?,
        workers: args.workers,
        path_traced_baseline: args.path_traced_baseline,
        super_sampler: args.super_sampler.clone(),
    };
    bar.set_style(frame_style());
    bar.set_position(0);
    bar.enable_steady_tick(Duration::from_millis(250));
    let scored = score_models(&options, facts, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    let summary = scored.summary;
    bar.suspend(|| {
        println!("evaluated {} frame(s) of {}: {}", summary.frames.len(), dataset.display(), args.out.join("metrics.json").display());
        if let Some(o) = &summary.order_test {
            println!(
                "  order test ({}, {} frames): max |difference| reversed {}, shuffled {}{}",
                o.model,
                o.frames,
                o.reversed_max_abs_diff,
                o.shuffled_max_abs_diff,
                if o.passed() { " (bit-identical)" } else { " — NOT identical" }
            );
        }
        println!("  LPIPS {}", summary.lpips);
        println!("  report {}", scored.report.display());
    });
    Ok(summary)
}
