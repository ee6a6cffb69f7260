//! One evaluation run: per-frame metrics of every model against the ground truth, per-frame
//! images and grids, the order test, and `metrics.json` / `metrics.csv`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glassbake_core::output_dir::{claim_output_dir, OutputKind};
use glassbake_core::{Error, Result};
use serde::{Deserialize, Serialize};

use crate::bootstrap::{self, Estimate};
use crate::grid;
use crate::lpips::Lpips;
use crate::metrics::{frame_metrics, FrameMetrics};
use crate::rgb::RgbImage;

pub const TONE_MAP: &str =
    "clamp linear RGB to [0, 1]; MAE, PSNR, DSSIM, T.MAE, T.PSNR on the clamped linear values; FLIP (8-bit) and LPIPS on their sRGB encoding";

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FrameRecord {
    pub index: u64,
    /// Pixels covered by any transparent object.
    pub transparent_pixels: usize,
    /// One entry per model, in the evaluation's model order.
    pub metrics: Vec<FrameMetrics>,
}

/// A model's metrics averaged over frames (T.* over the frames that show glass).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ModelMetrics {
    pub model: String,
    pub frames: usize,
    pub mae: f64,
    pub psnr: f64,
    pub dssim: f64,
    pub t_mae: Option<f64>,
    pub t_psnr: Option<f64>,
    pub t_frames: usize,
    pub flip: f64,
    pub lpips: Option<f64>,
    /// Mean wall time to render one frame, where the caller timed it (network inference; for
    /// the path-traced baselines tracing, plus denoising for `+oidn`).
    #[serde(default)]
    pub seconds_per_frame: Option<f64>,
    /// 95% bootstrap intervals of the means above over the frames, by metric name (`mae`,
    /// `psnr`, `dssim`, `t_mae`, `t_psnr`, `flip`, `lpips`); empty in metrics written before
    /// they were computed and for metrics with fewer than two frames.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub intervals: BTreeMap<String, Estimate>,
    /// This model's per-frame differences to the evaluation's first model, paired; `None` for
    /// the first model itself.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub versus: Option<Versus>,
}

/// A model's per-frame differences (this model minus `reference`) by metric name, each with
/// its paired 95% bootstrap interval over the frames.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Versus {
    pub reference: String,
    pub differences: BTreeMap<String, Estimate>,
}

/// The metrics by the names metrics.json uses, each a frame's value where it has one.
type Metric = (&'static str, fn(&FrameMetrics) -> Option<f64>);
const METRICS: [Metric; 7] = [
    ("mae", |m| Some(m.mae)),
    ("psnr", |m| Some(m.psnr)),
    ("dssim", |m| Some(m.dssim)),
    ("t_mae", |m| m.t_mae),
    ("t_psnr", |m| m.t_psnr),
    ("flip", |m| Some(m.flip)),
    ("lpips", |m| m.lpips),
];

/// The bootstrap intervals of model `m`'s means and, for every model but the first, of its
/// paired differences to the first.
fn intervals_of(frames: &[FrameRecord], names: &[String], m: usize) -> (BTreeMap<String, Estimate>, Option<Versus>) {
    let series = |model: usize, metric: fn(&FrameMetrics) -> Option<f64>| -> Vec<Option<f64>> { frames.iter().map(|r| metric(&r.metrics[model])).collect() };
    let intervals =
        METRICS.iter().filter_map(|&(name, metric)| Some((name.to_string(), bootstrap::mean_interval(&series(m, metric), bootstrap::SEED)?))).collect();
    let versus = (m > 0).then(|| Versus {
        reference: names[0].clone(),
        differences: METRICS
            .iter()
            .filter_map(|&(name, metric)| Some((name.to_string(), bootstrap::paired_difference(&series(m, metric), &series(0, metric), bootstrap::SEED)?)))
            .collect(),
    });
    (intervals, versus)
}

/// GlassNet rendered with its transparent objects in other orders than the dataset's.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct OrderTest {
    pub model: String,
    pub frames: usize,
    /// Largest |difference| of any pixel value against the dataset order.
    pub reversed_max_abs_diff: f32,
    pub shuffled_max_abs_diff: f32,
}

