//! Dataset generation end to end at tiny sizes (real path tracer, real rasterizer on
//! lavapipe): resume, corrupt-file detection, shard/merge byte equality, refusals, splits,
//! and the loader.

use std::collections::BTreeMap;
use std::path::Path;

use glassbake_core::layout::transparent;
use glassbake_core::{Error, PlanarImage};
use glassbake_dataset::store::{checksum_path, FrameStatus};
use glassbake_dataset::{
    generate, merge, upgrade, DatasetSpec, DatasetStore, GenerateOptions, GenerateProgress, Loader, LoaderOptions, ShardSpec, Split, TraceDevice,
};
use glassbake_scene::builtin::builtin;
use glassbake_trace::Estimator;

/// A small dataset whose training frames are traced at 1.5x their spp on glass pixels, its
/// test frames at 4x the training spp, 6x on glass pixels (so resume and merge cover the test
/// frames' training-spp copies too), with enough samples on the test frames (256) for
/// adaptive sampling to run.
fn spec(seed: u64) -> DatasetSpec {
    DatasetSpec {
        scene: "cornell-glass".into(),
        resolution: 8,
        spp: 64,
        glass_spp: Some(96),
        seed,
        train: 4,
        val: 2,
        test: 2,
        cache_buffers: true,
        device: TraceDevice::Cpu,
        test_spp: Some(256),
        test_glass_spp: Some(384),
        // The CPU default, so that resume and merge cover the light tracer, adaptive sampling
        // and stratified sample values too.
        estimator: Estimator::default(),
    }
}

fn no_progress(_: GenerateProgress) {}

/// Every file under `dir`, relative path -> bytes.
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    for sub in ["", "gt", "gt-train-spp", "buffers", "preview"] {
        for entry in std::fs::read_dir(dir.join(sub)).unwrap().flatten() {
            if entry.file_type().unwrap().is_file() {
                files.insert(format!("{sub}/{}", entry.file_name().to_string_lossy()), std::fs::read(entry.path()).unwrap());
            }
        }
    }
    files
}

#[test]
fn resume_redoes_exactly_what_is_missing_or_corrupt() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    let first = generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!((first.generated, first.skipped, first.frames_in_shard), (8, 0, 8));
    let reference = snapshot(&d);
    assert_eq!(reference.keys().filter(|k| k.starts_with("gt/") && k.ends_with(".exr")).count(), 8);

    // An interrupted run leaves: a missing frame, a truncated file, a stale temp file.
    let store = DatasetStore::open(&d).unwrap();
    std::fs::remove_file(store.gt_path(2)).unwrap();
    let truncated = std::fs::read(store.buffers_path(5)).unwrap();
    std::fs::write(store.buffers_path(5), &truncated[..truncated.len() / 2]).unwrap();
    std::fs::write(d.join("gt/.000006.exr.tmp999"), b"half").unwrap();

    let second = generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!((second.generated, second.skipped, second.redone), (2, 6, 1));
    assert_eq!(snapshot(&d), reference, "the completed set equals an uninterrupted run");

    let third = generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!((third.generated, third.skipped), (0, 8));

    // Only the writer's own temp names are removed, and never through a symbolic link: a
    // user's hidden file in a frame folder, and the temp-looking files of a folder that
    // `preview` links to, survive a resume.
    std::fs::write(d.join("gt/.notes.tmp"), b"mine").unwrap();
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    std::fs::write(elsewhere.join(".000001.png.tmp5"), b"not the dataset's").unwrap();
    for entry in std::fs::read_dir(d.join("preview")).unwrap().flatten() {
        std::fs::copy(entry.path(), elsewhere.join(entry.file_name())).unwrap();
    }
    std::fs::remove_dir_all(d.join("preview")).unwrap();
    std::os::unix::fs::symlink(&elsewhere, d.join("preview")).unwrap();
    generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!(std::fs::read(d.join("gt/.notes.tmp")).unwrap(), b"mine");
    assert_eq!(std::fs::read(elsewhere.join(".000001.png.tmp5")).unwrap(), b"not the dataset's");
}

