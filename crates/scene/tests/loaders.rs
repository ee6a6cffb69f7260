//! Loader, manifest, variable and sampling tests on small files the tests write themselves.

use std::path::{Path, PathBuf};

use glam::{Vec3, Vec4};
use glassbake_core::Error;
use glassbake_scene::builtin::{builtin, BUILTIN_NAMES};
use glassbake_scene::{load_scene, DielectricKind};
use serde_json::json;

mod common;
use common::{expect_bad_input, quad_buffer, quad_gltf, write, write_poster, write_quad_gltf};

/// A node hierarchy that is not a tree is refused, naming the node, before the traversal
/// could loop: a node that is its own child (which once grew memory without end), a cycle
/// through two nodes, and a node with two parents.
#[test]
fn gltf_node_cycles_and_shared_children_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    write_poster(dir.path());
    write(&dir.path().join("quad.bin"), quad_buffer());
    let cases: [(&str, serde_json::Value, &str); 3] = [
        ("self", json!([{"name": "wall", "mesh": 0, "children": [0]}, {"name": "glass", "mesh": 1}]), "nodes[0]"),
        ("cycle", json!([{"name": "wall", "mesh": 0, "children": [1]}, {"name": "glass", "mesh": 1, "children": [0]}]), "nodes[0]"),
        ("shared", json!([{"name": "wall", "mesh": 0, "children": [1]}, {"name": "glass", "mesh": 1}]), "nodes[1]"),
    ];
    for (name, nodes, field) in cases {
        let mut doc = quad_gltf(Some("quad.bin"), false);
        doc["nodes"] = nodes;
        let path = dir.path().join(format!("{name}.gltf"));
        write(&path, serde_json::to_vec(&doc).unwrap());
        expect_bad_input(load_scene(path.to_str().unwrap()), &format!("{name}.gltf"), field);
    }
}

