//! `glassbake dataset` killed mid-run and run again completes the set exactly as an
//! uninterrupted run would.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

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

fn dataset_args(out: &Path) -> Vec<String> {
    ["dataset", "cornell-glass", "--out", out.to_str().unwrap(), "--train", "10", "--val", "2", "--test", "2", "--res", "48", "--spp", "48", "--cache-buffers", "--threads", "1"]
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
        let done = std::fs::read_dir(resumed.join("gt")).map(|d| d.flatten().filter(|e| !e.file_name().to_string_lossy().starts_with('.')).count()).unwrap_or(0);
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
}
