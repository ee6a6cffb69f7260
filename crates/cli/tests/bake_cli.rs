//! `glassbake bake` and `glassbake eval` end to end on the tiny preset: every stage's outputs,
//! the order test, a second run that skips every stage, LPIPS from a weights file, bad input.

use std::path::Path;
use std::process::Command;

fn glassbake(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_glassbake")).args(args).output().unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A tiny AlexNet-shaped LPIPS weights file in the safetensors format (8-byte header length,
/// JSON header, little-endian f32 data), written by hand so the test needs no extra crate.
fn write_lpips_weights(file: &Path) {
    let channels = [3usize, 4, 5, 4, 3];
    let kernels = [11usize, 5, 3, 3, 3];
    let index = [0, 3, 6, 8, 10];
    let mut tensors: Vec<(String, Vec<usize>)> = Vec::new();
    let mut input = 3;
    for s in 0..5 {
        tensors.push((format!("features.{}.weight", index[s]), vec![channels[s], input, kernels[s], kernels[s]]));
        tensors.push((format!("features.{}.bias", index[s]), vec![channels[s]]));
        tensors.push((format!("lin{s}.model.1.weight"), vec![1, channels[s], 1, 1]));
        input = channels[s];
    }
    let mut header = serde_json::Map::new();
    let mut data: Vec<u8> = Vec::new();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for (name, shape) in &tensors {
        let n: usize = shape.iter().product();
        let fan_in: usize = shape.iter().skip(1).product();
        let start = data.len();
        for _ in 0..n {
            // A 64-bit LCG: uniform in [-1, 1), scaled like a trained layer (1 / sqrt(fan in)).
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let v = ((state >> 40) as f32 / (1u64 << 23) as f32 - 1.0) / (fan_in.max(1) as f32).sqrt();
            let v = if name.starts_with("lin") { v.abs() } else { v };
            data.extend_from_slice(&v.to_le_bytes());
        }
        header.insert(name.clone(), serde_json::json!({"dtype": "F32", "shape": shape, "data_offsets": [start, data.len()]}));
    }
    let header = serde_json::to_vec(&header).unwrap();
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend_from_slice(&header);
    bytes.extend_from_slice(&data);
    std::fs::write(file, bytes).unwrap();
}

/// What a trivial prediction scores against the clamped ground truth of the frames a bake
/// evaluated, averaged over frames as eval averages PSNR: (a black frame, the best constant
/// frame, each channel its own mean). A model or noise floor must beat both by a margin.
fn trivial_psnrs(bake: &Path, metrics: &serde_json::Value) -> (f64, f64) {
    let frames = metrics["frames"].as_array().unwrap();
    let (mut black, mut constant) = (0.0, 0.0);
    for frame in frames {
        let index = frame["index"].as_u64().unwrap();
        let truth = glassbake_core::PlanarImage::read_exr(&bake.join(format!("dataset/gt/{index:06}.exr"))).unwrap();
        let (mut squares, mut variance, mut count) = (0.0f64, 0.0f64, 0usize);
        for name in ["R", "G", "B"] {
            let plane: Vec<f64> = truth.plane_by_name(name).unwrap().iter().map(|&v| v.clamp(0.0, 1.0) as f64).collect();
            let mean = plane.iter().sum::<f64>() / plane.len() as f64;
            squares += plane.iter().map(|v| v * v).sum::<f64>();
            variance += plane.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
            count += plane.len();
        }
        black += 10.0 * (count as f64 / squares).log10();
        constant += 10.0 * (count as f64 / variance).log10();
    }
    (black / frames.len() as f64, constant / frames.len() as f64)
}

#[test]
fn bake_runs_every_stage_then_skips_them_and_eval_scores_with_lpips() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bake");
    // With the biased estimator, which the dataset records; the second run below, without
    // the flag, keeps it (a changed estimator would retrace every frame or be refused).
    let (code, stdout, err) =
        glassbake(&["bake", "cornell-glass", "--preset", "tiny", "--estimator", "caustic+merging+adaptive+stratified", "--out", path(&out)]);
    assert_eq!(code, 0, "{err}\n{stdout}");
    for file in [
        "dataset/manifest.json",
        "glassnet/glassnet.safetensors",
        "naive/glassnet.safetensors",
        "glassnet_choice.json",
        "eval/metrics.json",
        "eval/metrics.csv",
        "report/index.html",
        "report/report.md",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    // The bake ends with the metrics table, GlassNet against Naive.
    let table_at = stdout.find("model ").expect("a metrics table");
    assert!(stdout[table_at..].contains("glassnet") && stdout[table_at..].contains("naive"), "{stdout}");
    assert!(stdout.contains("order test (glassnet, 2 frames): max |difference| reversed 0, shuffled 0 (bit-identical)"), "{stdout}");
    let metrics: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("eval/metrics.json")).unwrap()).unwrap();
    // The two models, then the noise floor: the test split is traced at 8x the tiny preset's
    // 4 spp, and its 4-spp copy is scored against it.
    let rows: Vec<&str> = metrics["models"].as_array().unwrap().iter().map(|m| m["model"].as_str().unwrap()).collect();
    assert_eq!(rows, ["glassnet", "naive", "gt-4spp"]);
    assert!(metrics["models"][2]["seconds_per_frame"].is_null());
    let (black, constant) = trivial_psnrs(&out, &metrics);
    let psnr = |row: usize| metrics["models"][row]["psnr"].as_f64().unwrap();
    eprintln!("PSNR: black {black:.2}, best constant {constant:.2}, glassnet {:.2}, naive {:.2}, gt-4spp {:.2}", psnr(0), psnr(1), psnr(2));
    // Measured here: black 17.3, best constant 19.1, GlassNet 23.2, naive 22.0, noise floor
    // 27.3 dB. Even the tiny preset's networks learn the scene's structure, and a 4-spp
    // trace is far closer than any constant.
    for (row, margin) in [(0, 2.0), (1, 2.0), (2, 6.0)] {
        assert!(psnr(row) > constant + margin, "{}: PSNR {:.2} not {margin} dB above the best constant frame's {constant:.2}", rows[row], psnr(row));
    }
    assert!(stdout.contains("Noise floor (gt-4spp"), "{stdout}");
    let manifest: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("dataset/manifest.json")).unwrap()).unwrap();
    assert_eq!((manifest["spec"]["spp"].as_u64(), manifest["spec"]["test_spp"].as_u64()), (Some(4), Some(32)));
    assert_eq!(manifest["spec"]["estimator"], "caustic-merged");
    assert_eq!(metrics["order_test"]["reversed_max_abs_diff"], 0.0);
    assert_eq!(metrics["order_test"]["shuffled_max_abs_diff"], 0.0);
    assert_eq!(metrics["frames"].as_array().unwrap().len(), 2);

    // Again: every stage is done already.
    let (code, stdout, err) = glassbake(&["bake", "cornell-glass", "--preset", "tiny", "--out", path(&out)]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("0 frame(s) made") && stdout.matches("already trained").count() == 2 && stdout.contains("up to date"), "{stdout}");
    // The stage times of the run that did the work are kept for the report.
    let times: serde_json::Map<String, serde_json::Value> = serde_json::from_str(&std::fs::read_to_string(out.join("stage_times.json")).unwrap()).unwrap();
    assert_eq!(times.len(), 4, "{times:?}");
    assert!(times.contains_key("train glassnet, checked against naive on validation"), "{times:?}");
    let report = std::fs::read_to_string(out.join("report/report.md")).unwrap();
    assert!(report.contains("train glassnet, checked against naive on validation:") && report.contains("done earlier"), "{report}");

    // Killed after the metrics were written and before their report: evaluated again, so the
    // evaluation's report exists once more.
    std::fs::remove_dir_all(out.join("eval/report")).unwrap();
    let (code, stdout, err) = glassbake(&["bake", "cornell-glass", "--preset", "tiny", "--out", path(&out)]);
    assert_eq!(code, 0, "{err}");
    assert!(!stdout.contains("up to date") && out.join("eval/report/index.html").is_file(), "{stdout}");

    // eval on its own, with LPIPS weights.
    let weights = dir.path().join("lpips.safetensors");
    write_lpips_weights(&weights);
    let eval = dir.path().join("eval");
    let (code, stdout, err) =
        glassbake(&["eval", path(&out.join("glassnet")), path(&out.join("dataset")), "--out", path(&eval), "--lpips-weights", path(&weights)]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("LPIPS AlexNet weights from"), "{stdout}");
    let metrics: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(eval.join("metrics.json")).unwrap()).unwrap();
    assert!(metrics["models"][0]["lpips"].as_f64().unwrap() > 0.0);

    // Bad input: one line naming the culprit, exit code 2, nothing written.
    let (code, _, err) = glassbake(&[
        "eval",
        path(&out.join("glassnet")),
        path(&out.join("dataset")),
        "--out",
        path(&dir.path().join("e2")),
        "--lpips-weights",
        path(&dir.path().join("none.safetensors")),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("none.safetensors") && !dir.path().join("e2").exists(), "{err}");
    let (code, _, err) = glassbake(&["bake", "cornell-glass", "--preset", "huge", "--out", path(&dir.path().join("b2"))]);
    assert_eq!(code, 2);
    assert!(err.contains("--preset") && !dir.path().join("b2").exists(), "{err}");
    let (code, _, err) = glassbake(&["bake", "cornell-glass", "--preset", "tiny", "--estimator", "noisy", "--out", path(&dir.path().join("b3"))]);
    assert_eq!(code, 2);
    assert!(err.contains("--estimator") && err.contains("unknown transport") && !dir.path().join("b3").exists(), "{err}");
    let (code, _, err) =
        glassbake(&["bake", "cornell-glass", "--preset", "tiny", "--device", "wgpu", "--estimator", "caustic-merged", "--out", path(&dir.path().join("b4"))]);
    assert_eq!(code, 2);
    assert!(err.contains("--estimator") && err.contains("CPU only") && !dir.path().join("b4").exists(), "{err}");
}

