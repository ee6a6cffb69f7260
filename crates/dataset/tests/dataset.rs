//! Dataset generation end to end at tiny sizes (real path tracer, real rasterizer on
//! lavapipe): resume, corrupt-file detection, shard/merge byte equality, refusals, splits,
//! and the loader.

use std::collections::BTreeMap;
use std::path::Path;

use glassbake_core::layout::transparent;
use glassbake_core::Error;
use glassbake_dataset::{generate, merge, DatasetSpec, DatasetStore, GenerateOptions, Loader, LoaderOptions, ShardSpec, Split, TraceDevice};
use glassbake_scene::builtin::builtin;

fn spec(seed: u64) -> DatasetSpec {
    DatasetSpec { scene: "cornell-glass".into(), resolution: 8, spp: 2, seed, train: 4, val: 2, test: 2, cache_buffers: true, device: TraceDevice::Cpu }
}

fn no_progress(_: u64, _: u64) {}

/// Every file under `dir`, relative path -> bytes.
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    for sub in ["", "gt", "buffers", "preview"] {
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
    assert_eq!(reference.keys().filter(|k| k.starts_with("gt/")).count(), 8);

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
        (scene.clone(), DatasetSpec { spp: 4, ..tiny.clone() }, "--spp"),
        (scene.clone(), DatasetSpec { train: 2, ..tiny.clone() }, "--train"),
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
    let s = DatasetSpec { scene: "cornellbox".into(), resolution: 8, spp: 1, seed: 0, train: 7, val: 3, test: 5, cache_buffers: false, device: TraceDevice::Cpu };
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
