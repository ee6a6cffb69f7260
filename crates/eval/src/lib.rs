//! glassbake-eval: judging rendered frames against path-traced ground truth. It owns the
//! metrics (MAE, PSNR, DSSIM, their transparent-pixel versions T.MAE/T.PSNR, FLIP and LPIPS),
//! the tone map they are computed on, the comparison grids and error heat-maps, the
//! `metrics.json`/`metrics.csv` files and the HTML/Markdown/PNG report, which see only images,
//! and the scoring run that feeds them (`score`, the default feature `score`: every model's
//! frames of a dataset split, the path-traced + denoised baseline, the noise floor, the order
//! test; without it the crate builds without burn). The baseline's denoiser
//! (Intel Open Image Denoise, the optional `oidn` feature) lives here too.

pub mod bootstrap;
pub mod denoise;
pub mod evaluation;
pub mod grid;
pub mod lpips;
pub mod markdown;
pub mod metrics;
pub mod plot;
pub mod report;
pub mod rgb;
#[cfg(feature = "score")]
pub mod score;

pub use evaluation::{Evaluation, EvaluationSummary, ModelMetrics, OrderTest};
pub use lpips::Lpips;
pub use metrics::FrameMetrics;
pub use rgb::RgbImage;
