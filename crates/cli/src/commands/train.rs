//! `glassbake train` and `glassbake train-sr`: a model or the super-sampler trained on a
//! dataset (`glassbake_bake::training`), with a progress bar and a summary.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use glassbake_bake::training::{PositionEncoding, RendererOutput};
use glassbake_bake::{train_model, train_super_sampler, Ablation, Preset, Progress, SuperSamplerRequest, TrainOverrides, TrainRequest};
use glassbake_core::Error;
use glassbake_net::{DeviceChoice, ModelKind};

/// Options shared by `train` and `train-sr`.
#[derive(Args, Clone)]
pub struct CommonTrainArgs {
    /// Dataset directory (made by `glassbake dataset`).
    pub dataset: PathBuf,
    /// Model directory; re-running the same command there resumes from its checkpoint.
    #[arg(long)]
    pub out: PathBuf,
    /// tiny (tests), quick (a CPU bake at 64-128 px) or paper (GPU, 256 px).
    #[arg(long, default_value_t = Preset::quick())]
    pub preset: Preset,
    /// cpu (burn's flex backend), wgpu (Vulkan) or, in a build with the `cuda` feature, cuda.
    #[arg(long, default_value = "cpu")]
    pub device: DeviceChoice,
    /// GPUs of --device's kind that share each batch (data parallelism; at most the batch size).
    #[arg(long, default_value_t = 1)]
    pub devices: usize,
    /// On a GPU, the convolutions as burn's `kernels` or as `matmul` (im2col and matrix products).
    #[arg(long, default_value = "kernels")]
    pub gpu_convolutions: glassbake_net::convolution::GpuConvolutions,
    /// Override the preset's number of optimizer steps.
    #[arg(long)]
    pub steps: Option<u64>,
    /// Override the preset's batch size.
    #[arg(long)]
    pub batch: Option<usize>,
    /// Override the preset's learning rate.
    #[arg(long)]
    pub lr: Option<f64>,
    /// Train on random square crops of this side (default: the preset's, 32 px crops for quick, whole frames for tiny and paper).
    #[arg(long)]
    pub crop: Option<u32>,
    #[arg(long)]
    pub seed: Option<u64>,
    /// Frame-reading/rasterizing worker threads.
    #[arg(long, default_value_t = 2)]
    pub workers: usize,
}

#[derive(Args)]
pub struct TrainArgs {
    #[command(flatten)]
    pub common: CommonTrainArgs,
    /// glassnet, naive (single G-buffer, glass overwrites), concat (buffers concatenated) or
    /// pixelgen (Active Exploration's per-pixel MLP on the naive G-buffer).
    #[arg(long, default_value = "glassnet")]
    pub model: String,
    /// Positional-encoding frequencies (0 = the paper's "without positional encoding" ablation).
    #[arg(long)]
    pub encoding_frequencies: Option<usize>,
    /// Weight of the (1 - SSIM) term (0 = the paper's "L1 only" ablation).
    #[arg(long)]
    pub ssim_weight: Option<f64>,
    /// An ablation: the paper's (Table 2) no-encoding (no positional encoding) or l1-only;
    /// front-through (the naive baseline also reading the through buffer of the transparent
    /// object in front: GlassNet's input without its architecture); or no-through (GlassNet
    /// without the through buffers, as the paper's: what seeing through the glass adds).
    #[arg(long)]
    pub ablation: Option<String>,
    /// What the renderer R predicts: `rgb` (the image directly, as the paper; the default),
    /// `demodulated` (light that multiplies the G-buffer's albedo, plus a free RGB term),
    /// `through-demodulated` (GlassNet: what it sees through the glass as light that
    /// multiplies the through buffers' albedo, plus a free RGB term) or `demodulated-through`
    /// (both: the G-buffer's albedo for the direct term, the through buffers' behind glass).
    #[arg(long)]
    pub renderer_output: Option<String>,
    /// How world positions enter F and h: `fourier` (the paper's sinusoids, as every other
    /// channel) or `hash-grid` (a trainable multiresolution grid over the scene's bounds).
    #[arg(long)]
    pub position_encoding: Option<String>,
}

#[derive(Args)]
pub struct TrainSrArgs {
    #[command(flatten)]
    pub common: CommonTrainArgs,
    /// The trained GlassNet whose images are super-sampled (trained at half this dataset's
    /// resolution or on the same scene).
    #[arg(long)]
    pub glassnet: PathBuf,
}

impl CommonTrainArgs {
    fn overrides(&self) -> TrainOverrides {
        TrainOverrides { steps: self.steps, batch_size: self.batch, learning_rate: self.lr, crop: self.crop, seed: self.seed }
    }
}

impl TrainArgs {
    fn request(self) -> Result<TrainRequest> {
        let model = ModelKind::parse(&self.model)
            .ok_or_else(|| Error::bad_input("--model", "model", format!("{:?} is not glassnet, naive, concat or pixelgen", self.model)))?;
        Ok(TrainRequest {
            device: self.common.device,
            devices: self.common.devices,
            overrides: self.common.overrides(),
            workers: self.common.workers,
            ablation: self.ablation.as_deref().map(Ablation::parse).transpose()?,
            encoding_frequencies: self.encoding_frequencies,
            ssim_weight: self.ssim_weight,
            renderer_output: self.renderer_output.as_deref().map(RendererOutput::parse).transpose()?,
            position_encoding: self.position_encoding.as_deref().map(PositionEncoding::parse).transpose()?,
            ..TrainRequest::new(self.common.dataset, self.common.out, self.common.preset, model)
        })
    }
}

pub fn run(args: TrainArgs) -> Result<()> {
    glassbake_net::convolution::set_gpu_convolutions(args.common.gpu_convolutions);
    let request = args.request()?;
    Progress::printing_while(|progress| train_model(&request, progress)).map(|_| ()).map_err(Into::into)
}

pub fn run_super_sampler(args: TrainSrArgs) -> Result<()> {
    glassbake_net::convolution::set_gpu_convolutions(args.common.gpu_convolutions);
    let request = SuperSamplerRequest {
        dataset: args.common.dataset.clone(),
        glassnet: args.glassnet,
        out: args.common.out.clone(),
        preset: args.common.preset.clone(),
        device: args.common.device,
        devices: args.common.devices,
        overrides: args.common.overrides(),
        workers: args.common.workers,
    };
    Progress::printing_while(|progress| train_super_sampler(&request, progress)).map_err(Into::into)
}