/// Accessors that gltf-rs would misread, drop or panic on are refused, naming the accessor:
/// FLOAT indices, POSITION as UNSIGNED_BYTE or VEC2, indices running past their buffer view.
#[test]
fn gltf_accessors_of_the_wrong_type_or_out_of_bounds_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    write_poster(dir.path());
    write(&dir.path().join("quad.bin"), quad_buffer());
    let cases: [(&str, usize, serde_json::Value, &str); 6] = [
        ("float-indices", 2, json!({"bufferView": 2, "componentType": 5126, "count": 3, "type": "SCALAR"}), "indices (accessors[2])"),
        (
            "byte-positions",
            0,
            json!({"bufferView": 0, "componentType": 5121, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}),
            "POSITION (accessors[0])",
        ),
        (
            "vec2-positions",
            0,
            json!({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC2", "min": [0.0, 0.0], "max": [1.0, 1.0]}),
            "POSITION (accessors[0])",
        ),
        ("long-indices", 2, json!({"bufferView": 2, "componentType": 5123, "count": 9, "type": "SCALAR"}), "indices (accessors[2])"),
        // Found by fuzz/fuzz_targets/geometry_gltf.rs: the gltf crate's reader hit `unreachable!()`.
        ("uint-uvs", 1, json!({"bufferView": 1, "componentType": 5125, "count": 4, "type": "VEC2"}), "TEXCOORD_0 (accessors[1])"),
        ("vec2-normals", 3, json!({"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}), "NORMAL (accessors[3])"),
    ];
    for (name, accessor, replacement, field) in cases {
        let mut doc = quad_gltf(Some("quad.bin"), false);
        if accessor == 3 {
            // A NORMAL attribute of its own: the quad has none.
            doc["accessors"].as_array_mut().unwrap().push(replacement);
            doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(3);
        } else {
            doc["accessors"][accessor] = replacement;
        }
        let path = dir.path().join(format!("{name}.gltf"));
        write(&path, serde_json::to_vec(&doc).unwrap());
        // gltf-rs's own validation already refuses some (field "glTF", the attribute named in
        // the message); the rest are this loader's checks, with the accessor in the field.
        match load_scene(path.to_str().unwrap()) {
            Err(Error::BadInput { file, field: f, message }) => {
                assert!(file.contains(&format!("{name}.gltf")), "{name}: {file}");
                let said = format!("{f}: {message}");
                assert!(said.contains(field) || (f == "glTF" && said.contains(field.split(' ').next().unwrap())), "{name}: {said}");
            }
            Err(other) => panic!("{name}: expected bad input, got {other}"),
            Ok(_) => panic!("{name} was accepted"),
        }
    }
}

#[test]
fn a_position_attribute_without_its_accessor_is_refused() {
    // Found by fuzz/fuzz_targets/geometry_gltf.rs: gltf-json indexed the missing accessor.
    let dir = tempfile::tempdir().unwrap();
    write(&dir.path().join("quad.bin"), quad_buffer());
    for missing in [7, u32::MAX as usize] {
        let mut doc = quad_gltf(Some("quad.bin"), false);
        doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(missing);
        let path = dir.path().join("lost.gltf");
        write(&path, serde_json::to_vec(&doc).unwrap());
        match load_scene(path.to_str().unwrap()) {
            Err(Error::BadInput { field, message, .. }) => {
                assert_eq!(field, "meshes[0].primitives[0].attributes.POSITION");
                assert!(message.contains(&format!("accessor {missing} does not exist")), "{message}");
            }
            other => panic!("expected bad input, got {:?}", other.map(|s| s.objects.len())),
        }
    }
}

#[test]
fn a_material_colour_of_fewer_than_three_numbers_is_refused() {
    // Found by fuzz/fuzz_targets/geometry_obj.rs: tobj unwrapped the short colour.
    let dir = tempfile::tempdir().unwrap();
    write(&dir.path().join("short.mtl"), "newmtl wall\nKd 0.8 0.8 0.8\nnewmtl floor\nKs 0 1\n");
    let obj = dir.path().join("scene.obj");
    write(&obj, "mtllib short.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl floor\nf 1 2 3\n");
    expect_bad_input(load_scene(obj.to_str().unwrap()), "short.mtl", "line 4 Ks");
}

#[test]
fn an_image_without_a_source_is_refused() {
    // Found by fuzz/fuzz_targets/geometry_gltf.rs: the gltf crate unwrapped the missing uri.
    let dir = tempfile::tempdir().unwrap();
    write(&dir.path().join("quad.bin"), quad_buffer());
    for (image, problem) in [
        (json!({"name": "nothing"}), "neither a uri nor a bufferView"),
        (json!({"bufferView": 0}), "no mimeType"),
        (json!({"bufferView": 0, "mimeType": "image/png", "uri": "poster.png"}), "both a uri and a bufferView"),
    ] {
        let mut doc = quad_gltf(Some("quad.bin"), false);
        doc["images"][0] = image;
        let path = dir.path().join("image.gltf");
        write(&path, serde_json::to_vec(&doc).unwrap());
        match load_scene(path.to_str().unwrap()) {
            Err(Error::BadInput { field, message, .. }) => assert!(field == "images[0]" && message.contains(problem), "{field}: {message}"),
            other => panic!("expected bad input, got {:?}", other.map(|s| s.objects.len())),
        }
    }
}

/// Scene files may not make glassbake read files outside their folder: absolute paths,
/// `..` (also percent-encoded), `file:` URIs, in glTF buffers and images, a manifest's
/// geometry and an OBJ's material library and textures. Each is refused naming the field.
#[test]
fn references_outside_the_scene_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let inner = dir.path().join("scene");
    std::fs::create_dir(&inner).unwrap();
    write_poster(dir.path());
    write(&dir.path().join("quad.bin"), quad_buffer());
    write_poster(&inner);
    for (name, buffer, image, field) in [
        ("up", "../quad.bin", "poster.png", "buffers[0].uri"),
        ("encoded", "..%2Fquad.bin", "poster.png", "buffers[0].uri"),
        ("absolute", &*dir.path().join("quad.bin").to_string_lossy().into_owned(), "poster.png", "buffers[0].uri"),
        ("file-uri", "quad.bin", "file:///etc/passwd", "images[0].uri"),
        // Found by fuzz/fuzz_targets/geometry_gltf.rs: the gltf crate unwrapped the decoding.
        ("not-utf8", "quad%AA.bin", "poster.png", "buffers[0].uri"),
    ] {
        let mut doc = quad_gltf(Some(buffer), false);
        doc["images"][0]["uri"] = json!(image);
        let path = inner.join(format!("{name}.gltf"));
        write(&path, serde_json::to_vec(&doc).unwrap());
        expect_bad_input(load_scene(path.to_str().unwrap()), &format!("{name}.gltf"), field);
    }
    let manifest = inner.join("m.toml");
    write(&manifest, "geometry = \"../elsewhere.gltf\"\n");
    expect_bad_input(load_scene(manifest.to_str().unwrap()), "m.toml", "geometry");
    let obj = inner.join("scene.obj");
    write(&obj, "mtllib ../../etc/passwd\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_bad_input(load_scene(obj.to_str().unwrap()), "scene.obj", "mtllib");
    write(&inner.join("tex.mtl"), "newmtl wood\nKd 1 1 1\nmap_Kd ../poster.png\n");
    write(&obj, "mtllib tex.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl wood\nf 1 2 3\n");
    expect_bad_input(load_scene(obj.to_str().unwrap()), "scene.obj", "map_Kd");
}

#[test]
fn gltf_with_transmission_and_texture() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_quad_gltf(dir.path(), false);
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    assert_eq!(scene.objects.len(), 2);
    assert_eq!(scene.triangle_count(), 4);
    let wall = &scene.objects[scene.object_index("wall").unwrap()];
    let glass = &scene.objects[scene.object_index("glass").unwrap()];
    assert!(!wall.transparent && glass.transparent);
    assert_eq!(scene.transparent_objects(), vec![scene.object_index("glass").unwrap()]);
    // Node translation is applied.
    assert_eq!(scene.world_mesh(scene.object_index("glass").unwrap()).positions[2], Vec3::new(1.0, 1.0, 2.0));

    let poster = &scene.materials[wall.material];
    assert_eq!(poster.roughness, 0.7);
    assert_eq!(poster.emission, Vec3::new(4.0, 2.0, 0.0));
    let tex = &scene.textures[poster.base_color_texture.unwrap()];
    assert_eq!((tex.width, tex.height), (2, 1));
    // sRGB 188/255 decodes to linear 0.5029 (IEC 61966-2-1).
    assert!((tex.texels[0].x - 0.5029).abs() < 1e-3, "{}", tex.texels[0].x);
    assert_eq!(tex.texels[1], Vec4::new(1.0, 0.0, 0.0, 1.0));

    let m = &scene.materials[glass.material];
    let t = m.transmission.unwrap();
    assert_eq!((t.weight, t.ior, t.thin), (1.0, 1.33, true));
    assert_eq!(m.dielectric_kind(), Some(DielectricKind::Thin));
    assert_eq!(m.base_color, Vec3::new(0.9, 0.95, 1.0));
    // Missing normals are computed from the faces: the quad faces +z.
    assert!(scene.meshes[glass.mesh].normals.iter().all(|&n| (n - Vec3::Z).length() < 1e-6));
}

#[test]
fn gltf_volume_makes_a_solid_dielectric() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_quad_gltf(dir.path(), true);
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    let glass = &scene.materials[scene.objects[scene.object_index("glass").unwrap()].material];
    assert_eq!(glass.dielectric_kind(), Some(DielectricKind::Smooth));
}

#[test]
fn glb_binary_container_loads() {
    let dir = tempfile::tempdir().unwrap();
    write_poster(dir.path());
    let mut json = serde_json::to_vec(&quad_gltf(None, false)).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = quad_buffer();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    let path = dir.path().join("quad.glb");
    write(&path, glb);
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    assert_eq!(scene.objects.len(), 2);
    assert_eq!(scene.transparent_count(), 1);
}

const OBJ: &str = "mtllib scene.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 2 2
vt 0 0
vt 1 0
vt 1 1
vt 0 1
o floor
usemtl wood
f 1/1 2/2 3/3 4/4
o lens
usemtl glass
f 1 2 3
o sliver
usemtl lamp
f 1 2 1
f 1 2 5
";

const MTL: &str = "newmtl wood
Kd 1 1 1
Ns 10
map_Kd poster.png
newmtl glass
Kd 0 0 0
Tf 0.8 0.9 1.0
Ni 1.45
Ns 1000
illum 7
newmtl lamp
Kd 0 0 0
Ke 5 5 4
";

#[test]
fn obj_with_mtl_glass_texture_and_emission() {
    let dir = tempfile::tempdir().unwrap();
    write_poster(dir.path());
    write(&dir.path().join("scene.mtl"), MTL);
    let path = dir.path().join("scene.obj");
    write(&path, OBJ);
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    assert_eq!(scene.objects.len(), 3);
    let floor = &scene.objects[scene.object_index("floor").unwrap()];
    assert_eq!(scene.meshes[floor.mesh].triangle_count(), 2, "the quad face is triangulated");
    // OBJ v runs bottom-up; the model's v is top-down.
    let uvs = &scene.meshes[floor.mesh].uvs;
    assert!(uvs.contains(&glam::Vec2::new(0.0, 1.0)) && uvs.contains(&glam::Vec2::new(1.0, 0.0)));
    let wood = &scene.materials[floor.material];
    assert!(wood.base_color_texture.is_some());
    // Ns 10 -> alpha = sqrt(2/12); glTF roughness = sqrt(alpha).
    assert!((wood.roughness - (2.0f32 / 12.0).sqrt().sqrt()).abs() < 1e-6);
    let lens = &scene.objects[scene.object_index("lens").unwrap()];
    assert!(lens.transparent);
    let glass = &scene.materials[lens.material];
    assert_eq!(glass.transmission.unwrap().ior, 1.45);
    assert_eq!(glass.base_color, Vec3::new(0.8, 0.9, 1.0));
    assert_eq!(glass.dielectric_kind(), Some(DielectricKind::Smooth));
    let sliver = &scene.objects[scene.object_index("sliver").unwrap()];
    assert_eq!(scene.materials[sliver.material].emission, Vec3::new(5.0, 5.0, 4.0));
    // The zero-area triangle `1 2 1` is dropped with a warning.
    assert_eq!(scene.meshes[sliver.mesh].triangle_count(), 1);
    assert!(scene.warnings().iter().any(|w| w.contains("degenerate")), "{:?}", scene.warnings());
    assert_eq!(scene.light_count(), 1);
}

fn manifest_text(geometry: &str, variables: &str) -> String {
    format!(
        r#"
name = "quads"
geometry = "{geometry}"
background = [0.1, 0.1, 0.1]

[camera]
target = [0.5, 0.5, 0.0]
fov_x_deg = [40.0, 50.0]
near = 0.1
far = 50.0
position = {{ kind = "orbit", center = [0.5, 0.5, 0.0], radius = [3.0, 4.0], azimuth_deg = [-20.0, 20.0], elevation_deg = 10.0 }}

[[lights]]
name = "key"
corner = [0.0, 3.0, 0.0]
edge_u = [1.0, 0.0, 0.0]
edge_v = [0.0, 0.0, 1.0]
radiance = [10.0, 10.0, 10.0]

{variables}
"#
    )
}

const ALL_VARIABLES: &str = r#"
[[variables]]
name = "glass_x"
range = [-1.0, 1.0]
target = { kind = "translation", object = "glass", axis = [1.0, 0.0, 0.0] }

[[variables]]
name = "glass_rough"
range = [0.0, 0.5]
default = 0.25
target = { kind = "roughness", material = "glass" }

[[variables]]
name = "glass_hue"
range = [0.0, 360.0]
target = { kind = "hue", material = "glass", saturation = 1.0, brightness = 1.0 }

[[variables]]
name = "key_y"
range = [-0.5, 0.5]
target = { kind = "light_translation", light = "key", axis = [0.0, 1.0, 0.0] }

[[variables]]
name = "key_power"
range = [0.5, 2.0]
target = { kind = "light_intensity", light = "key" }

[[variables]]
name = "glow"
range = [0.0, 2.0]
target = { kind = "emission_intensity", material = "poster" }
"#;

fn write_manifest(dir: &Path, variables: &str) -> PathBuf {
    write_quad_gltf(dir, false);
    let path = dir.join("manifest.toml");
    write(&path, manifest_text("quad.gltf", variables));
    path
}

#[test]
fn manifest_declares_camera_lights_and_variables() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_manifest(dir.path(), ALL_VARIABLES);
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    assert_eq!(scene.name, "quads");
    assert_eq!(scene.background, Vec3::splat(0.1));
    assert_eq!(scene.rect_lights.len(), 1);
    assert_eq!(scene.variables.len(), 6);
    assert_eq!(scene.variables[0].default, 0.0, "default is the middle of the range");
    assert_eq!(scene.variables[1].default, 0.25);
    for i in 0..50 {
        let s = scene.sample(3, i);
        let d = s.camera.position - Vec3::new(0.5, 0.5, 0.0);
        assert!((3.0..=4.0001).contains(&d.length()), "{}", d.length());
        assert!((40.0..=50.0).contains(&s.camera.fov_x_deg));
        for (v, value) in scene.variables.iter().zip(&s.values) {
            assert!((v.min..=v.max).contains(value));
        }
    }
}

#[test]
fn variable_application_is_exact_and_leaves_the_base_scene_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_scene(write_manifest(dir.path(), ALL_VARIABLES).to_str().unwrap()).unwrap();
    let glass = scene.object_index("glass").unwrap();
    let glass_material = scene.objects[glass].material;
    let poster = scene.material_index("poster").unwrap();
    let values = [0.5, 0.3, 120.0, -0.25, 2.0, 0.5];
    let inst = scene.instantiate(&values).unwrap();
    assert_eq!(inst.world_mesh(glass).positions[0], Vec3::new(0.5, 0.0, 2.0));
    assert_eq!(inst.materials[glass_material].roughness, 0.3);
    // Hue 120 at full saturation and value is pure green.
    assert!((inst.materials[glass_material].base_color - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6);
    assert_eq!(inst.rect_lights[0].corner, Vec3::new(0.0, 2.75, 0.0));
    assert_eq!(inst.rect_lights[0].radiance, Vec3::splat(20.0));
    assert_eq!(inst.materials[poster].emission, Vec3::new(2.0, 1.0, 0.0));
    // The base scene is unchanged and instancing is deterministic.
    assert_eq!(scene.world_mesh(glass).positions[0], Vec3::new(0.0, 0.0, 2.0));
    assert_eq!(scene.rect_lights[0].radiance, Vec3::splat(10.0));
    let again = scene.instantiate(&values).unwrap();
    assert_eq!(again.content_hash(), inst.content_hash());
    assert_ne!(scene.content_hash(), inst.content_hash());
    // Applying twice from the base does not accumulate.
    let twice = inst.instantiate(&scene.default_values()).unwrap();
    assert_eq!(twice.world_mesh(glass).positions[0].x, 0.5, "instantiate applies to its receiver's base");
    assert!(scene.instantiate(&values[..2]).is_err());
    assert!(scene.instantiate(&[f32::NAN, 0.3, 120.0, 0.0, 1.0, 1.0]).is_err());
}

#[test]
fn set_assignments_are_checked() {
    let scene = builtin("cornellbox").unwrap();
    let v = scene.values_from_assignments(&["sphere_x=0.05".into(), "light_intensity = 1.5".into()]).unwrap();
    assert_eq!(v, vec![0.05, 0.0, 0.0, 1.5]);
    for bad in ["sphere_x", "nope=1", "sphere_x=abc", "sphere_x=9"] {
        assert!(matches!(scene.values_from_assignments(&[bad.into()]), Err(Error::BadInput { .. })), "{bad}");
    }
}

#[test]
fn sampling_is_reproducible_per_index() {
    for name in BUILTIN_NAMES {
        let scene = builtin(name).unwrap();
        let forward: Vec<_> = (0..20).map(|i| scene.sample(42, i)).collect();
        // Any sample regenerated alone, in any order, is identical.
        for i in (0..20).rev() {
            assert_eq!(scene.sample(42, i), forward[i as usize]);
        }
        assert_ne!(scene.sample(43, 0).camera, forward[0].camera);
        assert_ne!(forward[0].camera, forward[1].camera);
        // Uniform in range: the mean of many fov draws is near the middle of the range.
        let n = 2000;
        let mean: f32 = (0..n).map(|i| scene.sample(7, i).camera.fov_x_deg).sum::<f32>() / n as f32;
        let fov = scene.camera.fov_x_deg;
        assert!((mean - fov.mid()).abs() < 0.05 * (fov.max - fov.min), "{name}: {mean}");
    }
}

#[test]
fn bad_inputs_name_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    expect_bad_input(load_scene(d.join("missing.toml").to_str().unwrap()), "missing.toml", "file");
    expect_bad_input(load_scene("cornelbox"), "cornelbox", "scene");
    expect_bad_input(load_scene(d.join("scene.fbx").to_str().unwrap()), "scene.fbx", "scene");

    write_quad_gltf(d, false);
    let manifest = d.join("m.toml");
    let cases: &[(&str, &str)] = &[
        ("geometry = \"quad.gltf\"\n[camera\n", "line"),
        ("geometry = \"quad.gltf\"\nbogus = 1\n", "line 2"),
        ("geometry = \"nothere.gltf\"\n", "geometry"),
        (
            "geometry = \"quad.gltf\"\n[[variables]]\nname = \"r\"\nrange = [0.0, 1.0]\ntarget = { kind = \"roughness\", material = \"steel\" }\n",
            "variables[0] (r).target.material",
        ),
        (
            "geometry = \"quad.gltf\"\n[[variables]]\nname = \"x\"\nrange = [0.0, 1.0]\ntarget = { kind = \"translation\", object = \"ghost\", axis = [1.0, 0.0, 0.0] }\n",
            "variables[0] (x).target.object",
        ),
        (
            "geometry = \"quad.gltf\"\n[[variables]]\nname = \"x\"\nrange = [1.0, 1.0]\ntarget = { kind = \"translation\", object = \"glass\", axis = [1.0, 0.0, 0.0] }\n",
            "variables[0] (x).range",
        ),
        (
            "geometry = \"quad.gltf\"\n[[variables]]\nname = \"x\"\nrange = [1.0, -1.0]\ntarget = { kind = \"translation\", object = \"glass\", axis = [1.0, 0.0, 0.0] }\n",
            "variables[0] (x).range",
        ),
        (
            "geometry = \"quad.gltf\"\n[[variables]]\nname = \"x\"\nrange = []\ntarget = { kind = \"translation\", object = \"glass\", axis = [1.0, 0.0, 0.0] }\n",
            "variables[0] (x).range",
        ),
        (
            "geometry = \"quad.gltf\"\n[camera]\ntarget = [0.0, 0.0, 0.0]\nfov_x_deg = [50.0, 40.0]\nposition = { kind = \"box\", min = [0.0, 0.0, 1.0], max = [0.0, 0.0, 2.0] }\n",
            "camera.fov_x_deg",
        ),
        (
            "geometry = \"quad.gltf\"\n[[variables]]\nname = \"l\"\nrange = [0.0, 1.0]\ntarget = { kind = \"light_intensity\", light = \"sun\" }\n",
            "target.light",
        ),
        // Radiance that would overflow the image, or is negative.
        (
            "geometry = \"quad.gltf\"\n[[lights]]\nname = \"sun\"\ncorner = [0.0, 3.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nedge_v = [0.0, 0.0, 1.0]\nradiance = [3e38, 3e38, 3e38]\n",
            "light \"sun\" radiance",
        ),
        (
            "geometry = \"quad.gltf\"\n[[lights]]\nname = \"sun\"\ncorner = [0.0, 3.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nedge_v = [0.0, 0.0, 1.0]\nradiance = [1.0, -1.0, 1.0]\n",
            "light \"sun\" radiance",
        ),
    ];
    for (text, field) in cases {
        write(&manifest, text);
        expect_bad_input(load_scene(manifest.to_str().unwrap()), "m.toml", field);
    }

    let broken = d.join("broken.gltf");
    write(&broken, "{ \"asset\": { \"version\": \"2.0\" }, \"nodes\": [ { \"mesh\": 7 } ] ");
    expect_bad_input(load_scene(broken.to_str().unwrap()), "broken.gltf", "glTF");

    for bad in ["nan", "inf"] {
        let obj = d.join(format!("{bad}.obj"));
        write(&obj, format!("v 0 0 0\nv 1 0 0\nv 0 {bad} 0\nf 1 2 3\n"));
        expect_bad_input(load_scene(obj.to_str().unwrap()), &format!("{bad}.obj"), "vertex 2 position");
    }
}

