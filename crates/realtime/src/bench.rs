//! The real-time benchmark: frame time and peak memory over resolutions x transparent-object
//! counts, laid out as the paper's Table 4.

use std::fmt::Write as _;

use glassbake_core::Result;
use glassbake_rays::gpu_stats::GpuStats;
use serde::{Deserialize, Serialize};

use crate::memory::{peak_rss_mib, reset_peak_rss};
use crate::pipeline::{FramePipeline, Output};
use crate::synth::with_transparent_count;

#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub resolutions: Vec<u32>,
    pub objects: Vec<usize>,
    /// Frames rendered and discarded before timing each configuration.
    pub warmup: usize,
    /// Timed frames per configuration (the median is reported).
    pub frames: usize,
    /// Seed of the cameras and values (the scene's sampling ranges; one per frame).
    pub seed: u64,
    /// Hold the variables at the first frame's values and move only the camera, as a viewer
    /// orbiting a still scene does (what is built per variable value is then built once).
    pub camera_only: bool,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchRow {
    pub resolution: u32,
    pub objects: usize,
    /// Median wall time of a whole frame.
    pub ms_per_frame: f64,
    pub fps: f64,
    /// Medians of the frame's rasterizer and network parts.
    pub raster_ms: f64,
    /// The through buffers' refracted rays (0 for a model that does not read them).
    #[serde(default)]
    pub through_ms: f64,
    pub network_ms: f64,
    /// Fastest and slowest timed frame.
    pub min_ms: f64,
    pub max_ms: f64,
    /// Peak resident memory of the process while this configuration ran (MiB).
    pub peak_ram_mib: Option<f64>,
    /// Peak GPU memory (MiB) where the backend reports it.
    pub peak_gpu_mib: Option<f64>,
    /// wgpu objects glassbake's passes created per timed frame (`gpu_stats`; burn's runtime's
    /// are not counted here).
    #[serde(default)]
    pub gpu_objects_per_frame: f64,
    /// Times per timed frame the host waited for the GPU (the image's read-back counted).
    #[serde(default)]
    pub host_waits_per_frame: f64,
    /// How many more wgpu objects were alive on the device after the timed frames than
    /// before them (every user's, from wgpu's counters): above 0, something leaks.
    #[serde(default)]
    pub live_gpu_objects_growth: i64,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchReport {
    /// The network's device and the rasterizer's adapter.
    pub device: String,
    pub model: String,
    pub super_sampler: bool,
    pub warmup: usize,
    pub frames: usize,
    pub rows: Vec<BenchRow>,
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// Runs every (resolution, objects) configuration; `progress(done, total)` after each frame.
pub fn run_bench(pipeline: &mut FramePipeline, device: &str, options: &BenchOptions, progress: &dyn Fn(usize, usize)) -> Result<BenchReport> {
    let base = pipeline.scene.clone();
    let total = options.resolutions.len() * options.objects.len() * (options.warmup + options.frames);
    let mut done = 0;
    let mut rows = Vec::new();
    for &resolution in &options.resolutions {
        for &objects in &options.objects {
            pipeline.set_scene(with_transparent_count(&base, objects)?);
            let mut totals = Vec::new();
            let mut raster = Vec::new();
            let mut through = Vec::new();
            let mut network = Vec::new();
            let (mut gpu_before, mut live_before) = (GpuStats::now(), pipeline.live_gpu_objects());
            for i in 0..options.warmup + options.frames {
                if i == options.warmup {
                    // Measure what the timed frames need, not what earlier configurations left.
                    reset_peak_rss();
                    (gpu_before, live_before) = (GpuStats::now(), pipeline.live_gpu_objects());
                }
                let sample = base.sample(options.seed, i as u64);
                let values = if options.camera_only { base.sample(options.seed, 0).values } else { sample.values };
                let (_, times) = pipeline.render(&sample.camera, &values, resolution, resolution, &Output::GlassNet)?;
                if i >= options.warmup {
                    totals.push(times.total_ms);
                    raster.push(times.raster_ms);
                    through.push(times.through_ms);
                    network.push(times.network_ms);
                }
                done += 1;
                progress(done, total);
            }
            let peak = peak_rss_mib();
            let gpu = GpuStats::now().since(&gpu_before);
            let per_frame = |count: u64| count as f64 / options.frames.max(1) as f64;
            let ms_per_frame = median(&mut totals);
            rows.push(BenchRow {
                resolution,
                objects,
                ms_per_frame,
                fps: 1000.0 / ms_per_frame,
                raster_ms: median(&mut raster),
                through_ms: median(&mut through),
                network_ms: median(&mut network),
                min_ms: totals.first().copied().unwrap_or(f64::NAN),
                max_ms: totals.last().copied().unwrap_or(f64::NAN),
                peak_ram_mib: peak,
                peak_gpu_mib: None,
                gpu_objects_per_frame: per_frame(gpu.objects()),
                host_waits_per_frame: per_frame(gpu.host_waits),
                live_gpu_objects_growth: pipeline.live_gpu_objects() - live_before,
            });
        }
    }
    pipeline.set_scene(base);
    Ok(BenchReport {
        device: format!("{device}; rasterizer on {}", pipeline.adapter_name()),
        model: pipeline.glassnet.files.dir.display().to_string(),
        super_sampler: pipeline.super_sampler.is_some(),
        warmup: options.warmup,
        frames: options.frames,
        rows,
    })
}

/// What a run of the benchmark measures on: the network's device, the cores, where the
/// through rays are cast, and whether only the camera moves.
pub fn describe_run(pipeline: &FramePipeline, network_device: &str, camera_only: bool) -> String {
    let host = pipeline.zero_copy() && !pipeline.glassnet_frames_zero_copy();
    format!(
        "network on {network_device} ({} cores), through rays on the {}{}{}",
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        pipeline.through_rays().name(),
        if host { " (so GlassNet's buffers go through host memory)" } else { "" },
        if camera_only { "; the camera moves, the variables stay" } else { "" }
    )
}

impl BenchReport {
    /// The line above the table: where, how many frames, which model.
    pub fn heading(&self) -> String {
        let sampler = if self.super_sampler { ", with the x2 super-sampler" } else { "" };
        format!("{}: median of {} frames after {} warm-up, {}{sampler}", self.device, self.frames, self.warmup, self.model)
    }
}

/// Least-squares slope of ms per frame against the object count, per resolution.
pub fn marginal_ms_per_object(report: &BenchReport, resolution: u32) -> Option<f64> {
    marginal_per_object(report, resolution, |r| r.ms_per_frame)
}

/// Least-squares slope of the through rays' ms per frame against the object count, per
/// resolution: what casting one more object's through buffer costs.
pub fn marginal_through_ms_per_object(report: &BenchReport, resolution: u32) -> Option<f64> {
    marginal_per_object(report, resolution, |r| r.through_ms)
}

fn marginal_per_object(report: &BenchReport, resolution: u32, value: impl Fn(&BenchRow) -> f64) -> Option<f64> {
    let points: Vec<(f64, f64)> = report.rows.iter().filter(|r| r.resolution == resolution).map(|r| (r.objects as f64, value(r))).collect();
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    (sxx > 0.0).then(|| points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / sxx)
}

/// How one table row shows a configuration.
type CellFormat = Box<dyn Fn(&BenchRow) -> String>;

/// The paper's Table 4 layout: per resolution an FPS row and a frame-time row over the object
/// counts, then peak memory and the marginal cost of one more object.
pub fn table(report: &BenchReport) -> String {
    let mut counts: Vec<usize> = report.rows.iter().map(|r| r.objects).collect();
    counts.sort_unstable();
    counts.dedup();
    let mut resolutions: Vec<u32> = report.rows.iter().map(|r| r.resolution).collect();
    resolutions.dedup();
    let row = |res: u32, t: usize| report.rows.iter().find(|r| r.resolution == res && r.objects == t);
    let mut out = format!("{:<10} {:<22}", "size", "# transparent objects");
    for t in &counts {
        let _ = write!(out, " {t:>9}");
    }
    out.push('\n');
    for res in resolutions {
        let size = format!("{res}x{res}");
        let lines: [(&str, CellFormat); 9] = [
            ("framerate (FPS)", Box::new(|r: &BenchRow| format!("{:.1}", r.fps))),
            ("frame time (ms)", Box::new(|r: &BenchRow| format!("{:.1}", r.ms_per_frame))),
            ("  raster (ms)", Box::new(|r: &BenchRow| format!("{:.1}", r.raster_ms))),
            ("  through rays (ms)", Box::new(|r: &BenchRow| format!("{:.1}", r.through_ms))),
            ("  network (ms)", Box::new(|r: &BenchRow| format!("{:.1}", r.network_ms))),
            ("peak RAM (MiB)", Box::new(|r: &BenchRow| r.peak_ram_mib.map(|v| format!("{v:.0}")).unwrap_or_else(|| "-".into()))),
            ("GPU objects made/frame", Box::new(|r: &BenchRow| format!("{:.1}", r.gpu_objects_per_frame))),
            ("host waits/frame", Box::new(|r: &BenchRow| format!("{:.1}", r.host_waits_per_frame))),
            ("live wgpu objects +/-", Box::new(|r: &BenchRow| format!("{:+}", r.live_gpu_objects_growth))),
        ];
        for (i, (name, cell)) in lines.iter().enumerate() {
            let _ = write!(out, "{:<10} {:<22}", if i == 0 { size.as_str() } else { "" }, name);
            for &t in &counts {
                let _ = write!(out, " {:>9}", row(res, t).map(cell).unwrap_or_else(|| "-".into()));
            }
            out.push('\n');
        }
        if let Some(slope) = marginal_ms_per_object(report, res) {
            let _ = writeln!(out, "{:<10} {:<22} {slope:+.2} ms per extra object (least squares)", "", "marginal cost");
        }
        let casts = report.rows.iter().any(|r| r.resolution == res && r.through_ms > 0.0);
        if let Some(slope) = marginal_through_ms_per_object(report, res).filter(|_| casts) {
            let _ = writeln!(out, "{:<10} {:<22} {slope:+.2} ms per extra object", "", "  of it, through rays");
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(res: u32, objects: usize, ms: f64) -> BenchRow {
        BenchRow {
            resolution: res,
            objects,
            ms_per_frame: ms,
            fps: 1000.0 / ms,
            raster_ms: 1.0,
            through_ms: 0.5,
            network_ms: ms - 1.5,
            min_ms: ms,
            max_ms: ms,
            peak_ram_mib: Some(100.0),
            peak_gpu_mib: None,
            gpu_objects_per_frame: 0.0,
            host_waits_per_frame: 1.0,
            live_gpu_objects_growth: 0,
        }
    }

    #[test]
    fn median_and_slope() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
        // The paper's 512^2 frame times (20, 27, 31, 43 ms at t = 1, 2, 4, 8): slope 88.25 / 28.75 = 3.07 ms.
        let report = BenchReport {
            device: "d".into(),
            model: "m".into(),
            super_sampler: false,
            warmup: 0,
            frames: 1,
            rows: vec![row(512, 1, 20.0), row(512, 2, 27.0), row(512, 4, 31.0), row(512, 8, 43.0)],
        };
        let slope = marginal_ms_per_object(&report, 512).unwrap();
        assert!((slope - 88.25 / 28.75).abs() < 1e-9, "{slope}");
        let text = table(&report);
        assert!(text.contains("512x512") && text.contains("50.0") && text.contains("+3.07 ms per extra object"), "{text}");
        // The through rays' own slope: 10 ms per object.
        let mut through = report.clone();
        for r in &mut through.rows {
            r.through_ms = 10.0 * r.objects as f64;
        }
        assert!((marginal_through_ms_per_object(&through, 512).unwrap() - 10.0).abs() < 1e-9);
        assert!(table(&through).contains("through rays") && table(&through).contains("+10.00 ms per extra object"), "{}", table(&through));
    }
}
