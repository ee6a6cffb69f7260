//! `glassbake bake`: a scene to a trained model and an honest report in one command
//! (`glassbake_bake::bake`), with the scores on the terminal.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use glassbake_bake::{bake, BakeRequest, Preset, Progress};
use glassbake_net::DeviceChoice;

#[derive(Args)]
pub struct BakeArgs {
    /// A built-in name or a path to a manifest, glTF or OBJ file.
    pub scene: String,
    /// quick (a CPU bake: 96 px, about half an hour for cornellbox on 2 cores), paper (a GPU bake: 256 px, the paper's network) or
    /// tiny (a smoke test: seconds, meaningless numbers).
    #[arg(long, default_value_t = Preset::quick())]
    pub preset: Preset,
    /// Output directory: dataset/, glassnet/, naive/ (pixelgen/, glassnet-*/), eval/, report/.
    #[arg(long, default_value = "bake")]
    pub out: PathBuf,
    /// cpu (burn's flex backend), wgpu (Vulkan) or cuda (a build with the `cuda` feature) for
    /// training and evaluation; wgpu also
    /// path-traces the dataset's ground truth on the GPU (`dataset --device wgpu`).
    #[arg(long, default_value = "cpu")]
    pub device: DeviceChoice,
    /// GPUs of --device's kind that share each training batch (data parallelism).
    #[arg(long, default_value_t = 1)]
    pub devices: usize,
    /// On a GPU, the training convolutions as burn's `kernels` or as `matmul` (im2col, products).
    #[arg(long, default_value = "kernels")]
    pub gpu_convolutions: glassbake_net::convolution::GpuConvolutions,
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
    /// While GlassNet trails naive on the validation split (half way, where it is stopped, or at
    /// the end), train it again with the next seed, up to this many times; the best on
    /// validation ships (glassnet_choice.json says which).
    #[arg(long, default_value_t = 1)]
    pub seed_retries: u32,
    /// The networks' seed (weights, frame order and crops) instead of the preset's (0).
    #[arg(long)]
    pub seed: Option<u64>,
}

pub fn run(args: BakeArgs) -> Result<()> {
    glassbake_net::convolution::set_gpu_convolutions(args.gpu_convolutions);
    let request = BakeRequest {
        scene: args.scene,
        preset: args.preset.with_seed(args.seed),
        out: args.out,
        device: args.device,
        devices: args.devices,
        ablations: args.ablations,
        baselines: args.baselines,
        lpips_weights: args.lpips_weights,
        threads: args.threads,
        estimator: args.estimator,
        seed_retries: args.seed_retries,
    };
    let result = Progress::printing_while(|progress| bake(&request, progress))?;
    let summary = &result.summary;
    println!("\nbake of {} done in {:.1} min: {}", request.scene, result.elapsed.as_secs_f64() / 60.0, request.out.display());
    println!("  report {}\n", result.report.display());
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
    if let Some(floor) = result.noise_floor.as_ref().and_then(|row| summary.models.iter().find(|m| &m.model == row)) {
        println!(
            "Noise floor ({}: the training-spp ground truth against the test split's): PSNR {:.2} dB, T.PSNR {}",
            floor.model,
            floor.psnr,
            floor.t_psnr.map(|t| format!("{t:.2} dB")).unwrap_or_else(|| "-".into())
        );
    }
    Ok(())
}