#[test]
fn a_frame_whose_bytes_changed_after_writing_is_named_and_made_again() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    let reference = snapshot(&d);
    let store = DatasetStore::open(&d).unwrap();
    for index in 0..8 {
        for file in store.frame_files(index) {
            let line = std::fs::read_to_string(checksum_path(&file)).unwrap();
            let (hex, name) = line.trim_end().split_once("  ").unwrap();
            assert!(hex.len() == 64 && hex.bytes().all(|b| b.is_ascii_hexdigit()), "{line}");
            assert_eq!(name, file.file_name().unwrap().to_string_lossy());
        }
    }

    // Every one-byte change is caught, also those that still decode to finite pixels, which a
    // check by decoding alone lets through.
    let path = store.gt_path(3);
    let original = std::fs::read(&path).unwrap();
    let mut decodes_fine = None;
    for offset in 0..original.len() {
        let mut rotten = original.clone();
        rotten[offset] ^= 0x10;
        std::fs::write(&path, &rotten).unwrap();
        if PlanarImage::read_exr(&path).is_ok_and(|image| image.data().iter().all(|v| v.is_finite())) {
            decodes_fine = Some(rotten);
        }
        assert!(matches!(store.frame_status(3), FrameStatus::Corrupt(_)), "a change at byte {offset} went unnoticed");
    }
    let rotten = decodes_fine.expect("some one-byte change still decodes");
    std::fs::write(&path, &rotten).unwrap();
    let info = store.info();
    assert_eq!(info.damaged.len(), 1, "{:?}", info.damaged);
    assert!(info.damaged[0].starts_with("frame 3: ") && info.damaged[0].contains("SHA-256"), "{}", info.damaged[0]);
    assert!(info.damaged_summary().contains("frame 3: "));
    drop(store);

    let resumed = generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!((resumed.generated, resumed.redone), (1, 1));
    assert_eq!(snapshot(&d), reference);
}

/// Each frame file is bound to its dataset and index: one swapped with another frame of the
/// dataset, one copied in (with its checksum) from another dataset, and one whose checksum is
/// gone are all named and made again, for every kind of frame file (ground truth, its
/// training-spp copy, cached buffers).
#[test]
fn frames_copied_swapped_or_without_their_checksum_are_made_again() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (d, other) = (dir.path().join("set"), dir.path().join("other"));
    generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    generate(&scene, &spec(2), &other, &GenerateOptions::default(), &no_progress).unwrap();
    let reference = snapshot(&d);
    let (store, other_store) = (DatasetStore::open(&d).unwrap(), DatasetStore::open(&other).unwrap());
    // Frame 6 is a test frame: it has all three kinds of file.
    let files = store.frame_files(6);
    assert_eq!(files.len(), 3, "{files:?}");
    let copy_with_checksum = |from: &Path, to: &Path| {
        std::fs::copy(from, to).unwrap();
        std::fs::copy(checksum_path(from), checksum_path(to)).unwrap();
    };
    for (kind, file) in files.iter().enumerate() {
        let name = |index: u64| file.with_file_name(format!("{index:06}.exr"));
        let original = (std::fs::read(file).unwrap(), std::fs::read(checksum_path(file)).unwrap());
        let restore = || {
            std::fs::write(file, &original.0).unwrap();
            std::fs::write(checksum_path(file), &original.1).unwrap();
        };
        // Frame 7's file (another test frame, so it exists) put in frame 6's place, both the
        // frame alone and with its checksum renamed as well.
        std::fs::copy(name(7), file).unwrap();
        assert!(matches!(store.frame_status(6), FrameStatus::Corrupt(_)), "kind {kind}: a swapped frame passed");
        std::fs::copy(checksum_path(&name(7)), checksum_path(file)).unwrap();
        assert!(matches!(store.frame_status(6), FrameStatus::Corrupt(_)), "kind {kind}: a swapped frame with its checksum passed");
        restore();
        // The same frame index of another dataset (another seed), with its checksum.
        let theirs = other_store.frame_files(6)[kind].clone();
        copy_with_checksum(&theirs, file);
        match store.frame_status(6) {
            FrameStatus::Corrupt(why) => assert!(why.contains("another dataset"), "{why}"),
            status => panic!("kind {kind}: another dataset's frame passed: {status:?}"),
        }
        restore();
        // No checksum.
        std::fs::remove_file(checksum_path(file)).unwrap();
        assert!(matches!(store.frame_status(6), FrameStatus::Corrupt(_)), "kind {kind}: a frame without its checksum passed");
        restore();
        assert!(matches!(store.frame_status(6), FrameStatus::Done));
    }
    // Put in place for good, they are made again, and the dataset is as it was.
    copy_with_checksum(&other_store.frame_files(6)[0], &files[0]);
    drop(store);
    let resumed = generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!((resumed.generated, resumed.redone), (1, 1));
    assert_eq!(snapshot(&d), reference);
}

