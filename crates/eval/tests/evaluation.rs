//! An evaluation run on synthetic frames: per-frame and averaged metrics, metrics.json/csv,
//! grids, and a self-contained report.

use glassbake_eval::report::{write_report, BenchFile, BenchRow, ReportInputs, TrainingLog};
use glassbake_eval::{Evaluation, EvaluationSummary, OrderTest, RgbImage};

fn frame(w: usize, h: usize, level: f32) -> RgbImage {
    RgbImage::new(w, h, (0..w * h).map(|i| [level, ((i % w) as f32 / w as f32), 0.3]).collect()).unwrap()
}

#[test]
fn metrics_files_grids_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let eval_dir = dir.path().join("eval");
    let models = vec!["glassnet".to_string(), "naive".to_string()];
    let mut evaluation = Evaluation::new(&eval_dir, models, None, "data".into(), "test".into()).unwrap();
    let (w, h) = (24, 20);
    let truth = frame(w, h, 0.5);
    // Frame 7: glass on the left half; glassnet is off by 0.1 in red everywhere, naive by 0.2.
    let mask: Vec<bool> = (0..w * h).map(|i| i % w < w / 2).collect();
    let record = evaluation.add_frame(7, &truth, &mask, &[frame(w, h, 0.6), frame(w, h, 0.7)]).unwrap().clone();
    assert_eq!(record.transparent_pixels, w * h / 2);
    // MAE = 0.1 / 3 over all channels; T.MAE the same (uniform error).
    assert!((record.metrics[0].mae - 0.1 / 3.0).abs() < 1e-6);
    assert!((record.metrics[0].t_mae.unwrap() - 0.1 / 3.0).abs() < 1e-6);
    // PSNR = 10 log10(3 / 0.01) = 24.771 dB for glassnet, 10 log10(3 / 0.04) = 18.751 for naive.
    assert!((record.metrics[0].psnr - 24.771_21).abs() < 1e-3);
    assert!((record.metrics[1].psnr - 18.750_61).abs() < 1e-3);
    assert!(record.metrics[0].flip < record.metrics[1].flip);
    // Frame 8: no glass, exact match for glassnet.
    evaluation.add_frame(8, &truth, &vec![false; w * h], &[truth.clone(), frame(w, h, 0.7)]).unwrap();
    // Render times: glassnet timed on both frames, naive on none.
    evaluation.add_render_time(0, 0.25);
    evaluation.add_render_time(0, 0.75);
    evaluation.set_order_test(OrderTest { model: "glassnet".into(), frames: 2, reversed_max_abs_diff: 0.0, shuffled_max_abs_diff: 0.0 });
    let summary = evaluation.finish().unwrap();

    let g = &summary.models[0];
    assert_eq!((g.frames, g.t_frames), (2, 1));
    assert!((g.mae - 0.1 / 6.0).abs() < 1e-6, "mean of 0.1/3 and 0");
    assert!((g.psnr - (24.771_21 + 100.0) / 2.0).abs() < 1e-3, "an exact match counts as the 100 dB cap");
    assert!((g.t_psnr.unwrap() - 24.771_21).abs() < 1e-3, "T.PSNR only over the frame with glass");
    assert_eq!(g.lpips, None);
    assert_eq!(summary.lpips, "skipped: no weights");
    assert_eq!((g.seconds_per_frame, summary.models[1].seconds_per_frame), (Some(0.5), None));
    assert!(summary.text_table().lines().nth(1).unwrap().trim_end().ends_with("0.500"), "{}", summary.text_table());

    // Intervals over the two frames: PSNR's bootstrap means lie between the two frames'
    // values; naive's paired difference to GlassNet is the per-frame mean difference; T.PSNR
    // has one frame only, so no interval. Naive trails GlassNet on every frame: no warning.
    let psnr = g.intervals["psnr"];
    assert!(24.77 <= psnr.low && psnr.low <= psnr.mean && psnr.mean <= psnr.high && psnr.high <= 100.0, "{psnr:?}");
    assert!(!g.intervals.contains_key("t_psnr") && g.versus.is_none());
    let n = &summary.models[1];
    let versus = n.versus.as_ref().unwrap();
    assert_eq!(versus.reference, "glassnet");
    assert!((versus.differences["psnr"].mean - (n.psnr - g.psnr)).abs() < 1e-9);
    assert!(versus.differences["psnr"].below_zero());
    assert!(summary.not_leading().is_empty(), "{:?}", summary.not_leading());
    assert!(summary.markdown_differences().contains("| naive |"));

    // metrics.json reads back to the summary (to the last digit or so: serde_json's default
    // float parsing may differ from the written value in the last bit).
    let read = EvaluationSummary::read(&eval_dir.join("metrics.json")).unwrap();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(1.0);
    assert_eq!(read.models.len(), summary.models.len());
    for (r, m) in read.models.iter().zip(&summary.models) {
        assert_eq!((&r.model, r.frames, r.t_frames, r.lpips, r.seconds_per_frame), (&m.model, m.frames, m.t_frames, m.lpips, m.seconds_per_frame));
        assert_eq!(r.intervals.keys().collect::<Vec<_>>(), m.intervals.keys().collect::<Vec<_>>());
        assert_eq!(r.versus.as_ref().map(|v| &v.reference), m.versus.as_ref().map(|v| &v.reference));
        for (a, b) in [
            (r.mae, m.mae),
            (r.psnr, m.psnr),
            (r.dssim, m.dssim),
            (r.flip, m.flip),
            (r.t_mae.unwrap(), m.t_mae.unwrap()),
            (r.t_psnr.unwrap(), m.t_psnr.unwrap()),
        ] {
            assert!(close(a, b), "{a} vs {b}");
        }
    }
    let csv = std::fs::read_to_string(eval_dir.join("metrics.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 2 + 2, "{csv}");
    assert!(csv.lines().any(|l| l.starts_with("8,glassnet,0.000000,100.0000,") && l.contains(",,")), "{csv}");
    for file in ["grids/000007.png", "grids/000008.png", "frames/000007_ground_truth.png", "frames/000007_glassnet.png", "frames/000008_naive.png"] {
        assert!(eval_dir.join(file).is_file(), "{file}");
    }
    // A glass crop for the frame with glass only: ground truth + 2 models; the 24x20 frame's
    // 32 px window shrinks to 20 px, enlarged 7x to reach 128 px.
    assert!(!eval_dir.join("crops/000008.png").exists());
    let crop = image::open(eval_dir.join("crops/000007.png")).unwrap();
    assert_eq!((crop.width(), crop.height()), (3 * 140 + 2 * 4, 140));
    let grid = image::open(eval_dir.join("grids/000007.png")).unwrap();
    // ground truth, 2 models, 2 error maps, mask: 6 tiles of 24 px enlarged 6x, 4 px gaps.
    assert_eq!((grid.width(), grid.height()), (6 * 144 + 5 * 4, 120));

    let log = dir.path().join("train_log.csv");
    std::fs::write(&log, "step,epoch,learning_rate,train_loss,validation_loss,elapsed_s,validation_psnr\n1,0,1e-3,0.5,,0.1,\n2,0,1e-3,0.4,0.45,0.2,24.5\n3,0,1e-3,0.3,0.35,0.3,26.0\n").unwrap();
    // A log written before the PSNR column: its loss curves are still drawn.
    let old_log = dir.path().join("old_train_log.csv");
    std::fs::write(&old_log, "step,epoch,learning_rate,train_loss,validation_loss,elapsed_s\n1,0,1e-3,0.5,,0.1\n2,0,1e-3,0.4,0.45,0.2\n").unwrap();
    let bench = dir.path().join("bench.json");
    let rows = (1..=4)
        .map(|t| BenchRow {
            resolution: 64,
            objects: t,
            ms_per_frame: 10.0 + t as f64,
            fps: 1000.0 / (10.0 + t as f64),
            peak_ram_mib: Some(50.0),
            peak_gpu_mib: None,
        })
        .collect();
    std::fs::write(&bench, serde_json::to_string(&BenchFile { device: "cpu".into(), rows }).unwrap()).unwrap();
    let report_dir = dir.path().join("report");
    let index = write_report(
        &report_dir,
        &ReportInputs {
            title: "test <bake>".into(),
            facts: vec!["a fact".into()],
            eval_dir: Some(eval_dir.clone()),
            training_logs: vec![TrainingLog { name: "glassnet".into(), path: log }, TrainingLog { name: "naive".into(), path: old_log }],
            bench: Some(bench),
        },
    )
    .unwrap();
    let html = std::fs::read_to_string(&index).unwrap();
    assert!(html.contains("test &lt;bake&gt;") && html.contains("<table>") && html.contains("<td>glassnet</td>"));
    assert!(html.contains("data:image/png;base64,"), "grids are embedded");
    assert!(html.contains("bit-identical") && html.contains("<strong>Order test</strong>"));
    // Self-contained: nothing is fetched from anywhere.
    for external in ["src=\"http", "href=\"http", "src=\"/", "src=\"grids", "<link", "<script src"] {
        assert!(!html.contains(external), "{external}");
    }
    let md = std::fs::read_to_string(report_dir.join("report.md")).unwrap();
    assert!(md.contains("| glassnet |") && md.contains("![frame 7](grids/000007.png)"), "{md}");
    assert!(report_dir.join("grids/000007.png").is_file());
    assert!(md.contains("![frame 7, glass](crops/000007.png)") && report_dir.join("crops/000007.png").is_file(), "{md}");
    if glassbake_eval::plot::font_available() {
        assert!(html.contains("<svg"), "plots are inline SVG");
        assert!(html.contains("Validation PSNR over training time"));
        for png in ["metrics.png", "training_curves.png", "validation_psnr.png", "speed.png", "memory.png"] {
            assert!(image::open(report_dir.join(png)).is_ok(), "{png}");
        }
    } else {
        assert!(!resources_required(), "no TrueType font for the plots, and GLASSBAKE_TEST_RESOURCES=required");
        eprintln!("SKIPPED: no TrueType font: the report's plots are not tested here");
        assert!(html.contains("no TrueType font"));
    }
}

/// `.ci/run` sets GLASSBAKE_TEST_RESOURCES=required after installing what the tests need:
/// there a test must not skip for want of it.
fn resources_required() -> bool {
    std::env::var("GLASSBAKE_TEST_RESOURCES").is_ok_and(|v| v == "required")
}

/// When the first model does not lead a baseline (here it trails on every frame, and on a
/// second baseline the frames disagree), the summary says so in words, with the interval, and
/// the report carries the sentence; the noise-floor row is a reference and gets none.
#[test]
fn a_first_model_that_does_not_lead_is_said_to() {
    let dir = tempfile::tempdir().unwrap();
    let eval_dir = dir.path().join("eval");
    let models = ["glassnet", "naive", "concat", "gt-4spp"].map(String::from).to_vec();
    let mut evaluation = Evaluation::new(&eval_dir, models, None, "data".into(), "test".into()).unwrap();
    let (w, h) = (16, 16);
    let truth = frame(w, h, 0.5);
    let mask = vec![true; w * h];
    for (index, concat_level) in [(0, 0.55), (1, 0.7), (2, 0.52), (3, 0.75)] {
        let models = [frame(w, h, 0.6), frame(w, h, 0.55), frame(w, h, concat_level), frame(w, h, 0.51)];
        evaluation.add_frame(index, &truth, &mask, &models).unwrap();
    }
    let summary = evaluation.finish().unwrap();
    let sentences = summary.not_leading();
    assert!(sentences.iter().any(|s| s.starts_with("glassnet trails naive on PSNR")), "{sentences:?}");
    assert!(sentences.iter().any(|s| s.starts_with("glassnet does not lead concat on T.PSNR")), "{sentences:?}");
    assert!(!sentences.iter().any(|s| s.contains("gt-4spp")), "{sentences:?}");
    let report = dir.path().join("report");
    write_report(&report, &ReportInputs { title: "t".into(), facts: vec![], eval_dir: Some(eval_dir), training_logs: vec![], bench: None }).unwrap();
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    assert!(md.contains("**Warning:** glassnet trails naive on PSNR"), "{md}");
}
