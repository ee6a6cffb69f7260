//! Adaptive sampling: how many samples each pixel gets. A pilot pass, traced from random
//! streams of its own and then set aside, measures the noise of every 3x3 neighbourhood; the
//! pixels' budget is then spread in proportion to that noise (for the mean squared error
//! over an image, n_i proportional to the per-sample standard deviation sigma_i is optimal).
//!
//! Why the pilot is set aside: a pixel's samples must not decide how many samples the pixel
//! gets, or its mean is biased (a firefly in the pilot would buy more samples that dilute
//! it; Kirk and Arvo 1991). The final samples are drawn after the allocation and are
//! independent of it, so every pixel stays an unbiased mean, at the cost of the pilot's
//! 1/[`PILOT_SHARE`] of the budget.
//!
//! Pixels that show a glass object also share the noise measured over the whole object
//! ([`pool_by_object`]): a neighbourhood's pilot is too short to catch the rare bright paths
//! seen in glass.
//!
//! What counts as noise is what the metrics see: they clamp radiance to [0, 1], so a channel
//! whose pilot mean is clearly above 1 (the inside of a light) has no visible noise and
//! keeps only the floor.

use std::collections::BTreeMap;

/// The pilot takes 1/PILOT_SHARE of a pixel's budget.
pub const PILOT_SHARE: u32 = 16;
/// Every pixel keeps at least 1/FLOOR_SHARE of its budget, however quiet its neighbourhood
/// looked: a pilot of a few samples can miss rare light.
pub const FLOOR_SHARE: u32 = 4;
/// No pixel gets more than this many times its budget.
pub const MAX_FACTOR: u32 = 16;
/// Share of a glass pixel's noise estimate taken from its whole object ([`pool_by_object`]).
/// Chosen by measurement (docs/history/benchmarks-2026-11.md, 2026-11-24): at 128 px, 256 spp, 0.4, 0.6 and
/// 0.85 did about equally well; pooling opaque objects too made the Cornell boxes worse.
pub const OBJECT_SHARE: f64 = 0.6;
/// Below this budget the pilot (fewer than 16 samples a pixel, 144 a neighbourhood) is too
/// short to tell where the noise is: on cornellbox at 96 spp adaptive sampling was no better
/// than uniform, on two of three frames 1.14-1.25x worse (docs/benchmarks.md). Such pixels
/// are sampled uniformly.
pub const MIN_ADAPTIVE_SPP: u32 = 256;

/// Samples of the pilot for a pixel whose budget is `budget` (0: the pixel is sampled
/// uniformly).
pub fn pilot_spp(budget: u32) -> u32 {
    if budget >= MIN_ADAPTIVE_SPP {
        budget / PILOT_SHARE
    } else {
        0
    }
}

/// One pixel's pilot samples: sums and sums of squares per channel, and how many there were.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PilotStats {
    pub sum: [f64; 3],
    pub sum_squares: [f64; 3],
    pub count: u64,
}

/// The standard deviation per sample that each pixel's noise is taken to have (row-major,
/// `width` x `height`): the variance of the samples pooled over the pixel's 3x3 neighbourhood
/// (noise changes slowly across an image; one pixel's pilot alone is too short to say), over
/// the channels whose own pilot mean could still fall below 1 once the pixel is traced at
/// its `budget`.
pub fn noise_weights(pilot: &[PilotStats], budgets: &[u32], width: u32, height: u32) -> Vec<f64> {
    let (w, h) = (width as i64, height as i64);
    assert_eq!(pilot.len() as i64, w * h, "one pilot per pixel");
    (0..w * h)
        .map(|index| {
            let (x, y) = (index % w, index / w);
            let mut pooled = PilotStats::default();
            for ny in (y - 1).max(0)..=(y + 1).min(h - 1) {
                for nx in (x - 1).max(0)..=(x + 1).min(w - 1) {
                    let p = &pilot[(ny * w + nx) as usize];
                    for c in 0..3 {
                        pooled.sum[c] += p.sum[c];
                        pooled.sum_squares[c] += p.sum_squares[c];
                    }
                    pooled.count += p.count;
                }
            }
            if pooled.count < 2 {
                return 0.0;
            }
            let own = &pilot[index as usize];
            let n = pooled.count as f64;
            let mut visible_variance = 0.0;
            for c in 0..3 {
                let mean = pooled.sum[c] / n;
                let variance = ((pooled.sum_squares[c] - n * mean * mean) / (n - 1.0)).max(0.0);
                let own_mean = if own.count > 0 { own.sum[c] / own.count as f64 } else { mean };
                // Two standard errors at the final spp: a channel this far above 1 stays
                // clamped to 1 by every metric.
                let clearly_saturated = own_mean - 2.0 * (variance / budgets[index as usize].max(1) as f64).sqrt() > 1.0;
                if !clearly_saturated {
                    visible_variance += variance;
                }
            }
            (visible_variance / 3.0).sqrt()
        })
        .collect()
}