#[test]
fn a_manifest_changed_after_writing_is_refused_not_trusted() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    let path = d.join("manifest.json");
    let written = std::fs::read(&path).unwrap();
    // Formatting alone is no change.
    let value: serde_json::Value = serde_json::from_slice(&written).unwrap();
    std::fs::write(&path, serde_json::to_vec(&value).unwrap()).unwrap();
    DatasetStore::open(&d).unwrap();
    // One transparent object cut from the scene record: train would build a GlassNet for two.
    let mut cut = value.clone();
    cut["scene"]["transparent_objects"].as_array_mut().unwrap().pop();
    std::fs::write(&path, serde_json::to_vec_pretty(&cut).unwrap()).unwrap();
    let err = DatasetStore::open(&d).err().expect("an edited manifest is refused").to_string();
    assert!(err.contains("manifest.json") && err.contains("content_sha256") && err.contains("changed"), "{err}");
    let err = generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap_err().to_string();
    assert!(err.contains("content_sha256"), "{err}");
    std::fs::write(&path, &written).unwrap();
    DatasetStore::open(&d).unwrap();
}

#[test]
fn a_creation_cut_short_before_its_manifest_is_continued() {
    // A kill or a full disk between taking the lock and writing the manifest leaves the lock
    // file and perhaps the manifest's temp file; the same command then starts the dataset.
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    std::fs::create_dir(&d).unwrap();
    std::fs::write(d.join(".glassbake-writer.lock"), b"").unwrap();
    std::fs::write(d.join(".manifest.json.tmp4242"), b"{ \"format_ver").unwrap();
    let made = generate(&scene, &spec(1), &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!(made.generated, 8);
    assert!(!d.join(".manifest.json.tmp4242").exists());
    // Anything else there is still the user's, and refused.
    let other = dir.path().join("other");
    std::fs::create_dir(&other).unwrap();
    std::fs::write(other.join(".glassbake-writer.lock"), b"").unwrap();
    std::fs::write(other.join("notes.txt"), b"mine").unwrap();
    let err = generate(&scene, &spec(1), &other, &GenerateOptions::default(), &no_progress).unwrap_err().to_string();
    assert!(err.contains("not empty"), "{err}");
}

#[test]
fn test_frames_are_traced_at_the_test_spp_and_glass_spp_with_an_independent_training_spp_copy() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    let s = spec(7);
    generate(&scene, &s, &d, &GenerateOptions::default(), &no_progress).unwrap();
    let store = DatasetStore::open(&d).unwrap();
    let info = store.info();
    assert_eq!((info.spp, info.test_spp, info.test_glass_spp), (64, 256, 384));
    let render = |sample: &glassbake_dataset::SampleRecord, spp: u32, glass_spp: u32, seed: u64| {
        let settings =
            glassbake_trace::TraceSettings { glass_spp: Some(glass_spp), estimator: s.estimator, ..glassbake_trace::TraceSettings::new(8, 8, spp, seed) };
        glassbake_trace::render(&scene.instantiate(&sample.values).unwrap(), &sample.camera, &settings, None).unwrap().image
    };
    let trace_with_glass = |index: u64, spp: u32, glass_spp: u32, seed: u64| render(&store.manifest.samples[index as usize], spp, glass_spp, seed);
    let trace = |index: u64, spp: u32, seed: u64| trace_with_glass(index, spp, spp, seed);
    let mut glass_shown = false;
    let mut glass_shown_in_training = false;
    let read = |path: &Path| glassbake_core::PlanarImage::read_exr(path).unwrap();
    for sample in &store.manifest.samples {
        let gt = read(&store.gt_path(sample.index));
        let copy_path = store.train_spp_gt_path(sample.index);
        if sample.split == Split::Test {
            let seed = glassbake_trace::sample_trace_seed(sample.seed);
            assert_eq!(gt.plane_by_name("R"), trace_with_glass(sample.index, 256, 384, seed).plane_by_name("R"), "frame {}", sample.index);
            glass_shown |= gt.plane_by_name("R") != trace(sample.index, 256, seed).plane_by_name("R");
            let copy = read(&copy_path);
            let seed = glassbake_core::seed::purpose_seed(sample.seed, "training-spp copy of a test frame");
            assert_eq!(copy.plane_by_name("R"), trace_with_glass(sample.index, 64, 96, seed).plane_by_name("R"), "the copy is traced as training frames are");
            assert_ne!(copy.plane_by_name("R"), gt.plane_by_name("R"), "the copy is an independent trace");
        } else {
            let seed = glassbake_trace::sample_trace_seed(sample.seed);
            assert_eq!(gt.plane_by_name("R"), trace_with_glass(sample.index, 64, 96, seed).plane_by_name("R"), "frame {}", sample.index);
            glass_shown_in_training |= gt.plane_by_name("R") != trace(sample.index, 64, seed).plane_by_name("R");
            assert!(!copy_path.exists(), "frame {} is not a test frame", sample.index);
        }
    }
    assert!(glass_shown, "no test frame shows the pane: the glass spp went unchecked");
    assert!(glass_shown_in_training, "no training frame shows the pane: its glass spp went unchecked");
    // A test frame without its copy is incomplete and is made again.
    let test_frame = store.manifest.indices_of(Split::Test)[0];
    std::fs::remove_file(store.train_spp_gt_path(test_frame)).unwrap();
    drop(store);
    let again = generate(&scene, &s, &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!((again.generated, again.skipped), (1, 7));
    // Without --test-spp and --glass-spp nothing changes for old datasets: no copies, test
    // and glass pixels at --spp.
    let plain = dir.path().join("plain");
    let old_style = DatasetSpec { glass_spp: None, test_spp: None, test_glass_spp: None, ..s.clone() };
    generate(&scene, &old_style, &plain, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!(std::fs::read_dir(plain.join("gt-train-spp")).unwrap().count(), 0);
    let manifest = std::fs::read_to_string(plain.join("manifest.json")).unwrap();
    assert!(!manifest.contains("test_spp") && !manifest.contains("glass_spp"), "an old-style manifest stays as it was");
    let old_store = DatasetStore::open(&plain).unwrap();
    for sample in &old_store.manifest.samples {
        let gt = read(&old_store.gt_path(sample.index));
        assert_eq!(gt.plane_by_name("R"), render(sample, 64, 64, glassbake_trace::sample_trace_seed(sample.seed)).plane_by_name("R"));
    }
}

#[test]
fn progress_counts_traced_samples() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let seen = std::sync::Mutex::new(Vec::new());
    let record = |p: GenerateProgress| seen.lock().unwrap().push(p);
    generate(&scene, &spec(8), &dir.path().join("set"), &GenerateOptions::default(), &record).unwrap();
    let seen = seen.into_inner().unwrap();
    // 6 train/val frames at 64 spp (a quarter of the 32 more on glass pixels, as estimated), 2
    // test frames at 256 spp (a quarter of the 128 more) plus a copy traced as training
    // frames are.
    let last = *seen.last().unwrap();
    assert_eq!((last.frames_done, last.frames_total, last.work_done, last.work_total), (8, 8, 6 * (64 + 8) + 2 * (256 + 32 + 64 + 8), 1152));
    assert_eq!(seen.len(), 9);
    assert!(seen.windows(2).all(|w| w[1].work_done > w[0].work_done));
}

#[test]
fn shards_merge_into_the_single_machine_dataset_byte_for_byte() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let single = dir.path().join("single");
    generate(&scene, &spec(2), &single, &GenerateOptions::default(), &no_progress).unwrap();
    let mut shard_dirs = Vec::new();
    for i in 0..3 {
        let d = dir.path().join(format!("shard{i}"));
        let options = GenerateOptions { shard: ShardSpec { index: i, count: 3 }, threads: Some(1), ..Default::default() };
        let summary = generate(&scene, &spec(2), &d, &options, &no_progress).unwrap();
        assert_eq!(summary.generated, (0..8).filter(|f| f % 3 == i).count() as u64);
        shard_dirs.push(d);
    }
    let merged = dir.path().join("merged");
    // Merging an incomplete set of shards is refused and writes nothing.
    let partial: Vec<&Path> = shard_dirs[..2].iter().map(|p| p.as_path()).collect();
    assert!(matches!(merge(&merged, &partial), Err(Error::BadInput { .. })));
    assert!(!merged.exists());
    let all: Vec<&Path> = shard_dirs.iter().map(|p| p.as_path()).collect();
    // Shards of two tracer revisions are refused and write nothing.
    set_manifest_field(&shard_dirs[1], "tracer_revision", Some((glassbake_trace::TRACER_REVISION + 1).into()));
    let err = merge(&merged, &all).expect_err("two revisions").to_string();
    assert!(err.contains("tracer revision"), "{err}");
    assert!(!merged.exists());
    set_manifest_field(&shard_dirs[1], "tracer_revision", Some(glassbake_trace::TRACER_REVISION.into()));
    // So are shards traced with two ray casters; a shard from before the field was recorded
    // counts as obvhs, the only caster then.
    set_manifest_field(&shard_dirs[1], "ray_caster", Some("another-caster".into()));
    let err = merge(&merged, &all).expect_err("two ray casters").to_string();
    assert!(err.contains("ray caster") && err.contains("another-caster"), "{err}");
    assert!(!merged.exists());
    set_manifest_field(&shard_dirs[0], "ray_caster", Some("embree".into()));
    set_manifest_field(&shard_dirs[1], "ray_caster", None);
    let err = merge(&merged, &all).expect_err("embree and an unrecorded (obvhs) shard").to_string();
    assert!(err.contains("embree") && err.contains("obvhs"), "{err}");
    assert!(!merged.exists());
    set_manifest_field(&shard_dirs[0], "ray_caster", Some(glassbake_trace::RAY_CASTER.into()));
    set_manifest_field(&shard_dirs[1], "ray_caster", Some(glassbake_trace::RAY_CASTER.into()));
    assert_eq!(merge(&merged, &all).unwrap(), 8);
    assert_eq!(snapshot(&merged), snapshot(&single));
}

