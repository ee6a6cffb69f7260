//! `glassbake train` and `train-sr` end to end on a tiny dataset: model directory contents,
//! previews, resume of a finished run, super-sampler and its evaluation, and bad input.

use std::path::Path;
use std::process::Command;

fn glassbake(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_glassbake")).args(args).output().unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn trains_resumes_super_samples_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let (code, _, err) = glassbake(&[
        "dataset",
        "cornell-glass",
        "--out",
        path(&data),
        "--train",
        "3",
        "--val",
        "1",
        "--test",
        "0",
        "--res",
        "16",
        "--spp",
        "4",
        "--cache-buffers",
    ]);
    assert_eq!(code, 0, "{err}");

    let model = dir.path().join("model");
    let (code, out, err) = glassbake(&["train", path(&data), "--model", "glassnet", "--preset", "tiny", "--steps", "6", "--out", path(&model)]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("trained 6 steps"), "{out}");
    for file in ["config.json", "glassnet.safetensors", "train_log.csv", "checkpoint/state.json", "preview/val_003.png"] {
        assert!(model.join(file).is_file(), "{file} missing");
    }
    let config: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(model.join("config.json")).unwrap()).unwrap();
    assert_eq!(config["network"]["kind"], "glassnet");
    assert_eq!(config["network"]["transparent_objects"], 1);

    // The same command again: already trained, nothing retrained.
    let (code, out, _) = glassbake(&["train", path(&data), "--model", "glassnet", "--preset", "tiny", "--steps", "6", "--out", path(&model)]);
    assert_eq!(code, 0);
    assert!(out.contains("already trained"), "{out}");
    // Different settings into the same directory are refused, naming config.json.
    let (code, _, err) = glassbake(&["train", path(&data), "--model", "glassnet", "--preset", "tiny", "--steps", "7", "--out", path(&model)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("config.json"), "{err}");

    let sr = dir.path().join("sr");
    let (code, out, err) = glassbake(&["train-sr", path(&data), "--glassnet", path(&model), "--preset", "tiny", "--steps", "3", "--out", path(&sr)]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("trained 3 steps") && sr.join("super_sampler.safetensors").is_file(), "{out}");

    // eval scores the super-sampler: GlassNet at half resolution brought up by it and
    // bilinearly, beside GlassNet at full resolution.
    let eval = dir.path().join("eval");
    let (code, _, err) = glassbake(&["eval", path(&model), path(&data), "--split", "val", "--super-sampler", path(&sr), "--out", path(&eval)]);
    assert_eq!(code, 0, "{err}");
    let metrics: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(eval.join("metrics.json")).unwrap()).unwrap();
    let rows: Vec<(String, f64)> =
        metrics["models"].as_array().unwrap().iter().map(|m| (m["model"].as_str().unwrap().to_string(), m["psnr"].as_f64().unwrap())).collect();
    let names: Vec<&str> = rows.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(names, ["model", "model@half+sr", "model@half+bilinear"], "{rows:?}");
    assert!(rows.iter().all(|(_, psnr)| psnr.is_finite()), "{rows:?}");
    assert_ne!(rows[1].1, rows[2].1, "the super-sampled and the bilinear rows are different images");
    // A GlassNet directory where the super-sampler belongs is refused, naming it.
    let (code, _, err) = glassbake(&["eval", path(&model), path(&data), "--split", "val", "--super-sampler", path(&model), "--out", path(&eval)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("not a super-sampler"), "{err}");

    let (code, _, err) = glassbake(&["train", path(&data), "--model", "transformer", "--out", path(&dir.path().join("x"))]);
    assert_eq!(code, 2);
    assert!(err.contains("--model") && err.lines().count() == 1, "{err}");
    assert!(!dir.path().join("x").exists(), "nothing may be written for bad input");
}
