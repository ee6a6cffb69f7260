//! The bake ships the GlassNet that does best on validation, stops one that trails naive half
//! way, trains the next seeds while every one trails, records its choice, and makes the same
//! choice and finishes moving the folders when a kill interrupted it.

use std::path::Path;

use glassbake_bake::seed_choice::{candidate_dir, CHOICE_FILE};
use glassbake_bake::{bake, BakeRequest, Preset, Progress, SeedChoice};
use glassbake_net::model_dir::weights_step;
use glassbake_net::train::{logged_validation, logged_validations};
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

/// Rewrites the validation PSNR of every validated step in `model_dir`'s training log.
fn set_every_logged_psnr(model_dir: &Path, psnr: f64) {
    let log = model_dir.join("train_log.csv");
    let text = std::fs::read_to_string(&log).unwrap();
    let value = format!("{psnr:.3}");
    let rows: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, row)| {
            let mut fields: Vec<&str> = row.split(',').collect();
            if i > 0 && !row.ends_with(',') {
                *fields.last_mut().unwrap() = &value;
            }
            fields.join(",")
        })
        .collect();
    std::fs::write(&log, rows.join("\n") + "\n").unwrap();
    assert!(logged_validations(model_dir).unwrap().iter().all(|(_, s)| s.psnr == psnr));
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

#[test]
fn a_glassnet_trailing_naive_half_way_is_stopped_there_and_a_resumed_bake_decides_alike() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bake");
    let mut request = BakeRequest::new("cornell-glass", Preset::tiny(), &out);
    request.seed_retries = 0;
    bake(&request, &Progress::silent()).unwrap();
    let steps = Preset::tiny().training.steps;
    assert_eq!(weights_step(&out.join("glassnet/glassnet.safetensors")), Some(steps), "no retry left: trained through");

    // A naive baseline that leads at every step: with a retry left, GlassNet is trained anew,
    // stopped at half its steps, and the retry (no retry left after it) trained to the end.
    std::fs::remove_file(out.join(CHOICE_FILE)).unwrap();
    std::fs::remove_dir_all(out.join("glassnet")).unwrap();
    set_every_logged_psnr(&out.join("naive"), 99.0);
    request.seed_retries = 1;
    let choice = bake(&request, &Progress::silent()).unwrap().glassnet_choice.unwrap();
    let half = steps / 2;
    let halfway = choice.halfway.expect("naive was validated half way");
    assert_eq!((halfway.step, halfway.naive_validation_psnr), (half, 99.0));
    let stopped: Vec<(u64, Option<u64>)> = choice.candidates.iter().map(|c| (c.seed, c.stopped_at)).collect();
    assert_eq!(stopped, [(0, Some(half)), (1, None)]);
    let folder = |seed: u64| if choice.shipped_seed == seed { out.join("glassnet") } else { candidate_dir(&out, seed) };
    assert_eq!(weights_step(&folder(0).join("glassnet.safetensors")), Some(half));
    assert_eq!(logged_validation(&folder(0)).unwrap().unwrap().0, half, "nothing trained past the check");
    assert_eq!(weights_step(&folder(1).join("glassnet.safetensors")), Some(steps));
    for candidate in &choice.candidates {
        assert_eq!(candidate.validation_psnr, psnr_of(&folder(candidate.seed)));
    }
    let report = std::fs::read_to_string(out.join("report/report.md")).unwrap();
    assert!(report.contains(&format!("at step {half}, where naive scored 99.00 dB: stopped there")), "{report}");

    // Killed after the retry trained, before the choice was written: the next run trains
    // nothing and makes the same choice.
    std::fs::remove_file(out.join(CHOICE_FILE)).unwrap();
    if choice.shipped_seed != 0 {
        std::fs::rename(out.join("glassnet"), candidate_dir(&out, choice.shipped_seed)).unwrap();
        std::fs::rename(candidate_dir(&out, 0), out.join("glassnet")).unwrap();
    }
    let logs_before: Vec<String> =
        [out.join("glassnet"), candidate_dir(&out, 1)].iter().map(|d| std::fs::read_to_string(d.join("train_log.csv")).unwrap()).collect();
    let again = bake(&request, &Progress::silent()).unwrap().glassnet_choice.unwrap();
    assert_eq!(again, choice);
    assert_eq!(weights_step(&folder(0).join("glassnet.safetensors")), Some(half), "the stopped GlassNet stays stopped");
    let logs_after: Vec<String> = [folder(0), folder(1)].iter().map(|d| std::fs::read_to_string(d.join("train_log.csv")).unwrap()).collect();
    assert_eq!(logs_after, logs_before, "nothing trained again");
}
