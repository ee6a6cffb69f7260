//! Which GlassNet the bake ships. A training run can settle in a poor minimum (one bathroom
//! seed scored 1.3 dB under the naive baseline while two others led it by 3 dB), and a user
//! who bakes once cannot tell. So the bake trains naive first and checks GlassNet against it
//! on the validation frames twice: at half its steps (a run that trails naive there is
//! stopped, so a poor seed costs half a training, not a whole one) and at the end; while every
//! GlassNet so far trails and retries are left, it trains GlassNet again with the next seed,
//! then ships the best on validation. Nothing is retrained when GlassNet leads, so a bake
//! costs more only when it would otherwise have shipped a network worse than the baseline.
//!
//! Every decision is made from the training logs, so a bake killed and run again makes the
//! same ones. The choice is written to `glassnet_choice.json` before any folder moves: the
//! shipped network is always `glassnet/` and every other candidate keeps its own
//! `glassnet-seed<S>/`, and a bake killed between the moves finishes them when it resumes.

use std::path::{Path, PathBuf};

use glassbake_core::{Error, Result};
use glassbake_net::train::{logged_validation, logged_validations};
use glassbake_net::ModelFiles;
use serde::{Deserialize, Serialize};

use crate::{train_model, Progress, TrainRequest};

/// The file that records the choice, in the bake's folder.
pub const CHOICE_FILE: &str = "glassnet_choice.json";

/// One trained GlassNet and how its weights score on the validation frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    pub seed: u64,
    pub validation_psnr: f64,
    /// The step it was stopped at, trailing naive at the half-way check; `None`: trained to
    /// the end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stopped_at: Option<u64>,
}

/// The half-way check: the step and naive's validation PSNR there (dB).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HalfwayCheck {
    pub step: u64,
    pub naive_validation_psnr: f64,
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
    /// Where each GlassNet was checked before training on, while a retry was left (`None`:
    /// naive had no score at half the steps).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub halfway: Option<HalfwayCheck>,
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
        let mut text =
            format!("validation PSNR: GlassNet (seed {}) {:.2} dB{}, naive {naive:.2} dB", first.seed, first.validation_psnr, self.stopped_text(first));
        for (before, retry) in self.candidates.iter().zip(&self.candidates[1..]) {
            let why = if before.stopped_at.is_some() { "so" } else { "trailing, so" };
            text += &format!("; {why} trained again with seed {}: {:.2} dB{}", retry.seed, retry.validation_psnr, self.stopped_text(retry));
        }
        if self.candidates.len() > 1 {
            text += &format!("; shipped seed {}", self.shipped_seed);
        }
        if !self.leads() {
            text += &format!(" (GlassNet still trails naive on validation, by {:.2} dB)", naive - self.shipped().validation_psnr);
        }
        text
    }

    fn stopped_text(&self, candidate: &Candidate) -> String {
        match (candidate.stopped_at, self.halfway) {
            (Some(step), Some(check)) => format!(" at step {step}, where naive scored {:.2} dB: stopped there", check.naive_validation_psnr),
            (Some(step), None) => format!(" at step {step}: stopped there"),
            (None, _) => String::new(),
        }
    }
}

/// The step a GlassNet of `steps` steps is checked against naive at: half of them, rounded
/// down to a validated step (naive is scored every `validate_every` steps). `None` when that
/// is step 0.
pub fn halfway_step(steps: u64, validate_every: u64) -> Option<u64> {
    let step = steps / 2 / validate_every.max(1) * validate_every.max(1);
    (step > 0).then_some(step)
}