impl OrderTest {
    pub fn passed(&self) -> bool {
        self.reversed_max_abs_diff == 0.0 && self.shuffled_max_abs_diff == 0.0
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EvaluationSummary {
    pub dataset: String,
    pub split: String,
    pub resolution: usize,
    pub tone_map: String,
    /// "AlexNet weights from PATH" or "skipped: no weights".
    pub lpips: String,
    pub models: Vec<ModelMetrics>,
    pub order_test: Option<OrderTest>,
    pub frames: Vec<FrameRecord>,
}

pub struct Evaluation {
    dir: PathBuf,
    models: Vec<String>,
    lpips: Option<Lpips>,
    dataset: String,
    split: String,
    resolution: usize,
    frames: Vec<FrameRecord>,
    order_test: Option<OrderTest>,
    /// Per model: (seconds summed, frames timed).
    render_times: Vec<(f64, usize)>,
}

fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / n as f64)
}

/// The output-folder kind of an evaluation (`glassbake eval --out`).
pub const EVALUATION_DIRECTORY: OutputKind = OutputKind { name: "evaluation", signatures: &["metrics.json"] };

impl Evaluation {
    /// Starts an evaluation writing under `dir` (`frames/`, `grids/`, `metrics.*`).
    pub fn new(dir: &Path, models: Vec<String>, lpips: Option<Lpips>, dataset: String, split: String) -> Result<Evaluation> {
        claim_output_dir(dir, EVALUATION_DIRECTORY, "--out")?;
        for sub in ["frames", "grids", "crops"] {
            std::fs::create_dir_all(dir.join(sub)).map_err(|e| Error::io(&dir.join(sub), e))?;
        }
        let render_times = vec![(0.0, 0); models.len()];
        Ok(Evaluation { dir: dir.to_path_buf(), models, lpips, dataset, split, resolution: 0, frames: Vec::new(), order_test: None, render_times })
    }

    pub fn grid_path(&self, index: u64) -> PathBuf {
        self.dir.join("grids").join(format!("{index:06}.png"))
    }

    /// The glass crop of frame `index` (written only for frames that show glass).
    pub fn crop_path(&self, index: u64) -> PathBuf {
        self.dir.join("crops").join(format!("{index:06}.png"))
    }

    /// Scores one frame: `predictions` in the model order given to `new`.
    pub fn add_frame(&mut self, index: u64, ground_truth: &RgbImage, mask: &[bool], predictions: &[RgbImage]) -> Result<&FrameRecord> {
        if predictions.len() != self.models.len() {
            return Err(Error::Internal(format!("{} predictions for {} models", predictions.len(), self.models.len())));
        }
        self.resolution = ground_truth.width;
        let frames = self.dir.join("frames");
        ground_truth.write_png(&frames.join(format!("{index:06}_ground_truth.png")))?;
        let mut metrics = Vec::new();
        let mut heat_maps = Vec::new();
        for (model, prediction) in self.models.iter().zip(predictions) {
            let (m, flip_map) = frame_metrics(ground_truth, prediction, mask, self.lpips.as_ref())?;
            prediction.write_png(&frames.join(format!("{index:06}_{model}.png")))?;
            heat_maps.push(grid::heat_map(ground_truth.width, ground_truth.height, &flip_map));
            metrics.push(m);
        }
        let mut tiles = vec![ground_truth.clone()];
        tiles.extend(predictions.iter().cloned());
        tiles.extend(heat_maps);
        tiles.push(grid::mask_image(ground_truth.width, ground_truth.height, mask));
        grid::row(&tiles).write_png(&self.grid_path(index))?;
        if let Some((x0, y0, side)) = grid::glass_window(ground_truth.width, ground_truth.height, mask, grid::CROP_SIDE) {
            let crops: Vec<RgbImage> = std::iter::once(ground_truth).chain(predictions).map(|image| grid::crop(image, x0, y0, side)).collect();
            grid::row(&crops).write_png(&self.crop_path(index))?;
        }
        self.frames.push(FrameRecord { index, transparent_pixels: mask.iter().filter(|&&m| m).count(), metrics });
        Ok(self.frames.last().expect("just pushed"))
    }

    /// Records that model `model` (index in the order given to `new`) took `seconds` to
    /// render one frame.
    pub fn add_render_time(&mut self, model: usize, seconds: f64) {
        let t = &mut self.render_times[model];
        t.0 += seconds;
        t.1 += 1;
    }

