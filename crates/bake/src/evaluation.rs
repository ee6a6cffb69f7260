//! Scoring trained models on a dataset split with progress: `glassbake eval` and a bake's
//! evaluation stage.

use std::time::Duration;

use glassbake_core::Result;
use glassbake_eval::score::{score_models, ScoreOptions};
use glassbake_eval::EvaluationSummary;
use indicatif::ProgressStyle;

use crate::Progress;

/// Scores the models of `options`, counting frames on the progress bar; `facts` are extra
/// lines for the report.
pub fn evaluate(options: &ScoreOptions, facts: &[String], progress: &Progress) -> Result<EvaluationSummary> {
    let bar = progress.bar();
    bar.set_style(
        ProgressStyle::with_template("{spinner} frames {pos}/{len} [{elapsed_precise}] {wide_bar} ETA {eta}").expect("static template").progress_chars("=> "),
    );
    bar.set_position(0);
    bar.enable_steady_tick(Duration::from_millis(250));
    let scored = score_models(options, facts, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    let summary = scored.summary;
    progress.say(&format!("evaluated {} frame(s) of {}: {}", summary.frames.len(), options.dataset.display(), options.out.join("metrics.json").display()));
    if let Some(o) = &summary.order_test {
        progress.say(&format!(
            "  order test ({}, {} frames): max |difference| reversed {}, shuffled {}{}",
            o.model,
            o.frames,
            o.reversed_max_abs_diff,
            o.shuffled_max_abs_diff,
            if o.passed() { " (bit-identical)" } else { " — NOT identical" }
        ));
    }
    progress.say(&format!("  LPIPS {}", summary.lpips));
    progress.say(&format!("  report {}", scored.report.display()));
    Ok(summary)
}