#[test]
fn eval_refuses_a_model_of_another_scene() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bake");
    let (code, _, err) = glassbake(&["bake", "cornell-glass", "--preset", "tiny", "--out", path(&out)]);
    assert_eq!(code, 0, "{err}");
    let other = dir.path().join("other");
    let (code, _, err) = glassbake(&[
        "dataset",
        "cornellbox",
        "--out",
        path(&other),
        "--train",
        "1",
        "--val",
        "1",
        "--test",
        "1",
        "--res",
        "32",
        "--spp",
        "2",
        "--cache-buffers",
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = glassbake(&["eval", path(&out.join("glassnet")), path(&other), "--out", path(&dir.path().join("e"))]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("config.json") && err.contains("scene_hash"), "{err}");
    // No frames is refused up front, not written as metrics nobody can read back.
    let empty = dir.path().join("empty");
    let (code, _, err) = glassbake(&["eval", path(&out.join("glassnet")), path(&out.join("dataset")), "--frames", "0", "--out", path(&empty)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--frames") && !empty.join("metrics.json").exists(), "{err}");
}

#[test]
fn ablations_are_trained_with_their_settings_and_evaluated() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bake");
    let (code, stdout, err) = glassbake(&["bake", "cornell-glass", "--preset", "tiny", "--ablations", "--seed", "3", "--out", path(&out)]);
    assert_eq!(code, 0, "{err}");
    let config = |name: &str| -> serde_json::Value { serde_json::from_str(&std::fs::read_to_string(out.join(name).join("config.json")).unwrap()).unwrap() };
    // Every network is seeded with --seed; GlassNet's first, and the one shipped is the choice's.
    for name in ["naive", "glassnet-no-encoding", "glassnet-l1-only"] {
        assert_eq!(config(name)["train"]["seed"], 3, "{name}");
    }
    let choice: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("glassnet_choice.json")).unwrap()).unwrap();
    assert_eq!(choice["candidates"][0]["seed"], 3);
    assert_eq!(config("glassnet")["train"]["seed"], choice["shipped_seed"]);
    assert_eq!(config("glassnet")["network"]["encoding_frequencies"], 2);
    assert_eq!(config("glassnet-no-encoding")["network"]["encoding_frequencies"], 0);
    assert_eq!(config("glassnet")["train"]["ssim_weight"], 1.0);
    assert_eq!(config("glassnet-l1-only")["train"]["ssim_weight"], 0.0);
    assert_eq!(config("glassnet-l1-only")["network"]["encoding_frequencies"], 2);
    let metrics: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("eval/metrics.json")).unwrap()).unwrap();
    let models: Vec<&str> = metrics["models"].as_array().unwrap().iter().map(|m| m["model"].as_str().unwrap()).collect();
    assert_eq!(models, ["glassnet", "naive", "glassnet-no-encoding", "glassnet-l1-only", "gt-4spp"]);
    assert!(stdout.contains("glassnet-l1-only"), "{stdout}");

    let (code, _, err) = glassbake(&["train", path(&out.join("dataset")), "--ablation", "no-ssim", "--preset", "tiny", "--out", path(&dir.path().join("x"))]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--ablation") && err.contains("l1-only"), "{err}");

    // The naive baseline given the front-most through buffer trains (fed every object's
    // buffers: the model refuses to run without them) and is scored; GlassNet has no such
    // ablation.
    let front = dir.path().join("naive-front-through");
    let (code, _, err) =
        glassbake(&["train", path(&out.join("dataset")), "--model", "naive", "--ablation", "front-through", "--preset", "tiny", "--out", path(&front)]);
    assert_eq!(code, 0, "{err}");
    let front_config: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(front.join("config.json")).unwrap()).unwrap();
    assert_eq!((&front_config["network"]["model"], &front_config["network"]["through"]), (&"naive".into(), &true.into()));
    let scores = dir.path().join("front-eval");
    let (code, _, err) = glassbake(&["eval", path(&out.join("naive")), path(&front), path(&out.join("dataset")), "--out", path(&scores)]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) =
        glassbake(&["train", path(&out.join("dataset")), "--ablation", "front-through", "--preset", "tiny", "--out", path(&dir.path().join("y"))]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("front-through") && err.contains("naive"), "{err}");

    // GlassNet without the through buffers trains and reads none; the naive baseline has no
    // such ablation.
    let without = dir.path().join("glassnet-no-through");
    let (code, _, err) = glassbake(&["train", path(&out.join("dataset")), "--ablation", "no-through", "--preset", "tiny", "--out", path(&without)]);
    assert_eq!(code, 0, "{err}");
    let without_config: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(without.join("config.json")).unwrap()).unwrap();
    assert_eq!((&without_config["network"]["model"], &without_config["network"]["through"]), (&"glassnet".into(), &false.into()));
    let glassnet_config: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("glassnet/config.json")).unwrap()).unwrap();
    assert_eq!(glassnet_config["network"]["through"], true, "the ablation differs from GlassNet in its through buffers");
    let naive_without = dir.path().join("z");
    let (code, _, err) =
        glassbake(&["train", path(&out.join("dataset")), "--model", "naive", "--ablation", "no-through", "--preset", "tiny", "--out", path(&naive_without)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no-through") && err.contains("GlassNet"), "{err}");
}

#[test]
fn baselines_pixelgen_and_path_tracing_plus_denoising() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bake");
    let (code, stdout, err) = glassbake(&["bake", "cornell-glass", "--preset", "tiny", "--baselines", "--out", path(&out)]);
    if cfg!(feature = "oidn") {
        assert_eq!(code, 0, "{err}\n{stdout}");
        let metrics: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("eval/metrics.json")).unwrap()).unwrap();
        let models: Vec<&str> = metrics["models"].as_array().unwrap().iter().map(|m| m["model"].as_str().unwrap()).collect();
        assert_eq!(models, ["glassnet", "naive", "pixelgen", "pt32", "pt32+oidn", "gt-4spp"]);
        let (black, constant) = trivial_psnrs(&out, &metrics);
        for m in &metrics["models"].as_array().unwrap()[..5] {
            assert!(m["seconds_per_frame"].as_f64().unwrap() > 0.0, "{m}");
            // The networks beat a black frame; a 32-spp path trace, raw or denoised, is far
            // closer than any constant frame.
            let bound = if m["model"].as_str().unwrap().starts_with("pt") { constant + 6.0 } else { black };
            assert!(m["psnr"].as_f64().unwrap() > bound, "{m}: PSNR not above {bound:.2}");
        }
        // Denoising takes the path tracer's time plus its own.
        let seconds = |i: usize| metrics["models"][i]["seconds_per_frame"].as_f64().unwrap();
        assert!(seconds(4) > seconds(3));
        let pixelgen: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("pixelgen/config.json")).unwrap()).unwrap();
        assert_eq!(pixelgen["network"]["model"], "pixelgen");
        let frames: Vec<String> = std::fs::read_dir(out.join("eval/frames")).unwrap().map(|f| f.unwrap().file_name().to_string_lossy().into_owned()).collect();
        assert_eq!(frames.iter().filter(|f| f.ends_with("_pt32+oidn.png")).count(), 2, "{frames:?}");
        assert!(std::fs::read_dir(out.join("eval/crops")).unwrap().count() > 0, "glass crops");
        return;
    }
    // Without the feature: refused up front, naming it, nothing written.
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("`oidn` feature") && err.contains("pip install pyoidn"), "{err}");
    assert!(!out.exists());

    // pixelgen trains and evaluates on its own, with a time per frame.
    let data = dir.path().join("data");
    let (code, _, err) = glassbake(&[
        "dataset",
        "cornell-glass",
        "--out",
        path(&data),
        "--train",
        "2",
        "--val",
        "1",
        "--test",
        "2",
        "--res",
        "32",
        "--spp",
        "2",
        "--cache-buffers",
    ]);
    assert_eq!(code, 0, "{err}");
    let model = dir.path().join("pixelgen");
    let (code, stdout, err) = glassbake(&["train", path(&data), "--model", "pixelgen", "--preset", "tiny", "--out", path(&model)]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("training pixelgen"), "{stdout}");
    let eval = dir.path().join("eval");
    let (code, _, err) = glassbake(&["eval", path(&model), path(&data), "--out", path(&eval)]);
    assert_eq!(code, 0, "{err}");
    let metrics: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(eval.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(metrics["models"][0]["model"], "pixelgen");
    assert!(metrics["models"][0]["seconds_per_frame"].as_f64().unwrap() > 0.0);
    let (code, _, err) = glassbake(&["eval", path(&model), path(&data), "--out", path(&dir.path().join("e2")), "--path-traced-baseline", "32"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--path-traced-baseline") && err.contains("`oidn` feature") && !dir.path().join("e2").exists(), "{err}");
}