#[test]
fn a_scene_without_glass_is_valid_but_warned() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("plain.obj");
    write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let scene = load_scene(obj.to_str().unwrap()).unwrap();
    assert_eq!(scene.transparent_count(), 0);
    let warnings = scene.warnings();
    assert!(warnings.iter().any(|w| w.contains("no transparent object")), "{warnings:?}");
    assert!(warnings.iter().any(|w| w.contains("no light")), "{warnings:?}");
}

#[test]
fn export_refuses_to_overwrite_a_scene_unless_forced() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("manifest.toml");
    std::fs::write(&manifest, "# the user's own manifest\n").unwrap();
    let err = glassbake_scene::export::export_scene(&scene, dir.path(), false).unwrap_err();
    assert!(err.is_user_error() && err.to_string().contains("manifest.toml") && err.to_string().contains("--force"), "{err}");
    assert_eq!(std::fs::read_to_string(&manifest).unwrap(), "# the user's own manifest\n", "the manifest was touched");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "nothing else was written");
    glassbake_scene::export::export_scene(&scene, dir.path(), true).unwrap();
    assert!(load_scene(manifest.to_str().unwrap()).is_ok());
}

#[test]
fn export_round_trips_every_builtin() {
    for name in BUILTIN_NAMES {
        let original = builtin(name).unwrap();
        let dir = tempfile::tempdir().unwrap();
        glassbake_scene::export::export_scene(&original, dir.path(), false).unwrap();
        let loaded = load_scene(dir.path().join("manifest.toml").to_str().unwrap()).unwrap();
        assert_eq!(loaded.name, original.name);
        assert_eq!(loaded.objects.len(), original.objects.len(), "{name}");
        assert_eq!(loaded.transparent_count(), original.transparent_count(), "{name}");
        assert_eq!(loaded.triangle_count(), original.triangle_count(), "{name}");
        assert_eq!(loaded.variables, original.variables, "{name}");
        assert_eq!(loaded.rect_lights, original.rect_lights, "{name}");
        assert_eq!(loaded.background, original.background, "{name}");
        for (a, b) in loaded.objects.iter().zip(&original.objects) {
            assert_eq!(a.name, b.name);
            assert_eq!(a.transparent, b.transparent);
            assert_eq!(a.transform, b.transform, "{name}/{}", a.name);
            assert_eq!(loaded.meshes[a.mesh].positions, original.meshes[b.mesh].positions);
            let (ma, mb) = (&loaded.materials[a.material], &original.materials[b.material]);
            assert_eq!((ma.roughness, ma.metallic, ma.transmission), (mb.roughness, mb.metallic, mb.transmission));
            assert!((ma.emission - mb.emission).length() < 1e-5);
        }
        // Same ranges, so the same samples.
        for i in 0..5 {
            assert_eq!(loaded.sample(9, i), original.sample(9, i), "{name}");
        }
    }
}

