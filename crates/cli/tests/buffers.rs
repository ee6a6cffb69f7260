//! `glassbake buffers`: one multi-layer EXR with the layout's names; bad input exits 2.

use std::process::Command;

use glassbake_core::{layout, PlanarImage};

fn glassbake() -> Command {
    Command::new(env!("CARGO_BIN_EXE_glassbake"))
}

#[test]
fn writes_every_layer_and_previews() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frame.exr");
    let status = glassbake()
        .args(["buffers", "cornell-glass", "--camera", "0,1,3.5,0,0.9,0,40", "--set", "pane_x=0.1", "--res", "24"])
        .arg("--out")
        .arg(&out)
        .args(["--png", "opaque.albedo,transparent.0.coverage,opaque.normal,opaque.depth,opaque_light.coverage,transparent.0.through.albedo"])
        .status()
        .unwrap();
    assert!(status.success());
    let image = PlanarImage::read_exr(&out).unwrap();
    let mut names = layout::opaque_channel_names();
    names.extend(layout::naive_channel_names());
    names.extend(layout::transparent_channel_names(0));
    names.extend(layout::opaque_light_coverage_channel_names());
    names.extend(layout::naive_light_coverage_channel_names());
    names.extend(layout::through_channel_names(0));
    assert_eq!(image.channels().len(), names.len());
    let image = image.select(&names).unwrap();
    assert_eq!((image.width(), image.height()), (24, 24));
    for png in ["opaque.albedo", "transparent.0.coverage", "opaque.normal", "opaque.depth", "opaque_light.coverage", "transparent.0.through.albedo"] {
        assert!(dir.path().join(format!("frame.{png}.png")).exists(), "{png}");
    }
}

#[test]
fn bad_input_exits_with_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frame.exr");
    for args in [
        vec!["buffers", "cornell-glass", "--sample", "0", "--res", "0"],
        vec!["buffers", "cornell-glass", "--sample", "0", "--res", "9000"],
        vec!["buffers", "cornell-glass", "--camera", "0,1,2", "--res", "8"],
        vec!["buffers", "cornell-glass", "--camera", "0,1,3,0,1,0", "--set", "nope=1", "--res", "8"],
        vec!["buffers", "no-such-scene", "--sample", "0", "--res", "8"],
        // A bad preview name is refused before the EXR is written.
        vec!["buffers", "cornell-glass", "--sample", "0", "--res", "8", "--png", "opaque.albedo,nosuch.layer"],
    ] {
        let output = glassbake().args(&args).arg("--out").arg(&out).output().unwrap();
        assert_eq!(output.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&output.stderr));
    }
    assert!(!out.exists());
}
