//! A program that bakes through the library gets what `glassbake bake` makes with the same
//! arguments: the same dataset byte for byte, the same weights tensor for tensor, the same
//! scores on every frame.

use std::path::Path;
use std::process::Command;

mod common;

use glassbake_bake::{bake, BakeRequest, Preset, Progress};
use glassbake_eval::EvaluationSummary;

/// A safetensors file as (its header, its tensor bytes): the header's metadata is a map whose
/// order is not fixed, so it is compared as JSON.
fn tensors(file: &Path) -> (serde_json::Value, Vec<u8>) {
    let bytes = std::fs::read(file).unwrap();
    let header_len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header = serde_json::from_slice(&bytes[8..8 + header_len]).unwrap();
    (header, bytes[8 + header_len..].to_vec())
}

#[test]
fn a_library_bake_makes_what_the_command_makes() {
    let dir = tempfile::tempdir().unwrap();
    let (cli, library) = (dir.path().join("cli"), dir.path().join("library"));
    let out =
        Command::new(env!("CARGO_BIN_EXE_glassbake")).args(["bake", "cornell-glass", "--preset", "tiny", "--out", cli.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let result = bake(&BakeRequest::new("cornell-glass", Preset::tiny(), &library), &Progress::silent()).unwrap();

    let dataset = common::snapshot(&cli.join("dataset"));
    assert!(dataset.keys().any(|p| p.starts_with("gt-train-spp")), "the test split has its noise-floor copy");
    assert_eq!(dataset, common::snapshot(&library.join("dataset")), "the datasets differ");
    for model in ["glassnet", "naive"] {
        let weights = |bake: &Path| tensors(&bake.join(model).join("glassnet.safetensors"));
        assert_eq!(weights(&cli), weights(&library), "{model}'s weights differ");
    }
    // Both read back from metrics.json (the in-memory summary holds the exact values, which
    // serde_json's float parsing may read back a unit in the last place off).
    let [from_cli, from_library] = [&cli, &library].map(|bake| EvaluationSummary::read(&bake.join("eval").join("metrics.json")).unwrap());
    let scores = |s: &EvaluationSummary| {
        s.frames.iter().map(|f| (f.index, f.metrics.iter().map(|m| (m.psnr, m.t_psnr, m.dssim)).collect::<Vec<_>>())).collect::<Vec<_>>()
    };
    let rows = |s: &EvaluationSummary| s.models.iter().map(|m| m.model.clone()).collect::<Vec<_>>();
    assert_eq!(rows(&from_cli), rows(&result.summary));
    assert_eq!(scores(&from_cli), scores(&from_library));
    assert!(result.report.exists() && result.noise_floor.is_some());
}