#[test]
fn mitsuba_export_keeps_hostile_names_inside_their_comments() {
    let mut scene = builtin("cornell-glass").unwrap();
    let hostile = "pane --> <shape type=\"evil\"/> <!-- -";
    scene.objects[0].name = hostile.into();
    scene.name = "scene--->".into();
    scene.rect_lights[0].name = "light\n-->".into();
    let sample = scene.sample(0, 0);
    let instance = scene.instantiate(&sample.values).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.xml");
    glassbake_scene::mitsuba::write_mitsuba(&instance, &sample.camera, &out).unwrap();
    let xml = std::fs::read_to_string(&out).unwrap();
    // Remove the comments as an XML parser would (each ends at the first "-->"): nothing of
    // the names may be left outside them.
    let mut outside = String::new();
    let mut rest = xml.as_str();
    while let Some(start) = rest.find("<!--") {
        outside.push_str(&rest[..start]);
        let body = &rest[start + 4..];
        let end = body.find("-->").expect("every comment is closed");
        assert!(!body[..end].contains("--"), "a comment holds \"--\": {}", &body[..end]);
        rest = &body[end + 3..];
    }
    outside.push_str(rest);
    assert!(!outside.contains("evil") && !outside.contains("<!--"), "{outside}");
    assert_eq!(outside.matches("<shape type=\"ply\"").count(), scene.objects.len());
}

