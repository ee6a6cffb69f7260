//! The paper's ablations (Table 2) and glassbake's own, as changes to a preset's model.

use glassbake_core::{Error, Result};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ablation {
    /// Buffers enter the networks raw, without positional encoding.
    NoEncoding,
    /// L1 loss only, no SSIM term.
    L1Only,
    /// The naive baseline given what is seen through the front-most transparent object (its
    /// through buffer), which tells GlassNet's input from its architecture.
    FrontThrough,
    /// GlassNet without the through buffers (the paper's inputs), which tells what the
    /// refracted hits add.
    NoThrough,
}

impl Ablation {
    pub const ALL: [Ablation; 4] = [Ablation::NoEncoding, Ablation::L1Only, Ablation::FrontThrough, Ablation::NoThrough];
    /// The paper's ablations of GlassNet (Table 2), which `bake --ablations` trains.
    pub const PAPER: [Ablation; 2] = [Ablation::NoEncoding, Ablation::L1Only];

    pub fn name(self) -> &'static str {
        match self {
            Ablation::NoEncoding => "no-encoding",
            Ablation::L1Only => "l1-only",
            Ablation::FrontThrough => "front-through",
            Ablation::NoThrough => "no-through",
        }
    }

    pub fn parse(text: &str) -> Result<Ablation> {
        Ablation::ALL
            .into_iter()
            .find(|a| a.name() == text)
            .ok_or_else(|| Error::bad_input("--ablation", "ablation", format!("{text:?} is not no-encoding, l1-only, front-through or no-through")))
    }
}
