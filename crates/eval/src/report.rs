//! The report of a bake: `report/index.html` (self-contained: styles inline, images as data
//! URIs, plots as inline SVG), `report/report.md` with the same content pointing at PNG files
//! beside it, and those PNGs (plots, comparison grids).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use glassbake_core::image::write_bytes_atomically;
use glassbake_core::{Error, Result};
use serde::{Deserialize, Serialize};

use crate::evaluation::EvaluationSummary;
use crate::grid::column_titles;
use crate::markdown;
use crate::plot::{bar_chart, line_chart, Plot, Series};

/// Grids shown in the report (the rest stay in the evaluation directory).
pub const MAX_GRIDS: usize = 6;

pub struct TrainingLog {
    pub name: String,
    /// A `train_log.csv` with columns step, train_loss, validation_loss.
    pub path: PathBuf,
}

/// The part of `bench.json` (written by `glassbake bench`, `realtime::bench::BenchReport`)
/// the report reads. eval and realtime are sibling stages and do not import each other: the
/// JSON is the contract, and `crates/cli/tests/realtime_cli.rs` reads a real bench.json with
/// this type.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchFile {
    pub device: String,
    pub rows: Vec<BenchRow>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchRow {
    pub resolution: u32,
    pub objects: usize,
    pub ms_per_frame: f64,
    pub fps: f64,
    pub peak_ram_mib: Option<f64>,
    pub peak_gpu_mib: Option<f64>,
}

pub struct ReportInputs {
    pub title: String,
    /// Lines of context (scene, preset, stage wall times), shown first.
    pub facts: Vec<String>,
    /// An evaluation directory holding `metrics.json` and `grids/`.
    pub eval_dir: Option<PathBuf>,
    pub training_logs: Vec<TrainingLog>,
    pub bench: Option<PathBuf>,
}

/// A plot or image of the report: its file name beside the report and how to show it inline.
struct Figure {
    title: String,
    file: String,
    png: Vec<u8>,
    svg: Option<String>,
}

/// (x, y) points.
type Curve = Vec<(f64, f64)>;

/// The curves of a `train_log.csv`.
struct TrainingCurves {
    /// (step, loss) on the training batches.
    train: Curve,
    /// (step, loss) on the validation frames.
    validation: Curve,
    /// (training seconds, validation PSNR); empty for logs written before the column existed.
    psnr_over_time: Curve,
}

fn read_training_log(path: &Path) -> Result<TrainingCurves> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).ok_or_else(|| Error::bad_input(path.display(), name, "column missing"));
    let (step, train, val) = (column("step")?, column("train_loss")?, column("validation_loss")?);
    let (elapsed, psnr) = (column("elapsed_s").ok(), column("validation_psnr").ok());
    let mut curves = TrainingCurves { train: Vec::new(), validation: Vec::new(), psnr_over_time: Vec::new() };
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        let get = |i: usize| cells.get(i).and_then(|c| c.parse::<f64>().ok());
        if let Some(s) = get(step) {
            if let Some(v) = get(train) {
                curves.train.push((s, v));
            }
            if let Some(v) = get(val) {
                curves.validation.push((s, v));
            }
        }
        if let (Some(t), Some(p)) = (elapsed.and_then(get), psnr.and_then(get)) {
            curves.psnr_over_time.push((t, p));
        }
    }
    Ok(curves)
}

fn figure(title: &str, file: &str, plot: Option<Plot>) -> Option<Figure> {
    plot.map(|p| Figure { title: title.into(), file: file.into(), png: p.png, svg: Some(p.svg) })
}

fn bench_table(bench: &BenchFile) -> String {
    let mut out = String::from("| resolution | transparent objects | ms / frame | FPS | peak RAM (MiB) | peak GPU (MiB) |\n|---|---|---|---|---|---|\n");
    let mib = |v: Option<f64>| v.map(|v| format!("{v:.1}")).unwrap_or_else(|| "-".into());
    for r in &bench.rows {
        let _ = writeln!(
            out,
            "| {0}x{0} | {1} | {2:.2} | {3:.1} | {4} | {5} |",
            r.resolution,
            r.objects,
            r.ms_per_frame,
            r.fps,
            mib(r.peak_ram_mib),
            mib(r.peak_gpu_mib)
        );
    }
    out
}

/// A section of the report: its heading, its Markdown text and its figures.
struct Section {
    heading: &'static str,
    text: String,
    figures: Vec<Figure>,
}

