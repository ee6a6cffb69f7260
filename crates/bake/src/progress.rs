//! Where a long job reports: bars for what it counts, lines for a person to read. The
//! command-line tool prints both; a program that bakes from its own code can stay silent.

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget};

pub struct Progress {
    bars: MultiProgress,
    /// The bar of the work under way (frames traced, steps trained, frames scored).
    bar: ProgressBar,
    printing: bool,
}

impl Progress {
    /// Bars on the terminal (stderr), lines on stdout above them.
    pub fn printing() -> Progress {
        let bars = MultiProgress::new();
        let bar = bars.add(ProgressBar::new(0));
        Progress { bars, bar, printing: true }
    }

    /// Nothing drawn, nothing printed.
    pub fn silent() -> Progress {
        let bars = MultiProgress::with_draw_target(ProgressDrawTarget::hidden());
        let bar = bars.add(ProgressBar::new(0));
        Progress { bars, bar, printing: false }
    }

    pub fn bar(&self) -> &ProgressBar {
        &self.bar
    }

    /// A bar drawn above the work's bar (the bake's stages).
    pub fn add_bar_above(&self, length: u64) -> ProgressBar {
        self.bars.insert_before(&self.bar, ProgressBar::new(length))
    }

    /// A line for the person running the job.
    pub fn say(&self, line: &str) {
        if self.printing {
            self.bars.suspend(|| println!("{line}"));
        }
    }

    /// Clears the bars from the terminal.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }

    /// `work` with bars on the terminal, cleared when it ends.
    pub fn printing_while<T>(work: impl FnOnce(&Progress) -> T) -> T {
        let progress = Progress::printing();
        let result = work(&progress);
        progress.finish();
        result
    }
}
