//! `glassbake eval`: score trained models on a dataset split (glassbake_eval::score), with a
//! progress bar and a summary on the terminal.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use glassbake_bake::{evaluate, Progress};
use glassbake_dataset::Split;
use glassbake_eval::score::ScoreOptions;
use glassbake_net::DeviceChoice;

#[derive(Args)]
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
    pub device: DeviceChoice,
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
    let (dataset, models) = args.paths.split_last().expect("clap requires two paths");
    let options = ScoreOptions {
        models: models.to_vec(),
        dataset: dataset.clone(),
        out: args.out.clone(),
        split: Split::parse(&args.split)?,
        frames: args.frames,
        lpips_weights: args.lpips_weights.clone(),
        device: args.device,
        workers: args.workers,
        path_traced_baseline: args.path_traced_baseline,
        super_sampler: args.super_sampler.clone(),
    };
    let summary = Progress::printing_while(|progress| evaluate(&options, &[], progress));
    println!("{}", summary?.text_table());
    Ok(())
}
