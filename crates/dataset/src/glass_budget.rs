//! A cost limit on the glass pixels' extra samples.
//!
//! Glass pixels traced at several times `spp` cost little where glass fills a fifth of the
//! view and dominate a frame where it fills most of it (bathroom's partition covers 58% of
//! its frames on average: at 4x spp on glass a frame costs 2.7x its uniform trace). A budget
//! caps the extra samples at a share of the frames' samples at their base spp; the glass spp
//! it leaves is decided once per dataset, from the geometry of the frames it plans, so every
//! pixel stays an unbiased mean of its own samples and the dataset is the same on every run.

use glassbake_core::{Error, Result};
use glassbake_scene::Scene;
use glassbake_trace::{glass_pixels, PreparedScene};
use rayon::prelude::*;

use crate::format::{DatasetManifest, DatasetSpec};

/// Share of the pixels that show glass (`glassbake_trace::glass_pixels`) in each frame `spec`
/// plans of `scene`, each with its own camera and variable values, in frame order.
pub fn glass_shares(scene: &Scene, spec: &DatasetSpec) -> Result<Vec<f64>> {
    let res = spec.resolution;
    DatasetManifest::plan(spec, scene)
        .samples
        .par_iter()
        .map(|sample| {
            let instance = scene.instantiate(&sample.values)?;
            let glass = glass_pixels(&PreparedScene::new(&instance), &sample.camera, res, res);
            Ok(glass.iter().filter(|&&g| g).count() as f64 / glass.len() as f64)
        })
        .collect()
}

/// Mean of [`glass_shares`]; 0 for a dataset of no frames.
pub fn mean_glass_share(scene: &Scene, spec: &DatasetSpec) -> Result<f64> {
    let shares = glass_shares(scene, spec)?;
    if shares.is_empty() {
        return Ok(0.0);
    }
    // Summed in frame order, so the share (and the spp it decides) never depends on threads.
    Ok(shares.iter().sum::<f64>() / shares.len() as f64)
}

/// The most samples per pixel glass pixels can get when a share `glass_share` of the pixels
/// show glass and their samples beyond `spp` may add at most `budget` x the frame's samples
/// at `spp`: `glass_spp`, or less where that would cost more. Never below `spp`.
pub fn glass_spp_within_budget(spp: u32, glass_spp: u32, glass_share: f64, budget: f64) -> u32 {
    if glass_spp <= spp || glass_share <= 0.0 {
        return glass_spp;
    }
    let affordable_extra = (budget * f64::from(spp) / glass_share).floor();
    let extra = f64::from(glass_spp - spp).min(affordable_extra.max(0.0));
    spp + extra as u32
}

/// `spec` with its glass pixels' spp (training and test alike) lowered where their extra
/// samples, over the frames it plans of `scene`, would add more than `budget` x the samples
/// of those frames at their split's spp. A spec whose glass pixels fit is returned unchanged.
pub fn fit_glass_budget(spec: DatasetSpec, scene: &Scene, budget: f64) -> Result<DatasetSpec> {
    if !(budget.is_finite() && budget >= 0.0) {
        return Err(Error::bad_input("dataset", "glass budget", format!("{budget} is not a share of the frame's samples (0 or more)")));
    }
    let raises = |split_spp: u32, glass_spp: Option<u32>| glass_spp.is_some_and(|g| g > split_spp);
    let test_spp = spec.test_spp.unwrap_or(spec.spp);
    if !raises(spec.spp, spec.glass_spp) && !raises(test_spp, spec.test_glass_spp) {
        return Ok(spec);
    }
    let share = mean_glass_share(scene, &spec)?;
    let fit = |split_spp: u32, glass_spp: Option<u32>| glass_spp.map(|g| glass_spp_within_budget(split_spp, g, share, budget));
    Ok(DatasetSpec { glass_spp: fit(spec.spp, spec.glass_spp), test_glass_spp: fit(test_spp, spec.test_glass_spp), ..spec })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glass_that_fits_keeps_its_spp() {
        // A fifth of the view at 4x spp adds 3 x 0.2 = 0.6 of the frame's samples.
        assert_eq!(glass_spp_within_budget(96, 384, 0.2, 0.75), 384);
        assert_eq!(glass_spp_within_budget(96, 384, 0.0, 0.0), 384);
        assert_eq!(glass_spp_within_budget(96, 96, 0.9, 0.0), 96);
    }

    #[test]
    fn glass_over_budget_gets_what_the_budget_buys() {
        // Half the view: 0.75 x 96 / 0.5 = 144 extra samples on each glass pixel.
        assert_eq!(glass_spp_within_budget(96, 384, 0.5, 0.75), 240);
        // The whole view: the frame's samples grow by exactly the budget.
        assert_eq!(glass_spp_within_budget(100, 400, 1.0, 0.5), 150);
        // A budget of nothing leaves the glass at spp.
        assert_eq!(glass_spp_within_budget(96, 384, 0.6, 0.0), 96);
    }

    #[test]
    fn the_extra_samples_never_exceed_the_budget() {
        for spp in [1u32, 7, 96, 768] {
            for share in [0.01, 0.13, 0.37, 0.584, 0.99] {
                for budget in [0.0, 0.1, 0.75, 2.0] {
                    let glass_spp = glass_spp_within_budget(spp, 4 * spp, share, budget);
                    let extra = share * f64::from(glass_spp - spp);
                    assert!((spp..=4 * spp).contains(&glass_spp));
                    assert!(extra <= budget * f64::from(spp) + 1e-9, "spp {spp}, share {share}, budget {budget}: {glass_spp}");
                    // ... and one more sample on glass would exceed it, unless capped at 4x.
                    let one_more = share * f64::from(glass_spp + 1 - spp);
                    assert!(glass_spp == 4 * spp || one_more > budget * f64::from(spp), "spp {spp}, share {share}, budget {budget}");
                }
            }
        }
    }
}
