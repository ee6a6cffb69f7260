//! The `glassbake scene` subcommands as a user runs them: output, exit codes, one-line errors,
//! nothing written on bad input.

use std::process::Command;

fn glassbake(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_glassbake")).args(args).output().unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

#[test]
fn info_reports_the_paper_counts() {
    for (name, transparent, variables) in [("cornellbox", 4, 4), ("cornellbox8", 8, 7), ("desk", 3, 3), ("bathroom", 1, 1)] {
        let (code, out, _) = glassbake(&["scene", "info", name]);
        assert_eq!(code, 0);
        assert!(out.contains(&format!("({transparent} transparent)")), "{out}");
        assert!(out.contains(&format!("variables: {variables}")), "{out}");
    }
}

#[test]
fn unknown_scene_is_a_one_line_error_with_exit_code_2() {
    let (code, out, err) = glassbake(&["scene", "info", "cornelbox"]);
    assert_eq!(code, 2);
    assert!(out.is_empty());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("cornelbox") && err.contains("cornellbox"), "{err}");
}

#[test]
fn export_then_validate_and_bad_input_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cornell");
    let (code, _, err) = glassbake(&["scene", "export", "cornell-glass", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let manifest = out.join("manifest.toml");
    let (code, stdout, _) = glassbake(&["scene", "validate", manifest.to_str().unwrap()]);
    assert_eq!(code, 0);
    assert!(stdout.contains("valid"));

    // Break the manifest: a variable aimed at a missing object.
    let text = std::fs::read_to_string(&manifest).unwrap().replace("object = \"pane\"", "object = \"ghost\"");
    std::fs::write(&manifest, text).unwrap();
    let (code, _, err) = glassbake(&["scene", "validate", manifest.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("manifest.toml") && err.contains("target.object") && err.contains("ghost"), "{err}");
    let target = dir.path().join("never");
    let (code, _, _) = glassbake(&["scene", "export", manifest.to_str().unwrap(), target.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(!target.exists(), "nothing is written for bad input");
    let xml = dir.path().join("never.xml");
    let (code, _, _) = glassbake(&["scene", "mitsuba", manifest.to_str().unwrap(), "--out", xml.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(!xml.exists());
}

#[test]
fn mitsuba_writes_xml_and_meshes() {
    let dir = tempfile::tempdir().unwrap();
    let xml = dir.path().join("scene.xml");
    let (code, _, err) = glassbake(&["scene", "mitsuba", "cornellbox", "--sample", "4", "--out", xml.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::read_to_string(&xml).unwrap().contains("<sensor type=\"perspective\">"));
    assert!(dir.path().join("scene_assets/meshes/000.ply").exists());
    assert!(dir.path().join("scene_assets/textures/texture0.png").exists());
    // A second export beside the first keeps to its own assets.
    let first_mesh = std::fs::read(dir.path().join("scene_assets/meshes/000.ply")).unwrap();
    let other = dir.path().join("other.xml");
    let (code, _, err) = glassbake(&["scene", "mitsuba", "cornellbox8", "--sample", "1", "--out", other.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::read_to_string(&other).unwrap().contains("other_assets/meshes/000.ply"));
    assert_eq!(std::fs::read(dir.path().join("scene_assets/meshes/000.ply")).unwrap(), first_mesh);
    // A folder of the user's own files where the assets would go is refused, untouched.
    std::fs::create_dir(dir.path().join("mine_assets")).unwrap();
    std::fs::write(dir.path().join("mine_assets/notes.txt"), b"mine").unwrap();
    let mine = dir.path().join("mine.xml");
    let (code, _, err) = glassbake(&["scene", "mitsuba", "cornellbox", "--out", mine.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("mine_assets") && err.contains("did not write"), "{err}");
    assert!(!mine.exists());
    assert_eq!(std::fs::read_dir(dir.path().join("mine_assets")).unwrap().count(), 1);
}

/// A scene that reaches outside its folder is refused (exit 2) unless the user says it is
/// trusted with GLASSBAKE_ALLOW_OUTSIDE_FILES=1.
#[test]
fn files_outside_the_scene_folder_need_an_explicit_allowance() {
    let dir = tempfile::tempdir().unwrap();
    let inner = dir.path().join("scene");
    std::fs::create_dir(&inner).unwrap();
    image::RgbImage::from_pixel(2, 2, image::Rgb([200, 100, 50])).save(dir.path().join("wood.png")).unwrap();
    std::fs::write(inner.join("scene.mtl"), "newmtl wood\nKd 1 1 1\nmap_Kd ../wood.png\n").unwrap();
    let obj = inner.join("scene.obj");
    std::fs::write(&obj, "mtllib scene.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl wood\nf 1/1 2/2 3/3\n").unwrap();
    let (code, _, err) = glassbake(&["scene", "validate", obj.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("map_Kd") && err.contains("GLASSBAKE_ALLOW_OUTSIDE_FILES"), "{err}");
    let out = Command::new(env!("CARGO_BIN_EXE_glassbake"))
        .args(["scene", "validate", obj.to_str().unwrap()])
        .env("GLASSBAKE_ALLOW_OUTSIDE_FILES", "1")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
}
