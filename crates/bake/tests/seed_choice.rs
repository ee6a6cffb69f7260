//! The bake ships the GlassNet that does best on validation, trains the next seeds while
//! every one trails naive, records its choice, and finishes moving the folders when a kill
//! interrupted it.

use std::path::Path;

use glassbake_bake::seed_choice::{candidate_dir, CHOICE_FILE};
use glassbake_bake::{bake, BakeRequest, Preset, Progress, SeedChoice};
use glassbake_net::train::logged_validation;
use glassbake_net::ModelFiles;

fn seed_of(model_dir: &Path) -> u64 {
    ModelFiles::open(model_dir).unwrap().config.train.seed
}

fn psnr_of(model_dir: &Path) -> f64 {
    logged_validation(model_dir).unwrap().expect("validated").1.psnr
}

/// Rewrites the validation PSNR of the last validated step in `model_dir`'s training log.
fn set_logged_psnr(model_dir: &Path, psnr: f64) {
    let log = model_dir.join("train_log.csv");
    let text = std::fs::read_to_string(&log).unwrap();
    let mut rows: Vec<String> = text.lines().map(String::from).collect();
    let last = rows.iter().rposition(|r| !r.ends_with(',')).unwrap();
    let mut fields: Vec<&str> = rows[last].split(',').collect();
    let value = format!("{psnr:.3}");
    *fields.last_mut().unwrap() = &value;
    rows[last] = fields.join(",");
    std::fs::write(&log, rows.join("\n") + "\n").unwrap();
    assert_eq!(psnr_of(model_dir), psnr);
}

fn read_choice(bake_dir: &Path) -> SeedChoice {
    serde_json::from_str(&std::fs::read_to_string(bake_dir.join(CHOICE_FILE)).unwrap()).unwrap()
}

#[test]
fn a_glassnet_trailing_naive_is_trained_again_and_the_best_on_validation_ships() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bake");
    let mut request = BakeRequest::new("cornell-glass", Preset::tiny(), &out);
    request.seed_retries = 0;
    let first = bake(&request, &Progress::silent()).unwrap();
    let choice = first.glassnet_choice.expect("the tiny preset validates");
    assert_eq!(choice, read_choice(&out));
    assert_eq!(choice.candidates.len(), 1, "no retries allowed");
    assert_eq!((choice.shipped_seed, seed_of(&out.join("glassnet"))), (0, 0));
    assert_eq!(choice.candidates[0].validation_psnr, psnr_of(&out.join("glassnet")));
    assert_eq!(choice.naive_validation_psnr, psnr_of(&out.join("naive")));

    // A naive baseline no GlassNet can reach, and the first GlassNet made the worst: the bake,
    // choosing again, trains seeds 1 and 2 and ships the better of them.
    std::fs::remove_file(out.join(CHOICE_FILE)).unwrap();
    set_logged_psnr(&out.join("naive"), 99.0);
    set_logged_psnr(&out.join("glassnet"), 1.0);
    request.seed_retries = 2;
    let second = bake(&request, &Progress::silent()).unwrap();
    let choice = second.glassnet_choice.unwrap();
    let seeds: Vec<u64> = choice.candidates.iter().map(|c| c.seed).collect();
    assert_eq!(seeds, [0, 1, 2]);
    let shipped = choice.shipped_seed;
    let other = 3 - shipped;
    assert!(shipped == 1 || shipped == 2, "{choice:?}");
    assert_eq!(seed_of(&out.join("glassnet")), shipped);
    assert_eq!(seed_of(&candidate_dir(&out, 0)), 0);
    assert_eq!(seed_of(&candidate_dir(&out, other)), other);
    assert!(!candidate_dir(&out, shipped).exists());
    assert_eq!(choice.shipped().validation_psnr, psnr_of(&out.join("glassnet")));
    assert!(choice.shipped().validation_psnr >= psnr_of(&candidate_dir(&out, other)));
    assert!(!choice.leads());
    // The shipped network is the one evaluated, and the report says that it still trails.
    let weights_written = std::fs::metadata(out.join("glassnet/glassnet.safetensors")).unwrap().modified().unwrap();
    let metrics_written = std::fs::metadata(out.join("eval/metrics.json")).unwrap().modified().unwrap();
    assert!(metrics_written >= weights_written, "evaluated before the shipped GlassNet was moved in");
    let report = std::fs::read_to_string(out.join("report/report.md")).unwrap();
    assert!(report.contains(&format!("shipped seed {shipped}")) && report.contains("still trails naive on validation"), "{report}");

    // Killed after the choice was written, before the folders moved: the next run moves them.
    std::fs::rename(out.join("glassnet"), candidate_dir(&out, shipped)).unwrap();
    std::fs::rename(candidate_dir(&out, 0), out.join("glassnet")).unwrap();
    let third = bake(&request, &Progress::silent()).unwrap();
    assert_eq!(third.glassnet_choice.unwrap(), choice, "chosen once, not again");
    assert_eq!((seed_of(&out.join("glassnet")), seed_of(&candidate_dir(&out, 0))), (shipped, 0));
    // Killed between the two moves.
    std::fs::rename(out.join("glassnet"), candidate_dir(&out, shipped)).unwrap();
    bake(&request, &Progress::silent()).unwrap();
    assert_eq!(seed_of(&out.join("glassnet")), shipped);
    assert!(!candidate_dir(&out, shipped).exists() && candidate_dir(&out, 0).exists());
}