/// The next step of the choice, given naive's validation PSNR, the candidates' so far and how
/// many more may be trained: `Some(seed)` to train another GlassNet with that seed, `None` to
/// stop. A candidate trained to the end that matches naive counts as leading; one stopped
/// half way never does.
pub fn next_seed(naive_psnr: f64, candidates: &[Candidate], retries_left: u32) -> Option<u64> {
    let leads = candidates.iter().any(|c| c.stopped_at.is_none() && c.validation_psnr >= naive_psnr);
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

/// Trains the bake's GlassNet in `bake_dir` as `glassnet` asks (into `glassnet/`) and makes
/// the choice against the naive baseline trained in `naive_dir`: each GlassNet is checked at
/// [`halfway_step`] and stopped there if it trails naive while a retry is left, then at the
/// end; up to `retries` further GlassNets are trained while every one trails. Writes
/// `glassnet_choice.json`, then moves the shipped network into `glassnet/`. A bake that has
/// chosen before reads its choice (and finishes moving the folders). Returns the choice and
/// whether anything was done now; the choice is `None` when the dataset has no validation
/// frames to choose by (GlassNet is then trained unchecked).
pub fn choose_glassnet(bake_dir: &Path, glassnet: &TrainRequest, naive_dir: &Path, retries: u32, progress: &Progress) -> Result<(Option<SeedChoice>, bool)> {
    let choice_path = bake_dir.join(CHOICE_FILE);
    let first_seed = glassnet.overrides.seed.unwrap_or(glassnet.preset.training.seed);
    if choice_path.exists() {
        let choice = read_choice(&choice_path)?;
        move_into_place(bake_dir, &glassnet.out, first_seed, &choice)?;
        progress.say(&format!("{} is already trained and chosen ({CHOICE_FILE}); nothing to do", glassnet.out.display()));
        return Ok((Some(choice), false));
    }
    let naive_scores = logged_validations(naive_dir)?;
    let Some(&(_, naive_final)) = naive_scores.last() else {
        progress.say("the dataset has no validation frames: GlassNet is not checked against naive");
        return Ok((None, train_model(glassnet, progress)?));
    };
    let naive_final = naive_final.psnr;
    let config = glassnet.overrides.apply(&glassnet.preset)?;
    let halfway = halfway_step(config.steps, config.validate_every).and_then(|step| {
        let naive = naive_scores.iter().find(|(s, _)| *s == step)?;
        Some(HalfwayCheck { step, naive_validation_psnr: naive.1.psnr })
    });
    let (mut candidates, mut retries_left, mut worked, mut seed) = (Vec::new(), retries, false, first_seed);
    loop {
        let mut request = glassnet.clone();
        request.overrides.seed = Some(seed);
        if seed != first_seed {
            request.out = candidate_dir(bake_dir, seed);
        }
        let check = halfway.filter(|_| retries_left > 0);
        let mut stopped = false;
        if let Some(check) = check {
            request.pause_at = Some(check.step);
            worked |= train_model(&request, progress)?;
            request.pause_at = None;
            let psnr = validation_at(&request.out, check.step)?;
            stopped = psnr < check.naive_validation_psnr && !trained_to_the_end(&request.out, config.steps)?;
            if stopped {
                progress.say(&format!(
                    "GlassNet (seed {seed}) trails naive on validation at step {} ({psnr:.2} against {:.2} dB): stopped there, training again with seed {}",
                    check.step,
                    check.naive_validation_psnr,
                    seed + 1
                ));
            }
        }
        if !stopped {
            worked |= train_model(&request, progress)?;
        }
        let (step, psnr) = logged_validation(&request.out)?.ok_or_else(|| Error::Internal(format!("{} has no validation scores", request.out.display())))?;
        candidates.push(Candidate { seed, validation_psnr: psnr.psnr, stopped_at: stopped.then_some(step) });
        let Some(next) = next_seed(naive_final, &candidates, retries_left) else { break };
        if !stopped {
            progress.say(&format!(
                "GlassNet (seed {seed}) trails naive on validation ({:.2} against {naive_final:.2} dB): training it again with seed {next}",
                psnr.psnr
            ));
        }
        (retries_left, seed) = (retries_left - 1, next);
    }
    let choice = SeedChoice { naive_validation_psnr: naive_final, shipped_seed: best_seed(&candidates), candidates, halfway };
    let json = serde_json::to_string_pretty(&choice).map_err(|e| Error::Internal(e.to_string()))?;
    glassbake_core::image::write_bytes_atomically(&choice_path, json.as_bytes())?;
    move_into_place(bake_dir, &glassnet.out, first_seed, &choice)?;
    Ok((Some(choice), worked))
}

/// The validation PSNR logged at `step` in a model folder's training log.
fn validation_at(model_dir: &Path, step: u64) -> Result<f64> {
    let scores = logged_validations(model_dir)?;
    let found = scores.iter().find(|(s, _)| *s == step);
    found
        .map(|(_, v)| v.psnr)
        .ok_or_else(|| Error::bad_input(model_dir.join("train_log.csv").display(), "validation_psnr", format!("step {step} was not validated")))
}

/// Whether a model folder's weights are those of its last step (a GlassNet trained to the end
/// before the half-way check existed is not stopped after the fact).
fn trained_to_the_end(model_dir: &Path, steps: u64) -> Result<bool> {
    Ok(logged_validation(model_dir)?.is_some_and(|(step, _)| step >= steps))
}

fn read_choice(path: &Path) -> Result<SeedChoice> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let choice: SeedChoice = serde_json::from_str(&text).map_err(|e| Error::bad_input(path.display(), "glassnet_choice", e.to_string()))?;
    if !choice.candidates.iter().any(|c| c.seed == choice.shipped_seed) {
        return Err(Error::bad_input(path.display(), "shipped_seed", format!("seed {} is not among the candidates", choice.shipped_seed)));
    }
    Ok(choice)
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
        psnrs.iter().enumerate().map(|(i, &p)| Candidate { seed: 7 + i as u64, validation_psnr: p, stopped_at: None }).collect()
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
    fn the_halfway_check_falls_on_a_step_naive_was_validated_at() {
        assert_eq!(halfway_step(3000, 100), Some(1500));
        assert_eq!(halfway_step(40, 10), Some(20));
        assert_eq!(halfway_step(50, 10), Some(20));
        assert_eq!(halfway_step(15, 10), None);
        assert_eq!(halfway_step(10, 0), Some(5));
    }

    #[test]
    fn a_glassnet_stopped_half_way_never_counts_as_leading() {
        let mut stopped = candidates(&[25.5]);
        stopped[0].stopped_at = Some(1500);
        assert_eq!(next_seed(25.0, &stopped, 1), Some(8), "its score at half way is not its final one");
        assert_eq!(next_seed(25.0, &stopped, 0), None);
        stopped.push(Candidate { seed: 8, validation_psnr: 25.1, stopped_at: None });
        assert_eq!(next_seed(25.0, &stopped, 1), None);
    }

    #[test]
    fn the_description_says_where_a_glassnet_was_stopped() {
        let mut list = candidates(&[31.21, 34.23]);
        list[0].stopped_at = Some(1500);
        let halfway = Some(HalfwayCheck { step: 1500, naive_validation_psnr: 32.66 });
        let choice = SeedChoice { naive_validation_psnr: 33.30, candidates: list, shipped_seed: 8, halfway };
        let text = choice.describe();
        assert!(text.contains("(seed 7) 31.21 dB at step 1500, where naive scored 32.66 dB: stopped there"), "{text}");
        assert!(text.contains("; so trained again with seed 8: 34.23 dB; shipped seed 8") && !text.contains("trail"), "{text}");
    }

    #[test]
    fn the_best_on_validation_ships_and_the_earliest_wins_a_tie() {
        assert_eq!(best_seed(&candidates(&[24.0, 26.0, 25.0])), 8);
        assert_eq!(best_seed(&candidates(&[24.0, 24.0])), 7);
        assert_eq!(best_seed(&candidates(&[26.0, 24.0])), 7);
    }

    #[test]
    fn the_description_says_when_glassnet_still_trails() {
        let choice = SeedChoice { naive_validation_psnr: 25.0, candidates: candidates(&[24.0, 24.5]), shipped_seed: 8, halfway: None };
        assert!(!choice.leads());
        let text = choice.describe();
        assert!(
            text.contains("seed 8: 24.50 dB") && text.contains("shipped seed 8") && text.contains("still trails naive on validation, by 0.50 dB"),
            "{text}"
        );
        let leading = SeedChoice { naive_validation_psnr: 25.0, candidates: candidates(&[25.2]), shipped_seed: 7, halfway: None };
        assert!(leading.leads() && !leading.describe().contains("trail"), "{}", leading.describe());
    }
}