#[test]
fn mitsuba_export_writes_every_shape_and_the_camera() {
    let scene = builtin("cornell-glass").unwrap();
    let sample = scene.sample(0, 3);
    let instance = scene.instantiate(&sample.values).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene.xml");
    glassbake_scene::mitsuba::write_mitsuba(&instance, &sample.camera, &out).unwrap();
    let xml = std::fs::read_to_string(&out).unwrap();
    assert_eq!(xml.matches("<shape type=\"ply\"").count(), scene.objects.len());
    assert_eq!(xml.matches("<shape type=\"rectangle\"").count(), scene.rect_lights.len());
    assert!(xml.contains("thindielectric"));
    assert!(xml.contains(&format!("<float name=\"fov\" value=\"{}\"/>", sample.camera.fov_x_deg)));
    assert!(xml.contains("value=\"scene_assets/meshes/000.ply\""));
    // Each PLY holds exactly its header plus 8 floats per vertex and 13 bytes per triangle.
    for (i, o) in scene.objects.iter().enumerate() {
        let bytes = std::fs::read(dir.path().join(format!("scene_assets/meshes/{i:03}.ply"))).unwrap();
        let header_end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let mesh = &scene.meshes[o.mesh];
        assert_eq!(bytes.len() - header_end, mesh.vertex_count() * 32 + mesh.triangle_count() * 13);
    }
    // The pane moved by its variable is baked into its world-space mesh.
    let pane = scene.object_index("pane").unwrap();
    let bytes = std::fs::read(dir.path().join(format!("scene_assets/meshes/{pane:03}.ply"))).unwrap();
    let header_end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let x = f32::from_le_bytes(bytes[header_end..header_end + 4].try_into().unwrap());
    assert_eq!(x, instance.world_mesh(pane).positions[0].x);
}