#[test]
fn a_different_command_on_an_existing_dataset_is_refused() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    let tiny = DatasetSpec { train: 1, val: 0, test: 0, ..spec(3) };
    generate(&scene, &tiny, &d, &GenerateOptions::default(), &no_progress).unwrap();
    let other_scene = builtin("cornellbox").unwrap();
    let refusals = [
        (scene.clone(), DatasetSpec { seed: 4, ..tiny.clone() }, "--seed"),
        (scene.clone(), DatasetSpec { resolution: 16, ..tiny.clone() }, "--res"),
        (scene.clone(), DatasetSpec { spp: 4, glass_spp: None, ..tiny.clone() }, "--spp"),
        (scene.clone(), DatasetSpec { glass_spp: Some(128), ..tiny.clone() }, "--glass-spp"),
        (scene.clone(), DatasetSpec { test_spp: Some(512), test_glass_spp: Some(512), ..tiny.clone() }, "--test-spp"),
        (scene.clone(), DatasetSpec { test_glass_spp: Some(512), ..tiny.clone() }, "--test-glass-spp"),
        (scene.clone(), DatasetSpec { estimator: Estimator::parse("caustic").unwrap(), ..tiny.clone() }, "--estimator"),
        (scene.clone(), DatasetSpec { train: 2, ..tiny.clone() }, "--train"),
        (scene.clone(), DatasetSpec { estimator: Estimator::PLAIN, ..tiny.clone() }, "--estimator"),
        (other_scene, tiny.clone(), "different scene"),
    ];
    for (scene, spec, why) in refusals {
        match generate(&scene, &spec, &d, &GenerateOptions::default(), &no_progress) {
            Err(Error::BadInput { file, message, .. }) => {
                assert!(file.ends_with("manifest.json"), "{file}");
                assert!(message.contains(why), "{message} should mention {why}");
            }
            other => panic!("expected a refusal for {why}, got {:?}", other.map(|s| s.generated)),
        }
    }
    // Frames of another tracer revision would not be the bytes one run makes: refused, with
    // the field named; a manifest from before revisions were recorded is continued.
    let revision = glassbake_trace::TRACER_REVISION;
    assert_eq!(DatasetStore::open(&d).unwrap().manifest.tracer_revision, Some(revision));
    set_manifest_field(&d, "tracer_revision", Some((revision + 1).into()));
    match generate(&scene, &tiny, &d, &GenerateOptions::default(), &no_progress) {
        Err(Error::BadInput { file, message, .. }) => {
            assert!(file.ends_with("manifest.json"), "{file}");
            assert!(message.contains(&format!("tracer revision {}", revision + 1)), "{message}");
        }
        other => panic!("expected a refusal for the tracer revision, got {:?}", other.map(|s| s.generated)),
    }
    set_manifest_field(&d, "tracer_revision", None);
    let continued = generate(&scene, &tiny, &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!((continued.generated, continued.skipped), (0, 1));
    assert_eq!(DatasetStore::open(&d).unwrap().manifest.tracer_revision, None, "an unknown revision stays unknown");
    // The same for frames cast by another ray caster (a build with or without `embree`).
    assert_eq!(DatasetStore::open(&d).unwrap().manifest.ray_caster.as_deref(), Some(glassbake_trace::RAY_CASTER));
    set_manifest_field(&d, "ray_caster", Some("another-caster".into()));
    match generate(&scene, &tiny, &d, &GenerateOptions::default(), &no_progress) {
        Err(Error::BadInput { file, message, .. }) => {
            assert!(file.ends_with("manifest.json"), "{file}");
            assert!(message.contains("another-caster ray caster"), "{message}");
        }
        other => panic!("expected a refusal for the ray caster, got {:?}", other.map(|s| s.generated)),
    }
    // A manifest from before the field was cast by obvhs, the only caster then: continued by
    // an obvhs build, refused by an Embree one.
    set_manifest_field(&d, "ray_caster", None);
    assert_eq!(DatasetStore::open(&d).unwrap().info().ray_caster.as_deref(), Some("obvhs"));
    let result = generate(&scene, &tiny, &d, &GenerateOptions::default(), &no_progress);
    if glassbake_trace::RAY_CASTER == "obvhs" {
        let continued = result.unwrap();
        assert_eq!((continued.generated, continued.skipped), (0, 1));
        assert_eq!(DatasetStore::open(&d).unwrap().manifest.ray_caster, None, "the manifest is not rewritten");
    } else {
        assert!(matches!(&result, Err(Error::BadInput { message, .. }) if message.contains("obvhs ray caster")), "{:?}", result.map(|s| s.generated));
    }
    // Glass pixels below the test spp are refused before anything is written.
    let below = dir.path().join("below");
    let result = generate(&scene, &DatasetSpec { test_glass_spp: Some(128), ..spec(3) }, &below, &GenerateOptions::default(), &no_progress);
    assert!(matches!(&result, Err(Error::BadInput { field, .. }) if field == "--test-glass-spp"), "{:?}", result.map(|s| s.generated));
    assert!(!below.exists());
    let result = generate(&scene, &DatasetSpec { glass_spp: Some(32), ..spec(3) }, &below, &GenerateOptions::default(), &no_progress);
    assert!(matches!(&result, Err(Error::BadInput { field, .. }) if field == "--glass-spp"), "{:?}", result.map(|s| s.generated));
    assert!(!below.exists());
    // The GPU tracer has no light tracer.
    let gpu = dir.path().join("gpu");
    let result = generate(&scene, &DatasetSpec { device: TraceDevice::Wgpu, ..spec(3) }, &gpu, &GenerateOptions::default(), &no_progress);
    assert!(matches!(&result, Err(Error::BadInput { field, .. }) if field == "--estimator"), "{:?}", result.map(|s| s.generated));
    assert!(!gpu.exists());
    // A non-empty directory that is not a dataset is never written into.
    let foreign = dir.path().join("foreign");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
    assert!(generate(&scene, &tiny, &foreign, &GenerateOptions::default(), &no_progress).is_err());
    assert_eq!(std::fs::read_dir(&foreign).unwrap().count(), 1);
}