    pub fn set_order_test(&mut self, test: OrderTest) {
        self.order_test = Some(test);
    }

    /// Averages, writes `metrics.json` and `metrics.csv`, and returns the summary.
    pub fn finish(self) -> Result<EvaluationSummary> {
        let models = self
            .models
            .iter()
            .enumerate()
            .map(|(m, name)| {
                let (intervals, versus) = intervals_of(&self.frames, &self.models, m);
                let of = |f: &dyn Fn(&FrameMetrics) -> f64| mean(self.frames.iter().map(|r| f(&r.metrics[m]))).unwrap_or(f64::NAN);
                let t = |f: &dyn Fn(&FrameMetrics) -> Option<f64>| mean(self.frames.iter().filter_map(|r| f(&r.metrics[m])));
                ModelMetrics {
                    model: name.clone(),
                    frames: self.frames.len(),
                    mae: of(&|x| x.mae),
                    psnr: of(&|x| x.psnr),
                    dssim: of(&|x| x.dssim),
                    t_mae: t(&|x| x.t_mae),
                    t_psnr: t(&|x| x.t_psnr),
                    t_frames: self.frames.iter().filter(|r| r.metrics[m].t_mae.is_some()).count(),
                    flip: of(&|x| x.flip),
                    lpips: t(&|x| x.lpips),
                    seconds_per_frame: match self.render_times[m] {
                        (_, 0) => None,
                        (total, n) => Some(total / n as f64),
                    },
                    intervals,
                    versus,
                }
            })
            .collect();
        let summary = EvaluationSummary {
            dataset: self.dataset,
            split: self.split,
            resolution: self.resolution,
            tone_map: TONE_MAP.into(),
            lpips: match &self.lpips {
                Some(l) => format!("AlexNet weights from {}", l.source.display()),
                None => "skipped: no weights".into(),
            },
            models,
            order_test: self.order_test,
            frames: self.frames,
        };
        let json = serde_json::to_string_pretty(&summary).map_err(|e| Error::Internal(e.to_string()))?;
        glassbake_core::image::write_bytes_atomically(&self.dir.join("metrics.json"), json.as_bytes())?;
        glassbake_core::image::write_bytes_atomically(&self.dir.join("metrics.csv"), summary.csv().as_bytes())?;
        Ok(summary)
    }
}

fn csv_row(out: &mut String, frame: &str, model: &str, m: &FrameMetrics, seconds_per_frame: Option<f64>) {
    let _ = writeln!(
        out,
        "{frame},{model},{:.6},{:.4},{:.6},{},{},{:.6},{},{}",
        m.mae,
        m.psnr,
        m.dssim,
        cell(m.t_mae, 6),
        cell(m.t_psnr, 4),
        m.flip,
        cell(m.lpips, 6),
        cell(seconds_per_frame, 4)
    );
}

fn cell(v: Option<f64>, digits: usize) -> String {
    v.map(|v| format!("{v:.digits$}")).unwrap_or_default()
}