/// Blend each glass pixel's noise with its glass object's: sigma_i^2 becomes
/// (1 - [`OBJECT_SHARE`]) sigma_i^2 + [`OBJECT_SHARE`] x the mean of sigma^2 over the pixels
/// of the same object. `objects[i]` is the transparent object pixel i shows first (`None`
/// for anything else, whose weight stays). Why: most of the noise left on glass is rare
/// bright paths (caustics seen in or through it, reflections of glass in glass) that a
/// pilot of 16 samples a pixel, 144 a neighbourhood, catches only here and there, while
/// every pixel of the object is open to them; the object's hundreds of pixels measure their
/// rate where a neighbourhood cannot.
pub fn pool_by_object(weights: &[f64], objects: &[Option<u32>]) -> Vec<f64> {
    assert_eq!(weights.len(), objects.len(), "one object entry per pixel");
    let mut per_object: BTreeMap<u32, (f64, u64)> = BTreeMap::new();
    for (&weight, object) in weights.iter().zip(objects) {
        if let Some(object) = object {
            let entry = per_object.entry(*object).or_default();
            entry.0 += weight * weight;
            entry.1 += 1;
        }
    }
    weights
        .iter()
        .zip(objects)
        .map(|(&weight, object)| match object {
            Some(object) => {
                let (sum, count) = per_object[object];
                ((1.0 - OBJECT_SHARE) * weight * weight + OBJECT_SHARE * sum / count as f64).sqrt()
            }
            None => weight,
        })
        .collect()
}

/// Final samples per pixel (after the pilot), spreading each budget group's samples in
/// proportion to `weights`. Pixels are grouped by their budget (the `glass_spp` pixels and the
/// others), and each group keeps its own total: `sum(budget - pilot)` over the group, up to
/// what the per-pixel cap leaves unspent. Deterministic: a function of its inputs only.
pub fn allocate(budgets: &[u32], weights: &[f64]) -> Vec<u32> {
    assert_eq!(budgets.len(), weights.len(), "one weight per pixel");
    let mut groups: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (index, &budget) in budgets.iter().enumerate() {
        groups.entry(budget).or_default().push(index);
    }
    let mut counts = budgets.to_vec();
    for (budget, pixels) in groups {
        let pilot = pilot_spp(budget);
        if pilot == 0 {
            continue;
        }
        let floor = budget / FLOOR_SHARE;
        let headroom = (budget as u64 * MAX_FACTOR as u64 - floor as u64) as f64;
        let spare = (pixels.len() as u64 * (budget - pilot - floor) as u64) as f64;
        let extra = water_fill(&pixels.iter().map(|&i| weights[i].max(0.0)).collect::<Vec<_>>(), spare, headroom);
        // Cumulative rounding: integer counts whose running sum stays within half a sample
        // of the exact one, so the group's total is kept.
        let mut exact = 0.0;
        let mut given = 0u64;
        for (&index, share) in pixels.iter().zip(extra) {
            exact += share;
            let upto = exact.round() as u64;
            counts[index] = (floor as u64 + upto - given).min(u32::MAX as u64) as u32;
            given = upto;
        }
    }
    counts
}

