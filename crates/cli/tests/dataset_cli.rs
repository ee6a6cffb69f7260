//! `glassbake dataset` killed mid-run and run again completes the set exactly as an
//! uninterrupted run would; a frame rotted on disk is named and made again.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

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

fn dataset_args(out: &Path) -> Vec<String> {
    [
        "dataset",
        "cornell-glass",
        "--out",
        out.to_str().unwrap(),
        "--train",
        "10",
        "--val",
        "2",
        "--test",
        "2",
        "--res",
        "48",
        "--spp",
        "48",
        "--cache-buffers",
        "--threads",
        "1",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

#[test]
fn killed_and_rerun_equals_uninterrupted() {
    let bin = env!("CARGO_BIN_EXE_glassbake");
    let dir = tempfile::tempdir().unwrap();
    let reference = dir.path().join("reference");
    assert!(Command::new(bin).args(dataset_args(&reference)).output().unwrap().status.success());

    let resumed = dir.path().join("resumed");
    let mut child = Command::new(bin).args(dataset_args(&resumed)).spawn().unwrap();
    let start = Instant::now();
    // Kill it once some, but not all, frames are done.
    loop {
        let done =
            std::fs::read_dir(resumed.join("gt")).map(|d| d.flatten().filter(|e| !e.file_name().to_string_lossy().starts_with('.')).count()).unwrap_or(0);
        if done >= 3 || start.elapsed() > Duration::from_secs(120) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert!(!status.success(), "the run was killed before it finished, so the test exercises resume");
    assert!(snapshot(&resumed).len() < snapshot(&reference).len());

    let out = Command::new(bin).args(dataset_args(&resumed)).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("already complete"));
    assert_eq!(snapshot(&resumed), snapshot(&reference));

    // Bit rot in a training frame: `dataset info` and `train` name the frame and exit 2; the
    // dataset command makes it again.
    let frame = reference.join("gt/000004.exr");
    let mut bytes = std::fs::read(&frame).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x01;
    std::fs::write(&frame, &bytes).unwrap();
    let data = reference.to_str().unwrap();
    let (code, out, err) = glassbake(&["dataset", "info", data]);
    assert_eq!(code, 2, "{err}");
    assert!(out.contains("damaged frame 4: ") && err.contains("frame 4: ") && err.contains("SHA-256"), "{out}\n{err}");
    let model = dir.path().join("model");
    let (code, _, err) = glassbake(&["train", data, "--preset", "tiny", "--steps", "1", "--out", model.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("frame 4: ") && err.contains("000004.exr"), "{err}");
    let out = Command::new(bin).args(dataset_args(&reference)).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stdout).contains("1 frame(s) made"), "{}", String::from_utf8_lossy(&out.stdout));
    assert_eq!(snapshot(&resumed), snapshot(&reference));
    assert_eq!(glassbake(&["dataset", "info", data]).0, 0);
}

fn glassbake(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_glassbake")).args(args).output().unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

#[test]
fn a_gpu_traced_dataset_resumes_stays_on_its_device_and_trains() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("gpu");
    let data_arg = data.to_str().unwrap();
    let args = [
        "dataset",
        "cornell-glass",
        "--out",
        data_arg,
        "--train",
        "3",
        "--val",
        "1",
        "--test",
        "1",
        "--res",
        "16",
        "--spp",
        "8",
        "--cache-buffers",
        "--device",
        "wgpu",
    ];
    let (code, _, err) = glassbake(&args);
    assert_eq!(code, 0, "{err}");
    let manifest: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(data.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["spec"]["device"], "wgpu");
    let (_, info, _) = glassbake(&["dataset", "info", data_arg]);
    assert!(info.contains("traced on wgpu"), "{info}");
    assert!(info.contains(&format!("tracer revision {}", manifest["tracer_revision"])), "{info}");
    assert!(manifest["tracer_revision"].as_u64().is_some_and(|r| r >= 1), "{manifest}");
    assert!(manifest.get("ray_caster").is_none() && !info.contains("rays cast by"), "a GPU dataset records no CPU ray caster: {info}");

    // A lost frame is made again, identical on the same device; the rest are kept.
    let complete = snapshot(&data);
    std::fs::remove_file(data.join("gt/000002.exr")).unwrap();
    let (code, out, err) = glassbake(&args);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("1 frame(s) made, 4 already complete"), "{out}");
    assert_eq!(snapshot(&data), complete, "the remade frame differs from the first run's");

    // Continuing it on the CPU would mix two tracers' random numbers: refused, nothing written.
    let mut on_cpu = args.to_vec();
    on_cpu.truncate(on_cpu.len() - 2);
    let (code, _, err) = glassbake(&on_cpu);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--device wgpu, not cpu"), "{err}");
    assert_eq!(snapshot(&data), complete);

    let model = dir.path().join("model");
    let (code, out, err) = glassbake(&["train", data_arg, "--model", "glassnet", "--preset", "tiny", "--steps", "3", "--out", model.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("trained 3 steps"), "{out}");
}