#[test]
fn grey_alpha_textures_and_repeated_material_names() {
    let dir = tempfile::tempdir().unwrap();
    // A grey+alpha poster: luminance 255, alpha 128.
    image::GrayAlphaImage::from_raw(1, 1, vec![255, 128]).unwrap().save(dir.path().join("poster.png")).unwrap();
    write(&dir.path().join("quad.bin"), quad_buffer());
    let mut doc = quad_gltf(Some("quad.bin"), false);
    doc["materials"][1]["name"] = json!("poster");
    let path = dir.path().join("quad.gltf");
    write(&path, serde_json::to_vec(&doc).unwrap());
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, vec!["poster", "poster#1"]);
    let texture = &scene.textures[scene.materials[0].base_color_texture.unwrap()];
    assert_eq!(texture.texels[0], Vec4::new(1.0, 1.0, 1.0, 128.0 / 255.0));
}

#[test]
fn objects_left_without_triangles_are_skipped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("thin.obj");
    write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\no solid\nf 1 2 3\no flat\nf 1 2 1\n");
    let scene = load_scene(obj.to_str().unwrap()).unwrap();
    let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, vec!["solid"]);
    let warnings = scene.warnings().join("\n");
    assert!(warnings.contains("without triangles are skipped: flat"), "{warnings}");
}

#[test]
fn texture_sampling_is_bilinear_top_down_and_repeats() {
    let t = glassbake_scene::Texture {
        name: "2x2".into(),
        width: 2,
        height: 2,
        texels: vec![Vec4::splat(0.0), Vec4::splat(1.0), Vec4::splat(2.0), Vec4::splat(3.0)],
        is_color: false,
    };
    // Texel centres give the texels exactly; v = 0 is the top row.
    assert_eq!(t.sample(glam::Vec2::new(0.25, 0.25)), Vec4::splat(0.0));
    assert_eq!(t.sample(glam::Vec2::new(0.75, 0.25)), Vec4::splat(1.0));
    assert_eq!(t.sample(glam::Vec2::new(0.25, 0.75)), Vec4::splat(2.0));
    // Halfway between all four: their mean.
    assert_eq!(t.sample(glam::Vec2::new(0.5, 0.5)), Vec4::splat(1.5));
    // Repeat wrapping: u = -0.25 is u = 0.75, and u = 0 blends the last and first columns.
    assert_eq!(t.sample(glam::Vec2::new(-0.25, 0.25)), Vec4::splat(1.0));
    assert_eq!(t.sample(glam::Vec2::new(1.25, 0.75)), Vec4::splat(2.0));
    assert_eq!(t.sample(glam::Vec2::new(0.0, 0.25)), Vec4::splat(0.5));
}