impl EvaluationSummary {
    pub fn read(path: &Path) -> Result<EvaluationSummary> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_str(&text).map_err(|e| Error::bad_input(path.display(), "metrics", e.to_string()))
    }

    /// One row per frame and model, then one `mean` row per model (the only rows with a time).
    pub fn csv(&self) -> String {
        let mut out = String::from("frame,model,mae,psnr,dssim,t_mae,t_psnr,flip,lpips,seconds_per_frame\n");
        for record in &self.frames {
            for (model, m) in self.models.iter().zip(&record.metrics) {
                csv_row(&mut out, &record.index.to_string(), &model.model, m, None);
            }
        }
        for m in &self.models {
            let averaged = FrameMetrics { mae: m.mae, psnr: m.psnr, dssim: m.dssim, t_mae: m.t_mae, t_psnr: m.t_psnr, flip: m.flip, lpips: m.lpips };
            csv_row(&mut out, "mean", &m.model, &averaged, m.seconds_per_frame);
        }
        out
    }

    /// Per model, the averaged metrics as table cells: model, MAE, PSNR, DSSIM, T.MAE, T.PSNR,
    /// FLIP, LPIPS, seconds per frame.
    fn table_cells(&self) -> Vec<[String; 9]> {
        self.models
            .iter()
            .map(|m| {
                [
                    m.model.clone(),
                    format!("{:.4}", m.mae),
                    format!("{:.2}", m.psnr),
                    format!("{:.4}", m.dssim),
                    cell(m.t_mae, 4),
                    cell(m.t_psnr, 2),
                    format!("{:.4}", m.flip),
                    m.lpips.map(|v| format!("{v:.4}")).unwrap_or_else(|| "skipped".into()),
                    cell(m.seconds_per_frame, 3),
                ]
            })
            .collect()
    }

    /// The averaged metrics as a Markdown table (arrows say which way is better).
    pub fn markdown_table(&self) -> String {
        let mut out =
            String::from("| model | MAE ↓ | PSNR ↑ | DSSIM ↓ | T.MAE ↓ | T.PSNR ↑ | FLIP ↓ | LPIPS ↓ | s/frame |\n|---|---|---|---|---|---|---|---|---|\n");
        for (mut row, m) in self.table_cells().into_iter().zip(&self.models) {
            // The model's name is the user's; the numbers are ours.
            row[0] = crate::markdown::text(&row[0]);
            for (column, metric) in [(2, "psnr"), (5, "t_psnr")] {
                if let Some(e) = m.intervals.get(metric) {
                    row[column] = format!("{} [{:.2}, {:.2}]", row[column], e.low, e.high);
                }
            }
            let _ = writeln!(out, "| {} |", row.join(" | "));
        }
        out
    }

    /// Each model's paired differences to the first model as a Markdown table (empty when no
    /// model has them).
    pub fn markdown_differences(&self) -> String {
        let Some(reference) = self.models.iter().find_map(|m| m.versus.as_ref().map(|v| v.reference.clone())) else {
            return String::new();
        };
        let metrics = [("psnr", "PSNR", 2), ("t_psnr", "T.PSNR", 2), ("dssim", "DSSIM", 4), ("flip", "FLIP", 4)];
        let mut out = format!(
            "Differences to {} (this row minus it, mean over the frames with its paired 95% bootstrap interval):\n\n| model |",
            crate::markdown::text(&reference)
        );
        for (_, title, _) in metrics {
            let _ = write!(out, " Δ{title} |");
        }
        out.push_str(&format!("\n|---|{}\n", "---|".repeat(metrics.len())));
        for m in &self.models {
            let Some(versus) = &m.versus else { continue };
            let _ = write!(out, "| {} |", crate::markdown::text(&m.model));
            for (metric, _, digits) in metrics {
                match versus.differences.get(metric) {
                    Some(d) => {
                        let _ = write!(out, " {:+.digits$} [{:+.digits$}, {:+.digits$}] |", d.mean, d.low, d.high);
                    }
                    None => out.push_str(" - |"),
                }
            }
            out.push('\n');
        }
        out
    }

    /// A sentence for each baseline the first model does not lead on PSNR or T.PSNR: where the
    /// paired interval of the baseline's difference is not wholly below zero. Rows named
    /// `gt-*` (the noise floor) are references, not baselines.
    pub fn not_leading(&self) -> Vec<String> {
        let mut sentences = Vec::new();
        for m in self.models.iter().filter(|m| !m.model.starts_with("gt-")) {
            let Some(versus) = &m.versus else { continue };
            for (metric, title) in [("psnr", "PSNR"), ("t_psnr", "T.PSNR")] {
                let Some(d) = versus.differences.get(metric) else { continue };
                if !d.below_zero() {
                    let how = if d.above_zero() { "trails" } else { "does not lead" };
                    sentences.push(format!(
                        "{} {how} {} on {title}: {} scores {:+.2} dB against it, 95% interval [{:+.2}, {:+.2}] dB over {} frames.",
                        versus.reference, m.model, m.model, d.mean, d.low, d.high, m.frames
                    ));
                }
            }
        }
        sentences
    }

    /// A plain-text table for the terminal.
    pub fn text_table(&self) -> String {
        let header = ["model", "MAE", "PSNR", "DSSIM", "T.MAE", "T.PSNR", "FLIP", "LPIPS", "s/frame"].map(String::from);
        let mut out = String::new();
        for row in std::iter::once(header).chain(self.table_cells()) {
            let _ = write!(out, "{:<22}", row[0]);
            for value in &row[1..] {
                let _ = write!(out, " {value:>8}");
            }
            out.push('\n');
        }
        out
    }
}