/// The metrics' tables, differences, warnings and order test, with the PSNR bar chart.
fn metrics_section(summary: &EvaluationSummary) -> Result<Section> {
    let mut text = format!(
        "{} frames of the {} split of {}, {} px. Tone map: {}. LPIPS: {}.\n\n{}",
        summary.frames.len(),
        markdown::code(&summary.split),
        markdown::code(&summary.dataset),
        summary.resolution,
        markdown::text(&summary.tone_map),
        markdown::text(&summary.lpips),
        summary.markdown_table()
    );
    text.push_str("\nT.MAE and T.PSNR are computed over the pixels covered by a transparent object, averaged over the frames that show one. Brackets hold 95% bootstrap intervals over the frames.\n");
    let differences = summary.markdown_differences();
    if !differences.is_empty() {
        let _ = write!(text, "\n{differences}");
    }
    for sentence in summary.not_leading() {
        let _ = write!(text, "\n**Warning:** {}\n", markdown::text(&sentence));
    }
    if let Some(order) = &summary.order_test {
        let _ = write!(
            text,
            "\n**Order test** ({}, {} frames): transparent objects reversed, max |difference| {}; shuffled, {} — {}.\n",
            markdown::text(&order.model),
            order.frames,
            order.reversed_max_abs_diff,
            order.shuffled_max_abs_diff,
            if order.passed() { "bit-identical, as the order-independent sum guarantees" } else { "NOT identical" }
        );
    }
    let groups: Vec<String> = summary.models.iter().map(|m| m.model.clone()).collect();
    let bars = vec![
        ("PSNR".to_string(), summary.models.iter().map(|m| m.psnr).collect()),
        ("T.PSNR".to_string(), summary.models.iter().map(|m| m.t_psnr.unwrap_or(f64::NAN)).collect()),
    ];
    let figures = figure("PSNR and T.PSNR (dB, higher is better)", "metrics.png", bar_chart("PSNR and T.PSNR", "dB", &groups, &bars)?).into_iter().collect();
    Ok(Section { heading: "Metrics", text, figures })
}

/// The comparison grids, and the crops behind the glass where the evaluation made them.
fn image_sections(summary: &EvaluationSummary, eval_dir: &Path) -> Result<Vec<Section>> {
    let groups: Vec<String> = summary.models.iter().map(|m| m.model.clone()).collect();
    let mut grids = Vec::new();
    for record in summary.frames.iter().take(MAX_GRIDS) {
        let source = eval_dir.join("grids").join(format!("{:06}.png", record.index));
        let png = std::fs::read(&source).map_err(|e| Error::io(&source, e))?;
        grids.push(Figure { title: format!("frame {}", record.index), file: format!("grids/{:06}.png", record.index), png, svg: None });
    }
    let columns = column_titles(&groups).iter().map(|c| markdown::text(c)).collect::<Vec<_>>().join(" | ");
    let text = format!("Columns: {columns}. FLIP error maps in magma: black is no error, yellow the largest.\n");
    let mut sections = vec![Section { heading: "Comparison grids", text, figures: grids }];
    let mut crops = Vec::new();
    for record in summary.frames.iter().filter(|r| r.transparent_pixels > 0).take(MAX_GRIDS) {
        let source = eval_dir.join("crops").join(format!("{:06}.png", record.index));
        if let Ok(png) = std::fs::read(&source) {
            crops.push(Figure { title: format!("frame {}, glass", record.index), file: format!("crops/{:06}.png", record.index), png, svg: None });
        }
    }
    if !crops.is_empty() {
        let columns = std::iter::once("ground truth").chain(groups.iter().map(String::as_str)).map(markdown::text).collect::<Vec<_>>().join(" | ");
        let text = format!(
            "A {side}x{side} window around the transparent objects, enlarged 4x (nearest neighbour). Columns: {columns}.\n",
            side = crate::grid::CROP_SIDE
        );
        sections.push(Section { heading: "Behind the glass", text, figures: crops });
    }
    Ok(sections)
}

/// The training curves of the logs that exist, and validation PSNR over time where logged.
fn training_section(logs: &[TrainingLog]) -> Result<Option<Section>> {
    let (mut curves, mut psnr_curves) = (Vec::new(), Vec::new());
    for log in logs.iter().filter(|log| log.path.exists()) {
        let log_curves = read_training_log(&log.path)?;
        curves.push(Series { name: format!("{} train", log.name), points: log_curves.train, dashed: false });
        curves.push(Series { name: format!("{} validation", log.name), points: log_curves.validation, dashed: true });
        if !log_curves.psnr_over_time.is_empty() {
            psnr_curves.push(Series { name: log.name.clone(), points: log_curves.psnr_over_time, dashed: false });
        }
    }
    if curves.is_empty() {
        return Ok(None);
    }
    let mut figures: Vec<Figure> =
        figure("Training curves", "training_curves.png", line_chart("Training curves", "step", "loss (L1 + SSIM term)", &curves)?).into_iter().collect();
    let mut text = String::from("Loss per step (solid: training batches, dashed: validation frames).\n");
    if !psnr_curves.is_empty() {
        figures.extend(figure(
            "Validation PSNR over training time",
            "validation_psnr.png",
            line_chart("Validation PSNR over training time", "training seconds", "PSNR (dB)", &psnr_curves)?,
        ));
        text.push_str("\nValidation PSNR (whole frames, clamped to [0, 1]) against training wall time: a curve still rising at its end says more training time would help.\n");
    }
    Ok(Some(Section { heading: "Training", text, figures }))
}

