//! `glassbake trace` as a user runs it: EXR + PNG out, deterministic whatever the thread
//! count, exit code 2 and nothing written on bad input.

use std::path::Path;
use std::process::Command;

use glassbake_core::PlanarImage;

fn glassbake(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_glassbake")).args(args).output().unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

/// `glassbake trace cornell-glass` at 12x12, 2 spp unless `extra` says otherwise.
fn trace(out: &Path, extra: &[&str]) -> (i32, String, String) {
    let mut args = vec!["trace", "cornell-glass", "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    for (flag, default) in [("--res", "12"), ("--spp", "2")] {
        if !extra.contains(&flag) {
            args.extend_from_slice(&[flag, default]);
        }
    }
    glassbake(&args)
}

/// An EXR's R, G, B planes in that order (EXR files keep channels sorted by name).
fn read_rgb(path: &Path) -> PlanarImage {
    let rgb = ["R", "G", "B"].map(String::from);
    PlanarImage::read_exr(path).unwrap().select(&rgb).unwrap()
}

#[test]
fn trace_writes_an_rgb_exr_and_a_png_preview_deterministically() {
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("nested/one.exr");
    let (code, stdout, err) = trace(&one, &["--sample", "3", "--threads", "1"]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("one.exr") && stdout.contains("one.png"), "{stdout}");
    assert!(one.with_extension("png").is_file());
    let mut channels = PlanarImage::read_exr(&one).unwrap().channels().to_vec();
    channels.sort();
    assert_eq!(channels, ["B", "G", "R"]);
    let image = read_rgb(&one);
    assert_eq!((image.width(), image.height()), (12, 12));
    assert!(image.data().iter().all(|v| v.is_finite() && *v >= 0.0));
    assert!(image.data().iter().any(|&v| v > 0.0));

    let two = dir.path().join("two.exr");
    let (code, _, err) = trace(&two, &["--sample", "3", "--threads", "2"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(read_rgb(&two), image, "thread count changed the image");

    let other = dir.path().join("other.exr");
    let (code, _, err) = trace(&other, &["--camera", "0,1,3.5,0,0.9,0,45", "--set", "pane_x=0.2"]);
    assert_eq!(code, 0, "{err}");
    assert_ne!(read_rgb(&other), image);

    // --image-seed re-traces the same sample with other random numbers, reproducibly.
    let reseeded: Vec<PlanarImage> = ["a.exr", "b.exr"]
        .iter()
        .map(|name| {
            let path = dir.path().join(name);
            let (code, _, err) = trace(&path, &["--sample", "3", "--image-seed", "9"]);
            assert_eq!(code, 0, "{err}");
            read_rgb(&path)
        })
        .collect();
    assert_eq!(reseeded[0], reseeded[1]);
    assert_ne!(reseeded[0], image);
}

#[test]
fn bad_input_exits_2_with_one_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    for extra in [
        &["--spp", "0"][..],
        &["--res", "0"][..],
        &["--camera", "1,2,3"][..],
        &["--set", "no_such_variable=1"][..],
        &["--set", "pane_x=7"][..],
        // Glass pixels get at least --spp samples.
        &["--spp", "4", "--glass-spp", "2"][..],
    ] {
        let (code, stdout, err) = trace(&out, extra);
        assert_eq!(code, 2, "{extra:?}: {err}");
        assert!(stdout.is_empty(), "{extra:?}: {stdout}");
        assert_eq!(err.lines().count(), 1, "{extra:?}: {err}");
        assert!(!out.exists() && !out.with_extension("png").exists(), "{extra:?} wrote output");
    }
    // An unknown value is refused by the argument parser (its message has a usage hint).
    for (estimator, says) in [("guided", "unknown transport"), ("caustic+sideways", "unknown option"), ("plain+merging", "caustic transport")] {
        let (code, _, err) = trace(&out, &["--estimator", estimator]);
        assert_eq!(code, 2, "{err}");
        assert!(err.contains(says) && !out.exists(), "{estimator}: {err}");
    }
}

#[test]
fn trace_on_the_gpu_is_deterministic_and_refuses_cpu_only_estimators() {
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("gpu-one.exr");
    let (code, stdout, err) = trace(&one, &["--sample", "3", "--spp", "8", "--device", "wgpu"]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("gpu-one.exr") && one.with_extension("png").is_file(), "{stdout}");
    let image = read_rgb(&one);
    assert_eq!((image.width(), image.height()), (12, 12));
    assert!(image.data().iter().all(|v| v.is_finite() && *v >= 0.0) && image.data().iter().any(|&v| v > 0.0));
    let two = dir.path().join("gpu-two.exr");
    let (code, _, err) = trace(&two, &["--sample", "3", "--spp", "8", "--device", "wgpu"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(read_rgb(&two), image, "two GPU traces of one sample differ");

    for cpu_only in ["caustic", "plain+adaptive", "plain+stratified"] {
        let path = dir.path().join("cpu-only.exr");
        let (code, stdout, err) = trace(&path, &["--estimator", cpu_only, "--device", "wgpu"]);
        assert_eq!(code, 2, "{cpu_only}: {err}");
        assert!(stdout.is_empty() && err.lines().count() == 1 && err.contains("CPU only"), "{cpu_only}: {err}");
        assert!(!path.exists() && !path.with_extension("png").exists());
    }
}

/// Without --estimator the CPU traces with the ground truth's default,
/// `caustic+adaptive+stratified`, and each of its options changes the image.
#[test]
fn the_cpu_traces_with_the_default_estimator_unless_told() {
    let dir = tempfile::tempdir().unwrap();
    let traced = |name: &str, extra: &[&str]| {
        let path = dir.path().join(name);
        let mut args = vec!["--sample", "1", "--spp", "256"];
        args.extend_from_slice(extra);
        let (code, _, err) = trace(&path, &args);
        assert_eq!(code, 0, "{extra:?}: {err}");
        read_rgb(&path)
    };
    let default = traced("default.exr", &[]);
    assert_eq!(default, traced("named.exr", &["--estimator", "caustic+adaptive+stratified"]));
    assert_eq!(default, traced("reordered.exr", &["--estimator", "caustic+stratified+adaptive"]));
    assert_ne!(default, traced("uniform.exr", &["--estimator", "caustic+stratified"]));
    assert_ne!(default, traced("independent.exr", &["--estimator", "caustic+adaptive"]));
    assert_ne!(default, traced("plain.exr", &["--estimator", "plain+adaptive+stratified"]));
}
