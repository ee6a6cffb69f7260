//! Which GlassNet the bake ships. A training run can settle in a poor minimum (one bathroom
//! seed scored 1.3 dB under the naive baseline while two others led it by 3 dB), and a user
//! who bakes once cannot tell. So once GlassNet and naive are trained the bake compares their
//! validation PSNR (the same frames, the score of the final weights); while every GlassNet so
//! far trails naive and retries are left, it trains GlassNet again with the next seed, then
//! ships the best on validation. Nothing is retrained when GlassNet leads, so a bake costs
//! more only when it would otherwise have shipped a network worse than the baseline.
//!
//! The choice is written to `glassnet_choice.json` before any folder moves: the shipped
//! network is always `glassnet/` and every other candidate keeps its own `glassnet-seed<S>/`,
//! and a bake killed between the moves finishes them when it resumes.

use std::path::{Path, PathBuf};

use glassbake_core::{Error, Result};
use glassbake_net::train::logged_validation;
use glassbake_net::ModelFiles;
use serde::{Deserialize, Serialize};

use crate::{train_model, Progress, TrainRequest};

/// The file that records the choice, in the bake's folder.
pub const CHOICE_FILE: &str = "glassnet_choice.json";

/// One trained GlassNet and how it scored on the validation frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    pub seed: u64,
    pub validation_psnr: f64,
}

/// What the bake decided, as `glassnet_choice.json` holds it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SeedChoice {
    /// The naive baseline's validation PSNR (dB).
    pub naive_validation_psnr: f64,
    /// Every GlassNet trained, in the order trained (the preset's seed first).
    pub candidates: Vec<Candidate>,
    /// The seed of the network in `glassnet/`.
    pub shipped_seed: u64,
}

impl SeedChoice {
    pub fn shipped(&self) -> &Candidate {
        self.candidates.iter().find(|c| c.seed == self.shipped_seed).expect("the shipped seed is a candidate")
    }

    /// Whether the shipped GlassNet scores at least naive's PSNR on validation.
    pub fn leads(&self) -> bool {
        self.shipped().validation_psnr >= self.naive_validation_psnr
    }

    /// The choice in words, for the bake's output and report.
    pub fn describe(&self) -> String {
        let naive = self.naive_validation_psnr;
        let first = &self.candidates[0];
        let mut text = format!("validation PSNR: GlassNet (seed {}) {:.2} dB, naive {naive:.2} dB", first.seed, first.validation_psnr);
        for retry in &self.candidates[1..] {
            text += &format!("; trailing, so trained again with seed {}: {:.2} dB", retry.seed, retry.validation_psnr);
        }
        if self.candidates.len() > 1 {
            text += &format!("; shipped seed {}", self.shipped_seed);
        }
        if !self.leads() {
            text += &format!(" (GlassNet still trails naive on validation, by {:.2} dB)", naive - self.shipped().validation_psnr);
        }
        text
    }
}

/// The next step of the choice, given naive's validation PSNR, the candidates' so far and how
/// many more may be trained: `Some(seed)` to train another GlassNet with that seed, `None` to
/// stop. A candidate that matches naive counts as leading.
pub fn next_seed(naive_psnr: f64, candidates: &[Candidate], retries_left: u32) -> Option<u64> {
    let leads = candidates.iter().any(|c| c.validation_psnr >= naive_psnr);
    let last = candidates.last().expect("the first GlassNet is trained before the choice");
    (!leads && retries_left > 0).then_some(last.seed + 1)
}

/// The candidate to ship: the best on validation, the earliest trained among equals.
pub fn best_seed(candidates: &[Candidate]) -> u64 {
    let mut best = &candidates[0];
    for c in &candidates[1..] {
        if c.validation_psnr > best.validation_psnr {
            best = c;
        }
    }
    best.seed
}

/// The folder of a GlassNet that is not shipped.
pub fn candidate_dir(bake_dir: &Path, seed: u64) -> PathBuf {
    bake_dir.join(format!("glassnet-seed{seed}"))
}

/// Makes the choice for the bake in `bake_dir`, whose GlassNet was trained by `glassnet`
/// (into `glassnet/`) and whose naive baseline lies in `naive_dir`: trains up to `retries`
/// further GlassNets while every one trails, writes `glassnet_choice.json`, then moves the
/// shipped network into `glassnet/`. A bake that has chosen before reads its choice (and
/// finishes moving the folders). Returns the choice and whether anything was done now;
/// `None` when the dataset has no validation frames to choose by.
pub fn choose_glassnet(bake_dir: &Path, glassnet: &TrainRequest, naive_dir: &Path, retries: u32, progress: &Progress) -> Result<(Option<SeedChoice>, bool)> {
    let choice_path = bake_dir.join(CHOICE_FILE);
    if choice_path.exists() {
        let choice = read_choice(&choice_path)?;
        move_into_place(bake_dir, &glassnet.out, glassnet.overrides.seed.unwrap_or(glassnet.preset.training.seed), &choice)?;
        return Ok((Some(choice), false));
    }
    let Some(naive_psnr) = final_psnr(naive_dir)? else {
        progress.say("the dataset has no validation frames: GlassNet is not checked against naive");
        return Ok((None, false));
    };
    let first_seed = glassnet.overrides.seed.unwrap_or(glassnet.preset.training.seed);
    let Some(first_psnr) = final_psnr(&glassnet.out)? else {
        return Err(Error::Internal(format!("{} was trained without validation scores while naive has them", glassnet.out.display())));
    };
    let mut candidates = vec![Candidate { seed: first_seed, validation_psnr: first_psnr }];
    let mut retries_left = retries;
    while let Some(seed) = next_seed(naive_psnr, &candidates, retries_left) {
        progress.say(&format!(
            "GlassNet (seed {}) trails naive on validation ({:.2} against {naive_psnr:.2} dB): training it again with seed {seed}",
            candidates.last().map_or(first_seed, |c| c.seed),
            candidates.last().map_or(first_psnr, |c| c.validation_psnr)
        ));
        let mut retry = glassnet.clone();
        retry.out = candidate_dir(bake_dir, seed);
        retry.overrides.seed = Some(seed);
        train_model(&retry, progress)?;
        let psnr = final_psnr(&retry.out)?.ok_or_else(|| Error::Internal(format!("{} has no validation scores", retry.out.display())))?;
        candidates.push(Candidate { seed, validation_psnr: psnr });
        retries_left -= 1;
    }
    let choice = SeedChoice { naive_validation_psnr: naive_psnr, shipped_seed: best_seed(&candidates), candidates };
    let json = serde_json::to_string_pretty(&choice).map_err(|e| Error::Internal(e.to_string()))?;
    glassbake_core::image::write_bytes_atomically(&choice_path, json.as_bytes())?;
    move_into_place(bake_dir, &glassnet.out, first_seed, &choice)?;
    Ok((Some(choice), true))
}

