//! The files a scene refers to are read by one rule, whatever refers to them (a manifest's
//! geometry, a glTF buffer or image, an OBJ material library, an MTL texture): after its
//! links are resolved the file must be a regular file inside the referring file's folder, and
//! no more is read than its reference declares. Each test runs the rule over every kind of
//! reference.
#![cfg(unix)]

use std::os::unix::fs::symlink;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use glassbake_scene::load_scene;
use serde_json::json;

mod common;
use common::{expect_bad_input, quad_buffer, quad_gltf, write, write_poster};

/// One kind of reference: the scene file to load, the field its error names, and the name
/// under which the referred file is looked up in the scene's folder.
struct Reference {
    kind: &'static str,
    field: &'static str,
    /// Writes a complete scene into the folder whose reference of this kind names `name`,
    /// and every other file it needs; returns the file to load.
    write_scene: fn(&Path, &str) -> PathBuf,
    /// Writes a valid file of the referred kind.
    write_referred: fn(&Path),
}

fn gltf_referring_to(dir: &Path, buffer: &str, image: &str) -> PathBuf {
    let mut doc = quad_gltf(Some(buffer), false);
    doc["images"][0]["uri"] = json!(image);
    let path = dir.join("scene.gltf");
    write(&path, serde_json::to_vec(&doc).unwrap());
    path
}

/// The 2x1 test poster written under the name `path`.
fn poster_at(path: &Path) {
    write_poster(path.parent().unwrap());
    std::fs::rename(path.parent().unwrap().join("poster.png"), path).unwrap();
}

const OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl wood\nf 1/1 2/2 3/3\n";

const REFERENCES: [Reference; 5] = [
    Reference {
        kind: "glTF buffer",
        field: "buffers[0].uri",
        write_scene: |dir, name| {
            write_poster(dir);
            gltf_referring_to(dir, name, "poster.png")
        },
        write_referred: |path| write(path, quad_buffer()),
    },
    Reference {
        kind: "glTF image",
        field: "images[0].uri",
        write_scene: |dir, name| {
            write(&dir.join("quad.bin"), quad_buffer());
            gltf_referring_to(dir, "quad.bin", name)
        },
        write_referred: poster_at,
    },
    Reference {
        kind: "manifest geometry",
        field: "geometry",
        write_scene: |dir, name| {
            let path = dir.join("scene.toml");
            write(&path, format!("geometry = {name:?}\n"));
            path
        },
        write_referred: |path| {
            let dir = path.parent().unwrap();
            write(&dir.join("quad.bin"), quad_buffer());
            write_poster(dir);
            write(path, serde_json::to_vec(&quad_gltf(Some("quad.bin"), false)).unwrap());
        },
    },
    Reference {
        kind: "OBJ material library",
        field: "mtllib",
        write_scene: |dir, name| {
            let path = dir.join("scene.obj");
            write(&path, format!("mtllib {name}\n{OBJ}"));
            path
        },
        write_referred: |path| write(path, "newmtl wood\nKd 0.5 0.5 0.5\n"),
    },
    Reference {
        kind: "MTL texture",
        field: "map_Kd",
        write_scene: |dir, name| {
            write(&dir.join("scene.mtl"), format!("newmtl wood\nKd 1 1 1\nmap_Kd {name}\n"));
            let path = dir.join("scene.obj");
            write(&path, format!("mtllib scene.mtl\n{OBJ}"));
            path
        },
        write_referred: poster_at,
    },
];

/// The referred file's name in the folder, with the extension its kind is read by.
fn referred_name(kind: &Reference) -> &'static str {
    match kind.field {
        "buffers[0].uri" => "data.bin",
        "geometry" => "geometry.gltf",
        "mtllib" => "library.mtl",
        _ => "picture.png",
    }
}