/// The real-time benchmark's table and plots, from `bench.json`.
fn bench_section(path: &Path) -> Result<Section> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let bench: BenchFile = serde_json::from_str(&text).map_err(|e| Error::bad_input(path.display(), "bench", e.to_string()))?;
    let mut resolutions: Vec<u32> = bench.rows.iter().map(|r| r.resolution).collect();
    resolutions.dedup();
    let per_res = |f: &dyn Fn(&BenchRow) -> Option<f64>| -> Vec<Series> {
        resolutions
            .iter()
            .map(|&res| Series {
                name: format!("{res}x{res}"),
                points: bench.rows.iter().filter(|r| r.resolution == res).filter_map(|r| f(r).map(|v| (r.objects as f64, v))).collect(),
                dashed: false,
            })
            .collect()
    };
    let mut figures = Vec::new();
    figures.extend(figure(
        "Time per frame",
        "speed.png",
        line_chart(&format!("Time per frame ({})", bench.device), "transparent objects", "ms / frame", &per_res(&|r| Some(r.ms_per_frame)))?,
    ));
    let memory = per_res(&|r| r.peak_gpu_mib.or(r.peak_ram_mib));
    figures.extend(figure("Peak memory", "memory.png", line_chart("Peak memory", "transparent objects", "MiB", &memory)?));
    let text = format!("{} on {}.\n\n{}", markdown::text(&path.display().to_string()), markdown::text(&bench.device), bench_table(&bench));
    Ok(Section { heading: "Speed and memory", text, figures })
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}\ntable{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:4px 10px;text-align:right}th{background:#eee}td:first-child{text-align:left}\nimg{max-width:100%;image-rendering:pixelated}figure{margin:1em 0}figcaption{color:#555}.note{background:#fff4d6;padding:.5em 1em}";

/// The self-contained HTML: the same Markdown rendered, with the figures inline.
fn report_html(title: &str, head: &str, notes: &[String], sections: &[Section]) -> String {
    let mut html = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n<style>\n{STYLE}\n</style></head><body>\n{}",
        markdown::html_text(title),
        markdown::to_html(head)
    );
    for note in notes {
        let _ = writeln!(html, "<p class=\"note\">{}</p>", markdown::html_text(note));
    }
    for section in sections {
        html.push_str(&markdown::to_html(&format!("## {}\n\n{}", section.heading, section.text)));
        for f in &section.figures {
            let body = match &f.svg {
                Some(svg) => svg.clone(),
                None => format!(
                    "<img alt=\"{}\" src=\"data:image/png;base64,{}\">",
                    markdown::html_text(&f.title),
                    base64::engine::general_purpose::STANDARD.encode(&f.png)
                ),
            };
            let _ = writeln!(html, "<figure>{body}<figcaption>{}</figcaption></figure>", markdown::html_text(&f.title));
        }
    }
    html.push_str("</body></html>\n");
    html
}

/// Writes the report into `dir` (created); returns the path of `index.html`. The inputs'
/// strings are text: escaped, never read as markup.
pub fn write_report(dir: &Path, inputs: &ReportInputs) -> Result<PathBuf> {
    for sub in ["grids", "crops"] {
        std::fs::create_dir_all(dir.join(sub)).map_err(|e| Error::io(dir, e))?;
    }
    let mut sections = Vec::new();
    let mut notes = Vec::new();
    if !crate::plot::font_available() {
        notes.push("Plots were not drawn: no TrueType font was found (install fonts-dejavu-core or set GLASSBAKE_FONT).".to_string());
    }
    match inputs.eval_dir.as_ref().filter(|d| d.join("metrics.json").exists()) {
        Some(eval_dir) => {
            let summary = EvaluationSummary::read(&eval_dir.join("metrics.json"))?;
            sections.push(metrics_section(&summary)?);
            sections.extend(image_sections(&summary, eval_dir)?);
        }
        None => notes.push("No evaluation yet (run `glassbake eval`).".into()),
    }
    sections.extend(training_section(&inputs.training_logs)?);
    if let Some(path) = inputs.bench.as_ref().filter(|p| p.exists()) {
        sections.push(bench_section(path)?);
    }

    // Markdown and PNG files.
    let mut head = format!("# {}\n\n", markdown::text(&inputs.title));
    for fact in &inputs.facts {
        let _ = writeln!(head, "- {}", markdown::text(fact));
    }
    let mut md = head.clone();
    for note in &notes {
        let _ = writeln!(md, "\n> {note}");
    }
    for section in &sections {
        let _ = write!(md, "\n## {}\n\n{}\n", section.heading, section.text);
        for f in &section.figures {
            write_bytes_atomically(&dir.join(&f.file), &f.png)?;
            let _ = writeln!(md, "![{}]({})\n", markdown::text(&f.title), f.file);
        }
    }
    write_bytes_atomically(&dir.join("report.md"), md.as_bytes())?;
    let index = dir.join("index.html");
    write_bytes_atomically(&index, report_html(&inputs.title, &head, &notes, &sections).as_bytes())?;
    Ok(index)
}