/// The quad glTF with its wall material given KHR_materials_specular (factor, colour and both
/// textures) and a KHR_texture_transform on every texture.
fn specular_gltf(dir: &Path, extra_used: &[&str], required: &[&str]) -> PathBuf {
    write_poster(dir);
    write(&dir.join("quad.bin"), quad_buffer());
    let mut doc = quad_gltf(Some("quad.bin"), false);
    let transform = json!({"KHR_texture_transform": {"offset": [0.5, 0.0], "scale": [2.0, 2.0]}});
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] = transform.clone();
    doc["materials"][0]["extensions"]["KHR_materials_specular"] = json!({
        "specularFactor": 0.25,
        "specularColorFactor": [1.0, 0.5, 2.0],
        "specularTexture": {"index": 0, "extensions": transform.clone()},
        "specularColorTexture": {"index": 0, "extensions": transform},
    });
    let mut used: Vec<&str> =
        vec!["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_emissive_strength", "KHR_materials_specular", "KHR_texture_transform"];
    used.extend(extra_used);
    doc["extensionsUsed"] = json!(used);
    if !required.is_empty() {
        doc["extensionsRequired"] = json!(required);
    }
    let path = dir.join("specular.gltf");
    write(&path, serde_json::to_vec(&doc).unwrap());
    path
}

#[test]
fn gltf_specular_extension_and_texture_transform() {
    let dir = tempfile::tempdir().unwrap();
    let path = specular_gltf(dir.path(), &[], &["KHR_materials_specular"]);
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    let wall = &scene.objects[scene.object_index("wall").unwrap()];
    let m = &scene.materials[wall.material];
    assert_eq!(m.specular, 0.25);
    assert_eq!(m.specular_color, Vec3::new(1.0, 0.5, 2.0));
    // The factor's texture is linear (its alpha is read), the colour's sRGB.
    let (factor_tex, color_tex) = (m.specular_texture.unwrap(), m.specular_color_texture.unwrap());
    assert!(!scene.textures[factor_tex].is_color && scene.textures[color_tex].is_color);
    // KHR_texture_transform is baked into the wall's UVs: uv' = (0.5, 0) + 2 uv.
    let uvs = &scene.meshes[wall.mesh].uvs;
    assert_eq!(uvs[0], glam::Vec2::new(0.5, 2.0), "{uvs:?}");
    assert_eq!(uvs[1], glam::Vec2::new(2.5, 2.0), "{uvs:?}");
    // The glass without textures keeps its UVs (none) and the glTF default specular layer.
    let glass = &scene.materials[scene.objects[scene.object_index("glass").unwrap()].material];
    assert!(glass.has_default_specular());
    assert!(scene.warnings().is_empty(), "{:?}", scene.warnings());
    // specularFactor 0 is a Lambertian surface, and the content hash sees the difference.
    let lambertian = glassbake_scene::model::Material::lambertian("white", Vec3::ONE);
    assert_eq!(lambertian.specular, 0.0);
    let mut other = scene.clone();
    let material = wall.material;
    other.materials[material].specular = 0.0;
    assert_ne!(scene.content_hash(), other.content_hash());
}

#[test]
fn unsupported_gltf_extensions_are_refused_or_warned_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = specular_gltf(dir.path(), &["KHR_draco_mesh_compression"], &["KHR_materials_specular", "KHR_draco_mesh_compression"]);
    expect_bad_input(load_scene(path.to_str().unwrap()), "specular.gltf", "extensionsRequired[1]");
    match load_scene(path.to_str().unwrap()) {
        Err(e) => assert!(e.to_string().contains("KHR_draco_mesh_compression"), "{e}"),
        Ok(_) => unreachable!(),
    }
    let path = specular_gltf(dir.path(), &["KHR_materials_clearcoat", "KHR_materials_sheen"], &[]);
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    let warnings = scene.warnings();
    assert!(warnings.iter().any(|w| w.contains("KHR_materials_clearcoat")), "{warnings:?}");
    assert!(warnings.iter().any(|w| w.contains("KHR_materials_sheen")), "{warnings:?}");
}