#[test]
fn splits_are_disjoint_and_cover_the_set() {
    let scene = builtin("cornellbox").unwrap();
    let s = DatasetSpec {
        scene: "cornellbox".into(),
        resolution: 8,
        spp: 1,
        glass_spp: None,
        seed: 0,
        train: 7,
        val: 3,
        test: 5,
        cache_buffers: false,
        device: TraceDevice::Cpu,
        test_spp: None,
        test_glass_spp: None,
        estimator: Estimator::parse("caustic").unwrap(),
    };
    let manifest = glassbake_dataset::DatasetManifest::plan(&s, &scene);
    let train = manifest.indices_of(Split::Train);
    let val = manifest.indices_of(Split::Val);
    let test = manifest.indices_of(Split::Test);
    assert_eq!((train.len(), val.len(), test.len()), (7, 3, 5));
    let mut all: Vec<u64> = [train, val, test].concat();
    all.sort();
    all.dedup();
    assert_eq!(all, (0..15).collect::<Vec<_>>());
    // No two frames share a camera (a test frame is never a training frame in disguise).
    for a in &manifest.samples {
        for b in &manifest.samples {
            if a.index != b.index {
                assert_ne!(a.camera, b.camera);
            }
        }
    }
}

#[test]
fn loader_batches_crops_and_matches_rasterizing_again() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let cached = dir.path().join("cached");
    let s = DatasetSpec { resolution: 16, ..spec(5) };
    generate(&scene, &s, &cached, &GenerateOptions::default(), &no_progress).unwrap();
    let uncached = dir.path().join("uncached");
    generate(&scene, &DatasetSpec { cache_buffers: false, ..s.clone() }, &uncached, &GenerateOptions::default(), &no_progress).unwrap();

    let options = LoaderOptions { batch_size: 3, crop: Some(8), seed: 9, naive: true, workers: 2, ..Default::default() };
    let mut loader = Loader::new(&cached, None, options.clone()).unwrap();
    assert_eq!(loader.len(), 4);
    let epoch0 = loader.epoch(0).unwrap();
    assert_eq!(epoch0.iter().map(Vec::len).collect::<Vec<_>>(), vec![3, 1]);
    let order0: Vec<u64> = epoch0.iter().flatten().map(|e| e.index).collect();
    let mut sorted = order0.clone();
    sorted.sort();
    assert_eq!(sorted, vec![0, 1, 2, 3], "train split only, each frame once");
    for e in epoch0.iter().flatten() {
        assert_eq!((e.opaque.width(), e.ground_truth.width(), e.mask.height()), (8, 8, 8));
        assert_eq!(e.transparent.len(), 1);
        assert!(e.naive.is_some());
        assert!(e.values.iter().all(|v| (0.0..=1.0).contains(v)));
        let coverage = e.transparent[0].plane(transparent::COVERAGE);
        assert_eq!(e.mask.plane(0), coverage, "one object: the mask is its coverage");
    }
    // Same seed, same epoch: same order and crops; another epoch: reshuffled.
    let again = Loader::new(&cached, None, options.clone()).unwrap().epoch(0).unwrap();
    let order_again: Vec<u64> = again.iter().flatten().map(|e| e.index).collect();
    assert_eq!(order0, order_again);
    assert_eq!(again[0][0].ground_truth, epoch0[0][0].ground_truth);
    let orders: Vec<Vec<u64>> = (1..6).map(|e| loader.epoch_order(e)).collect();
    assert!(orders.iter().any(|o| *o != order0), "epochs reshuffle");

    // Without cached buffers the loader rasterizes again and gets the same frames (f16 cache).
    assert!(Loader::new(&uncached, None, options.clone()).is_err(), "the scene is required");
    let mut raster_loader = Loader::new(&uncached, Some(scene.clone()), options).unwrap();
    let rerendered = raster_loader.epoch(0).unwrap();
    for (a, b) in rerendered.iter().flatten().zip(epoch0.iter().flatten()) {
        assert_eq!(a.index, b.index);
        assert_eq!(a.ground_truth, b.ground_truth);
        for (x, y) in a.opaque.data().iter().zip(b.opaque.data()) {
            assert!((x - y).abs() <= 2e-3 * x.abs().max(1.0), "{x} vs {y}");
        }
    }
}