fn read_choice(path: &Path) -> Result<SeedChoice> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let choice: SeedChoice = serde_json::from_str(&text).map_err(|e| Error::bad_input(path.display(), "glassnet_choice", e.to_string()))?;
    if !choice.candidates.iter().any(|c| c.seed == choice.shipped_seed) {
        return Err(Error::bad_input(path.display(), "shipped_seed", format!("seed {} is not among the candidates", choice.shipped_seed)));
    }
    Ok(choice)
}

/// The validation PSNR of a finished model's weights.
fn final_psnr(model_dir: &Path) -> Result<Option<f64>> {
    Ok(logged_validation(model_dir)?.map(|(_, scores)| scores.psnr))
}

/// The seed a model folder was trained with.
fn trained_seed(model_dir: &Path) -> Result<u64> {
    Ok(ModelFiles::open(model_dir)?.config.train.seed)
}

/// Puts the shipped candidate in `shipped_dir` (`glassnet/`) and the first one, when not
/// shipped, in its own `glassnet-seed<S>/`. Each move is one rename, and each is skipped when
/// already made, so a run killed between them finishes them here.
fn move_into_place(bake_dir: &Path, shipped_dir: &Path, first_seed: u64, choice: &SeedChoice) -> Result<()> {
    if choice.shipped_seed == first_seed {
        return Ok(());
    }
    let rename = |from: &Path, to: &Path| std::fs::rename(from, to).map_err(|e| Error::io(from, e));
    let first_dir = candidate_dir(bake_dir, first_seed);
    if shipped_dir.exists() && trained_seed(shipped_dir)? == first_seed {
        if first_dir.exists() {
            return Err(Error::bad_input(first_dir.display(), "glassnet_choice", "both this folder and glassnet/ hold the first GlassNet; remove one"));
        }
        rename(shipped_dir, &first_dir)?;
    }
    if !shipped_dir.exists() {
        rename(&candidate_dir(bake_dir, choice.shipped_seed), shipped_dir)?;
    }
    let seed = trained_seed(shipped_dir)?;
    if seed != choice.shipped_seed {
        return Err(Error::bad_input(shipped_dir.display(), "seed", format!("holds seed {seed}, but {CHOICE_FILE} ships seed {}", choice.shipped_seed)));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidates(psnrs: &[f64]) -> Vec<Candidate> {
        psnrs.iter().enumerate().map(|(i, &p)| Candidate { seed: 7 + i as u64, validation_psnr: p }).collect()
    }

    #[test]
    fn a_glassnet_that_leads_or_ties_is_not_trained_again() {
        assert_eq!(next_seed(25.0, &candidates(&[25.5]), 3), None);
        assert_eq!(next_seed(25.0, &candidates(&[25.0]), 3), None);
        assert_eq!(next_seed(25.0, &candidates(&[24.0, 25.1]), 3), None);
    }

    #[test]
    fn a_trailing_glassnet_is_trained_again_with_the_next_seed_while_retries_last() {
        assert_eq!(next_seed(25.0, &candidates(&[24.9]), 1), Some(8));
        assert_eq!(next_seed(25.0, &candidates(&[24.9, 24.0]), 1), Some(9));
        assert_eq!(next_seed(25.0, &candidates(&[24.9]), 0), None);
    }

    #[test]
    fn the_best_on_validation_ships_and_the_earliest_wins_a_tie() {
        assert_eq!(best_seed(&candidates(&[24.0, 26.0, 25.0])), 8);
        assert_eq!(best_seed(&candidates(&[24.0, 24.0])), 7);
        assert_eq!(best_seed(&candidates(&[26.0, 24.0])), 7);
    }

    #[test]
    fn the_description_says_when_glassnet_still_trails() {
        let choice = SeedChoice { naive_validation_psnr: 25.0, candidates: candidates(&[24.0, 24.5]), shipped_seed: 8 };
        assert!(!choice.leads());
        let text = choice.describe();
        assert!(
            text.contains("seed 8: 24.50 dB") && text.contains("shipped seed 8") && text.contains("still trails naive on validation, by 0.50 dB"),
            "{text}"
        );
        let leading = SeedChoice { naive_validation_psnr: 25.0, candidates: candidates(&[25.2]), shipped_seed: 7 };
        assert!(leading.leads() && !leading.describe().contains("trail"), "{}", leading.describe());
    }
}