#[test]
fn obj_illumination_models_set_the_specular_layer() {
    let dir = tempfile::tempdir().unwrap();
    write(
        &dir.path().join("m.mtl"),
        "newmtl chalk\nKd 0.8 0.8 0.8\nillum 1\nnewmtl flat\nKd 0.5 0.5 0.5\nillum 0\n\
         newmtl plastic\nKd 0.2 0.3 0.4\nKs 0.08 0.04 0.02\nNs 100\nillum 2\nnewmtl matte\nKd 0.5 0.5 0.5\nKs 0 0 0\nillum 2\n\
         newmtl plain\nKd 0.5 0.5 0.5\n\
         newmtl pane\nKd 0 0 0\nTf 0.9 0.9 0.9\nNi 1.5\nillum 7\n",
    );
    let mut obj = String::from("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\n");
    for name in ["chalk", "flat", "plastic", "matte", "plain", "pane"] {
        obj.push_str(&format!("o {name}\nusemtl {name}\nf 1 2 3\n"));
    }
    let path = dir.path().join("m.obj");
    write(&path, &obj);
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    let material = |object: &str| scene.materials[scene.objects[scene.object_index(object).unwrap()].material].clone();
    assert_eq!(material("chalk").specular, 0.0, "illum 1 is Lambertian");
    assert_eq!(material("flat").specular, 0.0, "illum 0 is Lambertian");
    let plastic = material("plastic");
    assert_eq!(plastic.specular, 1.0);
    // Ks is the reflectance at normal incidence: F0 = 0.04 x colour = Ks.
    assert!((plastic.specular_color * 0.04 - Vec3::new(0.08, 0.04, 0.02)).abs().max_element() < 1e-6, "{}", plastic.specular_color);
    assert_eq!(material("matte").specular, 0.0, "Ks 0 has no specular layer");
    assert!(material("plain").has_default_specular(), "no illum, no Ks: glTF's default layer");
    assert_eq!(material("pane").dielectric_kind(), Some(DielectricKind::Smooth));

    // A manifest makes the OBJ pane thin, for that object only.
    let manifest = dir.path().join("m.toml");
    write(&manifest, format!("{}\n[objects.pane]\nthin = true\n", manifest_text("m.obj", "")));
    let scene = load_scene(manifest.to_str().unwrap()).unwrap();
    let pane = &scene.materials[scene.objects[scene.object_index("pane").unwrap()].material];
    assert_eq!(pane.dielectric_kind(), Some(DielectricKind::Thin));
    // thin on an opaque object is refused, naming the field.
    write(&manifest, format!("{}\n[objects.chalk]\nthin = true\n", manifest_text("m.obj", "")));
    expect_bad_input(load_scene(manifest.to_str().unwrap()), "m.toml", "objects.chalk.thin");
}

/// Objects the geometry file gives one name are told apart (`wall`, `wall#1`) with a warning,
/// never colliding with a name the file uses itself; a manifest naming such a name is refused
/// instead of addressing whichever came first.
#[test]
fn repeated_object_names_are_warned_and_a_manifest_cannot_address_them() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_quad_gltf(dir.path(), false);
    let mut doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    doc["nodes"][1]["name"] = json!("wall");
    write(&path, serde_json::to_vec(&doc).unwrap());
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["wall", "wall#1"]);
    assert!(scene.warnings().iter().any(|w| w.contains("2 objects are named \"wall\"")), "{:?}", scene.warnings());
    let variables = "[[variables]]\nname = \"slide\"\nrange = [0.0, 1.0]\ntarget = { kind = \"translation\", object = \"wall\", axis = [1.0, 0.0, 0.0] }\n";
    let manifest = dir.path().join("scene.toml");
    write(&manifest, manifest_text("quad.gltf", variables));
    expect_bad_input(load_scene(manifest.to_str().unwrap()), "scene.toml", "variables[0] (slide).target.object");
    // A third node named like a told-apart name keeps its own name; the repeat moves on.
    doc["nodes"].as_array_mut().unwrap().push(json!({"name": "wall#1", "mesh": 0, "translation": [0.0, 0.0, 4.0]}));
    doc["scenes"][0]["nodes"] = json!([2, 0, 1]);
    write(&path, serde_json::to_vec(&doc).unwrap());
    let scene = load_scene(path.to_str().unwrap()).unwrap();
    let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["wall#1", "wall", "wall#2"]);
}

#[test]
fn a_scene_folder_in_memory_loads_as_it_does_from_disk_and_reads_nothing_else() {
    use std::collections::BTreeMap;
    let original = builtin("desk").unwrap();
    let dir = tempfile::tempdir().unwrap();
    glassbake_scene::export::export_scene(&original, dir.path(), false).unwrap();
    let on_disk = load_scene(dir.path().join("manifest.toml").to_str().unwrap()).unwrap();
    let mut files = BTreeMap::new();
    let mut stack = vec![dir.path().to_path_buf()];
    while let Some(folder) = stack.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let name = path.strip_prefix(dir.path()).unwrap().to_str().unwrap().replace('\\', "/");
                files.insert(format!("scene/{name}"), std::fs::read(&path).unwrap());
            }
        }
    }
    let in_memory = glassbake_scene::load::load_scene_from_memory("scene/manifest.toml", &files).unwrap();
    assert_eq!(in_memory.content_hash(), on_disk.content_hash());
    // A reference to a file the folder does not hold is refused, naming the file and field,
    // even where a file of that name exists on disk beside the process.
    let manifest = String::from_utf8(files["scene/manifest.toml"].clone()).unwrap();
    let geometry = manifest.lines().find(|l| l.starts_with("geometry")).unwrap().to_string();
    let moved = manifest.replace(&geometry, "geometry = \"elsewhere.gltf\"");
    files.insert("scene/manifest.toml".into(), moved.into_bytes());
    let err = glassbake_scene::load::load_scene_from_memory("scene/manifest.toml", &files).unwrap_err().to_string();
    assert!(err.contains("scene/manifest.toml") && err.contains("geometry") && err.contains("not among the scene's files"), "{err}");
    let escaping = manifest.replace(&geometry, "geometry = \"../outside.gltf\"");
    files.insert("scene/manifest.toml".into(), escaping.into_bytes());
    assert!(glassbake_scene::load::load_scene_from_memory("scene/manifest.toml", &files).is_err());
    assert!(glassbake_scene::load::load_scene_from_memory("scene/missing.toml", &files).is_err());
}