/// Shares of `total` in proportion to `weights`, none above `cap`; whatever the caps leave
/// goes to the others in proportion again. Equal shares where every weight is zero.
fn water_fill(weights: &[f64], total: f64, cap: f64) -> Vec<f64> {
    let mut shares = vec![0.0; weights.len()];
    let mut capped = vec![false; weights.len()];
    let weights: Vec<f64> = if weights.iter().all(|&w| w == 0.0) { vec![1.0; weights.len()] } else { weights.to_vec() };
    let mut remaining = total;
    loop {
        let active: f64 = weights.iter().zip(&capped).filter(|(_, &c)| !c).map(|(w, _)| w).sum();
        if active <= 0.0 || remaining <= 0.0 {
            break;
        }
        let mut newly_capped = false;
        for (i, &w) in weights.iter().enumerate() {
            if !capped[i] {
                shares[i] = remaining * w / active;
                if shares[i] > cap {
                    capped[i] = true;
                    newly_capped = true;
                }
            }
        }
        if !newly_capped {
            break;
        }
        for (share, &c) in shares.iter_mut().zip(&capped) {
            if c {
                *share = cap;
            }
        }
        remaining = total - capped.iter().filter(|&&c| c).count() as f64 * cap;
    }
    shares
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(samples: &[f32]) -> PilotStats {
        let mut s = PilotStats::default();
        for &v in samples {
            for c in 0..3 {
                s.sum[c] += v as f64;
                s.sum_squares[c] += (v as f64).powi(2);
            }
            s.count += 1;
        }
        s
    }

    #[test]
    fn a_group_keeps_its_total_and_samples_follow_the_noise() {
        let budgets = vec![256u32; 6];
        let weights = [0.0, 1.0, 2.0, 4.0, 1.0, 0.5];
        let counts = allocate(&budgets, &weights);
        let pilot = pilot_spp(256);
        assert_eq!(counts.iter().map(|&c| c as u64).sum::<u64>(), 6 * (256 - pilot) as u64);
        let floor = 256 / FLOOR_SHARE;
        assert_eq!(counts[0], floor, "a pixel without noise keeps the floor");
        // Above the floor, extra samples are proportional to the weight (up to rounding).
        let spare = (6 * (256 - pilot - floor)) as f64;
        for (count, w) in counts.iter().zip(weights) {
            let expected = floor as f64 + spare * w / 8.5;
            assert!((*count as f64 - expected).abs() <= 1.0, "{count} vs {expected}");
        }
    }

    #[test]
    fn the_cap_holds_and_what_it_leaves_goes_to_the_others() {
        let budgets = vec![256u32; 100];
        let mut weights = vec![1.0; 100];
        weights[7] = 1e9;
        let counts = allocate(&budgets, &weights);
        assert_eq!(counts[7], 256 * MAX_FACTOR);
        assert_eq!(counts.iter().map(|&c| c as u64).sum::<u64>(), 100 * (256 - pilot_spp(256)) as u64);
        let others: Vec<u32> = counts.iter().enumerate().filter(|(i, _)| *i != 7).map(|(_, &c)| c).collect();
        assert!(others.iter().max().unwrap() - others.iter().min().unwrap() <= 1, "{others:?}");
    }

    #[test]
    fn groups_keep_their_budgets_and_small_budgets_stay_uniform() {
        let small = MIN_ADAPTIVE_SPP - 1;
        let budgets = [small, small, 256, 256, 512, small];
        let weights = [5.0, 0.0, 0.0, 3.0, 1.0, 1.0];
        let counts = allocate(&budgets, &weights);
        assert_eq!(&counts[..2], &[small, small]);
        assert_eq!(counts[5], small);
        assert_eq!(counts[2] + counts[3], 2 * (256 - pilot_spp(256)));
        assert_eq!(counts[2], 256 / FLOOR_SHARE);
        assert_eq!(counts[4], 512 - pilot_spp(512), "a group of one gets its own budget back");
    }

    #[test]
    fn glass_pixels_share_their_objects_noise() {
        // Object 0 covers pixels 0 and 3 (one noisy, one quiet), object 1 pixel 4 alone;
        // pixels 1 and 2 show no glass.
        let weights = [2.0, 1.0, 0.5, 0.0, 3.0];
        let objects = [Some(0), None, None, Some(0), Some(1)];
        let pooled = pool_by_object(&weights, &objects);
        let object_variance = (4.0 + 0.0) / 2.0;
        let blend = |w: f64| ((1.0 - OBJECT_SHARE) * w * w + OBJECT_SHARE * object_variance).sqrt();
        assert!((pooled[0] - blend(2.0)).abs() < 1e-12, "{}", pooled[0]);
        assert!((pooled[3] - blend(0.0)).abs() < 1e-12, "{}", pooled[3]);
        assert!(pooled[3] > 1.0, "a quiet pixel of a noisy object gets the object's noise");
        assert_eq!(&pooled[1..3], &weights[1..3], "pixels without glass keep their own");
        assert!((pooled[4] - 3.0).abs() < 1e-12, "an object of one pixel is that pixel");
    }

    #[test]
    fn noise_is_pooled_over_the_neighbourhood_and_saturated_channels_are_quiet() {
        // 3x1 image: a noisy pixel (samples 0 and 0.5), a constant one, and the inside of a
        // light (samples 10 and 12).
        let pilot = [stats(&[0.0, 0.5, 0.0, 0.5]), stats(&[0.25; 4]), stats(&[10.0, 12.0, 10.0, 12.0])];
        let budgets = [64; 3];
        let w = noise_weights(&pilot, &budgets, 3, 1);
        // Pixel 0 pools itself and pixel 1: samples {0, .5, 0, .5, .25 x4}, variance 1/28.
        assert!((w[0] - (1.0f64 / 28.0).sqrt()).abs() < 1e-12, "{}", w[0]);
        // Pixel 1 pools all three: its own mean 0.25 is below 1, so the light's spread counts.
        assert!(w[1] > 1.0, "{}", w[1]);
        // Pixel 2's own mean is 11: clamped to 1 whatever its neighbours do.
        assert_eq!(w[2], 0.0);
    }
}
