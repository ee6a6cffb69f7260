//! Which estimator traces an image: one value, named the same way by the library, the CLI
//! (`--estimator`) and datasets (`manifest.json`), whose `Default` is the ground truth's.
//!
//! An estimator has three independent parts, spelled `transport[+merging][+adaptive][+stratified]`:
//! - the transport: `plain` (the path tracer alone) or `caustic` (the path tracer without the
//!   paths that reach opaque surfaces through bending glass, plus a light tracer for them),
//!   optionally with photon merging of what the camera sees through bending glass (`+merging`,
//!   caustic only: biased);
//! - pixel sampling: uniform, or `+adaptive` (a pilot pass spreads the samples where the noise
//!   is, `adaptive.rs`);
//! - sample values: independent, or `+stratified` (scrambled Sobol points, `qmc.rs`).
//!
//! Every combination the type can hold is valid on the CPU tracer. The GPU tracer runs
//! [`Estimator::PLAIN`] only.

use std::fmt;
use std::str::FromStr;

/// How the light reaches the camera's paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Transport {
    /// Unidirectional path tracing with next-event estimation and MIS; lights sampled by area
    /// and picked by power.
    Plain,
    /// The path tracer without the paths a light tracer carries (light that reached an opaque
    /// surface through bending glass, `light_tracing.rs`), plus that light tracer; rectangle
    /// lights sampled by solid angle near them, emitters picked by their contribution, and
    /// emitters reflected in smooth glass the camera sees taken at every sample.
    Caustic {
        /// Estimate what the camera sees through bending glass from photons' density
        /// (`photon_merging.rs`) instead of path tracing it: biased (a blur of about a pixel,
        /// shrinking as the budget grows), much less noisy.
        photon_merging: bool,
    },
}

/// The estimator of an image (see the module documentation for its parts and their names).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Estimator {
    pub transport: Transport,
    /// Spread each pixel's budget by the noise a pilot pass measured (`adaptive.rs`); budgets
    /// below [`crate::adaptive::MIN_ADAPTIVE_SPP`] are sampled uniformly all the same.
    pub adaptive: bool,
    /// Draw each sample's sub-pixel position and its first vertices' light and BSDF samples
    /// from scrambled Sobol points (`qmc.rs`) instead of independent random numbers.
    pub stratified: bool,
}

impl Default for Estimator {
    /// The ground truth's estimator: `caustic+adaptive+stratified`, unbiased, the fastest to
    /// converge on the built-in scenes (docs/trace.md).
    fn default() -> Self {
        Estimator { transport: Transport::Caustic { photon_merging: false }, adaptive: true, stratified: true }
    }
}

impl Estimator {
    /// The path tracer alone, uniform pixels, independent values: the GPU tracer's only
    /// estimator, and the baseline every other is measured against.
    pub const PLAIN: Estimator = Estimator { transport: Transport::Plain, adaptive: false, stratified: false };

    /// Whether the caustic light tracer runs.
    pub fn is_caustic(&self) -> bool {
        matches!(self.transport, Transport::Caustic { .. })
    }

    /// Whether photon merging runs (biased).
    pub fn photon_merging(&self) -> bool {
        matches!(self.transport, Transport::Caustic { photon_merging: true })
    }

    /// The canonical name, e.g. `caustic+adaptive+stratified`.
    pub fn name(&self) -> String {
        let mut name = String::from(if self.is_caustic() { "caustic" } else { "plain" });
        for (on, part) in [(self.photon_merging(), "+merging"), (self.adaptive, "+adaptive"), (self.stratified, "+stratified")] {
            if on {
                name.push_str(part);
            }
        }
        name
    }

    /// Parse a name: a transport, then its options in any order; or one of the names datasets
    /// recorded before options were spelled with `+` (`caustic-adaptive-stratified`,
    /// `caustic-merged`, which was adaptive and stratified too).
    pub fn parse(name: &str) -> Result<Estimator, String> {
        match name {
            "caustic-adaptive-stratified" => return Ok(Estimator::default()),
            "caustic-merged" => return Ok(Estimator { transport: Transport::Caustic { photon_merging: true }, ..Estimator::default() }),
            _ => {}
        }
        let expected = "expected plain or caustic, optionally followed by +merging (caustic only), +adaptive and +stratified, e.g. caustic+adaptive+stratified";
        let mut parts = name.split('+');
        let transport = parts.next().unwrap_or_default();
        let caustic = match transport {
            "plain" => false,
            "caustic" => true,
            other => return Err(format!("unknown transport {other:?}: {expected}")),
        };
        let (mut merging, mut adaptive, mut stratified) = (false, false, false);
        for part in parts {
            let flag = match part {
                "merging" => &mut merging,
                "adaptive" => &mut adaptive,
                "stratified" => &mut stratified,
                other => return Err(format!("unknown option {other:?}: {expected}")),
            };
            if *flag {
                return Err(format!("option {part:?} given twice"));
            }
            *flag = true;
        }
        let transport = match (caustic, merging) {
            (true, photon_merging) => Transport::Caustic { photon_merging },
            (false, false) => Transport::Plain,
            (false, true) => return Err("+merging merges the caustic light tracer's photons: it needs the caustic transport".to_string()),
        };
        Ok(Estimator { transport, adaptive, stratified })
    }
}

impl fmt::Display for Estimator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

impl FromStr for Estimator {
    type Err = String;

    fn from_str(name: &str) -> Result<Self, String> {
        Estimator::parse(name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn every_estimator() -> Vec<Estimator> {
        let mut all = Vec::new();
        for transport in [Transport::Plain, Transport::Caustic { photon_merging: false }, Transport::Caustic { photon_merging: true }] {
            for adaptive in [false, true] {
                for stratified in [false, true] {
                    all.push(Estimator { transport, adaptive, stratified });
                }
            }
        }
        all
    }

    #[test]
    fn every_estimator_round_trips_through_its_name() {
        let all = every_estimator();
        let names: std::collections::HashSet<String> = all.iter().map(Estimator::name).collect();
        assert_eq!(names.len(), all.len(), "two estimators share a name");
        for estimator in all {
            assert_eq!(Estimator::parse(&estimator.name()), Ok(estimator));
        }
    }

    #[test]
    fn options_parse_in_any_order_and_older_dataset_names_keep_their_meaning() {
        assert_eq!(Estimator::parse("caustic+stratified+adaptive"), Ok(Estimator::default()));
        assert_eq!(Estimator::parse("caustic-adaptive-stratified"), Ok(Estimator::default()));
        let merged = Estimator::parse("caustic-merged").unwrap();
        assert_eq!(merged.name(), "caustic+merging+adaptive+stratified");
        assert_eq!(Estimator::parse("plain"), Ok(Estimator::PLAIN));
        assert_eq!(Estimator::parse("caustic").unwrap(), Estimator { adaptive: false, stratified: false, ..Estimator::default() });
    }

    #[test]
    fn bad_names_are_refused_with_the_reason() {
        for (name, says) in [
            ("plain+merging", "caustic transport"),
            ("guided", "unknown transport"),
            ("caustic+fast", "unknown option"),
            ("caustic+adaptive+adaptive", "twice"),
            ("", "unknown transport"),
        ] {
            let err = Estimator::parse(name).unwrap_err();
            assert!(err.contains(says), "{name}: {err}");
        }
    }

    #[test]
    fn the_default_is_the_unbiased_ground_truth_estimator() {
        let default = Estimator::default();
        assert_eq!(default.name(), "caustic+adaptive+stratified");
        assert!(!default.photon_merging());
    }
}
