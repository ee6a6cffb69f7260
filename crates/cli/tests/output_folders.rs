//! One rule for every folder a command writes: new, empty, or one glassbake made for the same
//! kind of output. Every command that writes a folder is pointed at a folder of the user's own
//! files and at a glassbake folder of another kind: each exits 2 naming the folder, and leaves
//! it exactly as it was. Bad arguments are refused before anything is written.

use std::path::Path;
use std::process::Command;

mod common;

fn glassbake(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_glassbake")).args(args).output().unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stderr).into())
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn tiny_dataset(scene: &str, out: &Path) {
    let (code, err) = glassbake(&[
        "dataset",
        scene,
        "--out",
        path(out),
        "--train",
        "2",
        "--val",
        "1",
        "--test",
        "1",
        "--res",
        "16",
        "--spp",
        "2",
        "--test-spp",
        "2",
        "--cache-buffers",
    ]);
    assert_eq!(code, 0, "{err}");
}

#[test]
fn every_command_refuses_a_folder_it_did_not_make() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    tiny_dataset("cornell-glass", &data);
    let model = dir.path().join("model");
    let (code, err) = glassbake(&["train", path(&data), "--preset", "tiny", "--steps", "2", "--out", path(&model)]);
    assert_eq!(code, 0, "{err}");
    let evaluation = dir.path().join("eval");
    let (code, err) = glassbake(&["eval", path(&model), path(&data), "--out", path(&evaluation)]);
    assert_eq!(code, 0, "{err}");

    // The user's folder: a file with a name of their own, and one with a name glassbake writes.
    let user = dir.path().join("mine");
    std::fs::create_dir(&user).unwrap();
    std::fs::write(user.join("notes.txt"), b"my notes").unwrap();
    std::fs::write(user.join("metrics.csv"), b"my metrics").unwrap();

    let commands = |out: &Path| -> Vec<(&'static str, Vec<String>)> {
        let o = path(out).to_string();
        let (d, m) = (path(&data).to_string(), path(&model).to_string());
        vec![
            ("dataset", vec!["dataset".into(), "cornell-glass".into(), "--out".into(), o.clone(), "--train".into(), "1".into(), "--res".into(), "16".into()]),
            ("train", vec!["train".into(), d.clone(), "--preset".into(), "tiny".into(), "--steps".into(), "2".into(), "--out".into(), o.clone()]),
            (
                "train-sr",
                vec![
                    "train-sr".into(),
                    d.clone(),
                    "--glassnet".into(),
                    m.clone(),
                    "--preset".into(),
                    "tiny".into(),
                    "--steps".into(),
                    "2".into(),
                    "--out".into(),
                    o.clone(),
                ],
            ),
            ("eval", vec!["eval".into(), m.clone(), d.clone(), "--out".into(), o.clone()]),
            ("bake", vec!["bake".into(), "cornell-glass".into(), "--preset".into(), "tiny".into(), "--out".into(), o]),
        ]
    };
    for (target, what) in [(&user, "the user's folder"), (&model, "a model directory"), (&evaluation, "an evaluation")] {
        let before = common::snapshot(target);
        for (command, args) in commands(target) {
            let own_kind = (command == "train" && target == &model) || (command == "eval" && target == &evaluation);
            if own_kind {
                continue;
            }
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let (code, err) = glassbake(&args);
            assert_eq!(code, 2, "{command} into {what}: {err}");
            assert!(err.contains(path(target)), "{command} into {what} should name the folder: {err}");
            assert_eq!(common::snapshot(target), before, "{command} into {what} changed it");
        }
    }
}

/// Arguments each command checks are refused with exit 2 before its output folder exists.
#[test]
fn bad_arguments_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    tiny_dataset("cornell-glass", &data);
    let out = dir.path().join("out");
    let o = path(&out);
    let d = path(&data);
    let cases: [&[&str]; 7] = [
        &["train", d, "--preset", "tiny", "--crop", "0", "--out", o],
        &["train", d, "--preset", "tiny", "--crop", "8", "--out", o],
        &["train", d, "--preset", "tiny", "--workers", "100000", "--out", o],
        &["train", d, "--preset", "tiny", "--workers", "0", "--out", o],
        &["dataset", "cornell-glass", "--out", o, "--train", "1", "--res", "16", "--threads", "0"],
        &["dataset", "cornell-glass", "--out", o, "--train", "1", "--res", "16", "--threads", "1000000"],
        &["bake", "cornell-glass", "--preset", "nonesuch", "--out", o],
    ];
    for args in cases {
        let (code, err) = glassbake(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
    // train-sr with a GlassNet trained on another scene.
    let other = dir.path().join("other");
    tiny_dataset("cornellbox", &other);
    let model = dir.path().join("model");
    let (code, err) = glassbake(&["train", path(&other), "--preset", "tiny", "--steps", "2", "--out", path(&model)]);
    assert_eq!(code, 0, "{err}");
    let (code, err) = glassbake(&["train-sr", d, "--glassnet", path(&model), "--preset", "tiny", "--steps", "2", "--out", o]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("another scene"), "{err}");
    assert!(!out.exists());
}