/// Sets (or, with `None`, removes) a top-level field of the dataset manifest in `dir`.
/// Makes the manifest look as an older glassbake wrote it: `field` set or removed, and no
/// `content_sha256` (older glassbakes recorded none).
fn set_manifest_field(dir: &Path, field: &str, value: Option<serde_json::Value>) {
    let path = dir.join("manifest.json");
    let mut manifest: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let object = manifest.as_object_mut().unwrap();
    object.remove("content_sha256");
    match value {
        Some(value) => object.insert(field.to_string(), value),
        None => object.remove(field),
    };
    std::fs::write(&path, serde_json::to_vec_pretty(&manifest).unwrap()).unwrap();
}

/// Rewrites the `format_version` of the dataset manifest in `dir`.
fn set_format_version(dir: &Path, version: u32) {
    let path = dir.join("manifest.json");
    let mut manifest: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    manifest["format_version"] = version.into();
    manifest.as_object_mut().unwrap().remove("content_sha256");
    std::fs::write(&path, serde_json::to_vec_pretty(&manifest).unwrap()).unwrap();
}

#[test]
fn a_dataset_of_the_previous_format_has_its_buffers_rasterized_again() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    generate(&scene, &spec(6), &d, &GenerateOptions::default(), &no_progress).unwrap();
    let options = LoaderOptions { batch_size: 4, seed: 1, workers: 1, ..Default::default() };
    let current: Vec<_> = Loader::new(&d, None, options.clone()).unwrap().epoch(0).unwrap().into_iter().flatten().collect();

    // Cached buffers of format 1 (no L_d) and 2 (no L_d_far, point-sampled L_d) must not be
    // read at all: with them deleted, the loader rasterizes today's buffers from the scene.
    for entry in std::fs::read_dir(d.join("buffers")).unwrap().flatten() {
        std::fs::remove_file(entry.path()).unwrap();
    }
    for version in [1, 2] {
        set_format_version(&d, version);
        let store = DatasetStore::open(&d).unwrap();
        assert!(store.manifest.spec.cache_buffers && !store.manifest.reads_cached_buffers());
        let err = Loader::new(&d, None, options.clone()).err().expect("the scene is required").to_string();
        assert!(err.contains("scene"), "{err}");
        let old: Vec<_> = Loader::new(&d, Some(scene.clone()), options.clone()).unwrap().epoch(0).unwrap().into_iter().flatten().collect();
        assert_eq!(old.len(), current.len());
        for (a, b) in old.iter().zip(&current) {
            assert_eq!((a.index, &a.ground_truth), (b.index, &b.ground_truth));
            for (x, y) in a.transparent[0].data().iter().zip(b.transparent[0].data()) {
                assert!((x - y).abs() <= 2e-3 * x.abs().max(1.0), "{x} vs {y} (f16 cache)");
            }
        }
    }

    // A newer format than this build knows is refused, naming the field.
    set_format_version(&d, glassbake_dataset::FORMAT_VERSION + 1);
    let err = DatasetStore::open(&d).err().expect("refused").to_string();
    assert!(err.contains("format_version") && err.contains("newer"), "{err}");
}