/// Loads on another thread, so that a load that blocks fails the test instead of hanging it.
fn load_within_seconds(path: &Path) -> glassbake_core::Result<glassbake_scene::Scene> {
    let (send, receive) = mpsc::channel();
    let arg = path.to_str().unwrap().to_string();
    std::thread::spawn(move || {
        let _ = send.send(load_scene(&arg));
    });
    receive.recv_timeout(Duration::from_secs(20)).unwrap_or_else(|_| panic!("loading {} did not finish", path.display()))
}

/// A link inside the folder to a file outside it is refused for every kind of reference, as is
/// a file reached through a linked folder; the same links to files inside the folder load.
#[test]
fn links_out_of_the_scene_folder_are_refused_for_every_reference() {
    for reference in &REFERENCES {
        let root = tempfile::tempdir().unwrap();
        let (scene_dir, outside) = (root.path().join("scene"), root.path().join("outside"));
        std::fs::create_dir_all(&scene_dir).unwrap();
        std::fs::create_dir_all(&outside).unwrap();
        let name = referred_name(reference);
        (reference.write_referred)(&outside.join(name));

        symlink(outside.join(name), scene_dir.join(name)).unwrap();
        let scene = (reference.write_scene)(&scene_dir, name);
        expect_bad_input(load_within_seconds(&scene), "scene.", reference.field);

        symlink(&outside, scene_dir.join("linked")).unwrap();
        let scene = (reference.write_scene)(&scene_dir, &format!("linked/{name}"));
        expect_bad_input(load_within_seconds(&scene), "scene.", reference.field);

        // Links that stay inside the folder are the user's own layout.
        let inside = scene_dir.join("assets");
        std::fs::create_dir_all(&inside).unwrap();
        (reference.write_referred)(&inside.join(name));
        std::fs::remove_file(scene_dir.join(name)).unwrap();
        symlink(inside.join(name), scene_dir.join(name)).unwrap();
        let scene = (reference.write_scene)(&scene_dir, name);
        load_within_seconds(&scene).unwrap_or_else(|e| panic!("{}: a link inside the folder: {e}", reference.kind));
    }
}

/// A reference to a pipe or a folder is refused without reading it: a pipe would block the
/// load (as a device would never end it).
#[test]
fn references_to_what_is_not_a_regular_file_are_refused() {
    for reference in &REFERENCES {
        let dir = tempfile::tempdir().unwrap();
        let name = referred_name(reference);
        let fifo = dir.path().join(name);
        let made = std::process::Command::new("mkfifo").arg(&fifo).status().expect("mkfifo runs");
        assert!(made.success());
        let scene = (reference.write_scene)(dir.path(), name);
        expect_bad_input(load_within_seconds(&scene), "scene.", reference.field);

        std::fs::remove_file(&fifo).unwrap();
        std::fs::create_dir(&fifo).unwrap();
        expect_bad_input(load_within_seconds(&scene), "scene.", reference.field);
    }
}

/// A glTF buffer is read to its declared byteLength and no further: a file shorter than
/// declared is refused, a longer one loads, and a declaration beyond any file is refused before
/// memory is set aside for it.
#[test]
fn buffers_are_read_to_their_declared_length() {
    let dir = tempfile::tempdir().unwrap();
    write_poster(dir.path());
    let declared = quad_buffer().len();
    let bin = dir.path().join("quad.bin");
    let scene = gltf_referring_to(dir.path(), "quad.bin", "poster.png");

    write(&bin, &quad_buffer()[..declared - 4]);
    expect_bad_input(load_within_seconds(&scene), "scene.gltf", "buffers[0]");

    let mut longer = quad_buffer();
    longer.extend(std::iter::repeat_n(0xAB, 1 << 16));
    write(&bin, &longer);
    let loaded = load_within_seconds(&scene).expect("a buffer file longer than declared loads");
    assert_eq!(loaded.objects.len(), 2);

    for huge in [1u64 << 40, u64::MAX >> 12] {
        let mut doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&scene).unwrap()).unwrap();
        doc["buffers"][0]["byteLength"] = json!(huge);
        write(&scene, serde_json::to_vec(&doc).unwrap());
        expect_bad_input(load_within_seconds(&scene), "scene.gltf", "buffers[0]");
    }
}