#[test]
fn upgrade_rasterizes_the_buffers_again_and_keeps_the_ground_truth() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    generate(&scene, &spec(3), &d, &GenerateOptions::default(), &no_progress).unwrap();
    let reference = snapshot(&d);
    let raster = glassbake_raster::RasterizerOptions::default();

    // Today's format: nothing to do.
    let same = upgrade(&d, &scene, &raster, &|_, _| {}).unwrap();
    assert_eq!((same.from_version, same.rasterized), (glassbake_dataset::FORMAT_VERSION, 0));

    // A format-2 dataset: its buffer files hold other channels (here: truncated, deleted).
    set_format_version(&d, 2);
    let store = DatasetStore::open(&d).unwrap();
    let buffers = std::fs::read(store.buffers_path(1)).unwrap();
    std::fs::write(store.buffers_path(1), &buffers[..buffers.len() / 3]).unwrap();
    std::fs::remove_file(store.buffers_path(4)).unwrap();
    let err = generate(&scene, &spec(3), &d, &GenerateOptions::default(), &no_progress).expect_err("an older format is not continued").to_string();
    assert!(err.contains("format version 2") && err.contains("glassbake dataset upgrade"), "{err}");
    let other = builtin("cornellbox").unwrap();
    let err = upgrade(&d, &other, &raster, &|_, _| {}).expect_err("another scene is refused").to_string();
    assert!(err.contains("manifest.json") && err.contains("scene"), "{err}");
    assert!(!DatasetStore::open(&d).unwrap().manifest.reads_cached_buffers(), "a refused upgrade leaves the old format");

    let calls = std::sync::Mutex::new(Vec::new());
    let done = upgrade(&d, &scene, &raster, &|n, total| calls.lock().unwrap().push((n, total))).unwrap();
    assert_eq!((done.from_version, done.rasterized), (2, 8));
    assert_eq!(calls.into_inner().unwrap().last(), Some(&(8, 8)));
    // Byte for byte what generating it today makes: the same manifest, the same ground
    // truth, the same (deterministically rasterized) buffers.
    assert_eq!(snapshot(&d), reference);
    assert!(DatasetStore::open(&d).unwrap().manifest.reads_cached_buffers());
}

#[test]
fn two_writers_never_share_a_dataset_directory() {
    let scene = builtin("cornell-glass").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("set");
    let tiny = DatasetSpec { train: 1, val: 0, test: 0, ..spec(6) };
    let planned = glassbake_dataset::DatasetManifest::plan(&tiny, &scene);
    let first_writer = DatasetStore::create_or_resume(&d, &planned).unwrap();
    match generate(&scene, &tiny, &d, &GenerateOptions::default(), &no_progress) {
        Err(Error::BadInput { message, .. }) => assert!(message.contains("another glassbake process"), "{message}"),
        other => panic!("expected a refusal, got {:?}", other.map(|s| s.generated)),
    }
    drop(first_writer);
    let summary = generate(&scene, &tiny, &d, &GenerateOptions::default(), &no_progress).unwrap();
    assert_eq!(summary.generated, 1);
}
