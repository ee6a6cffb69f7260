//! How sure a mean over test frames is: percentile-bootstrap intervals (Efron & Tibshirani,
//! "An Introduction to the Bootstrap", 1993, ch. 13) of each metric's mean, and of each
//! model's per-frame difference to a reference model (paired: both resampled by the same
//! frames, so what the two share in difficulty cancels). Seeded, so an evaluation's intervals
//! are the same every time it is run.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Resamples per interval: the 2.5% and 97.5% quantiles then rest on 50 resamples each.
pub const RESAMPLES: usize = 2000;

/// The resampling's seed (any fixed value; fixed so that reports are reproducible).
pub const SEED: u64 = 0x6c61_7373_626f_6f74;

/// A mean with its 95% interval.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    pub mean: f64,
    pub low: f64,
    pub high: f64,
}

impl Estimate {
    /// Whether the whole interval lies above zero (a difference that is a gain, not noise).
    pub fn above_zero(&self) -> bool {
        self.low > 0.0
    }

    pub fn below_zero(&self) -> bool {
        self.high < 0.0
    }
}

/// The quantile `q` of sorted values, linearly interpolated.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let at = q * (sorted.len() - 1) as f64;
    let (i, frac) = (at.floor() as usize, at.fract());
    if i + 1 < sorted.len() {
        sorted[i] + frac * (sorted[i + 1] - sorted[i])
    } else {
        sorted[i]
    }
}

/// The mean of the frames' values (`None` where a frame has no value, as T.PSNR on a frame
/// without glass) with its 95% percentile-bootstrap interval over frames; `None` with fewer
/// than two values. Frames are resampled with replacement, all of them, so the share of frames
/// without a value varies as it would in another test split.
pub fn mean_interval(values: &[Option<f64>], seed: u64) -> Option<Estimate> {
    let present: Vec<f64> = values.iter().flatten().copied().collect();
    if present.len() < 2 {
        return None;
    }
    let mean = present.iter().sum::<f64>() / present.len() as f64;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut means = Vec::with_capacity(RESAMPLES);
    while means.len() < RESAMPLES {
        let (mut sum, mut n) = (0.0, 0usize);
        for _ in 0..values.len() {
            if let Some(v) = values[rng.random_range(0..values.len())] {
                sum += v;
                n += 1;
            }
        }
        if n > 0 {
            means.push(sum / n as f64);
        }
    }
    means.sort_by(f64::total_cmp);
    Some(Estimate { mean, low: quantile(&means, 0.025), high: quantile(&means, 0.975) })
}

/// The mean per-frame difference `model - reference` with its paired 95% interval (frames
/// where either has no value are left out of every resample).
pub fn paired_difference(model: &[Option<f64>], reference: &[Option<f64>], seed: u64) -> Option<Estimate> {
    let differences: Vec<Option<f64>> = model.iter().zip(reference).map(|(m, r)| Some((*m)? - (*r)?)).collect();
    mean_interval(&differences, seed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// Normal draws (Box-Muller) of mean `mu` and deviation `sigma`.
    fn normal(rng: &mut ChaCha8Rng, n: usize, mu: f64, sigma: f64) -> Vec<Option<f64>> {
        (0..n)
            .map(|_| {
                let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
                Some(mu + sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos())
            })
            .collect()
    }

    /// The interval's half-width is the standard error's 1.96 (the normal theory answer for a
    /// mean of n draws of deviation sigma), and it covers the true mean about 95% of the time.
    #[test]
    fn intervals_match_the_normal_theory_and_cover_the_mean() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (n, sigma) = (400, 2.0);
        let e = mean_interval(&normal(&mut rng, n, 30.0, sigma), 5).unwrap();
        let expected = 1.96 * sigma / (n as f64).sqrt();
        let half = 0.5 * (e.high - e.low);
        assert!((half / expected - 1.0).abs() < 0.12, "half-width {half} against {expected}");
        assert!(e.low < e.mean && e.mean < e.high);

        let trials = 300;
        let covered = (0..trials).filter(|&t| mean_interval(&normal(&mut rng, 40, 30.0, sigma), t).is_some_and(|e| e.low <= 30.0 && 30.0 <= e.high)).count();
        let rate = covered as f64 / trials as f64;
        // The percentile bootstrap of 40 normal draws covers a little under 95% (its known
        // small-sample narrowness); 300 trials put the rate within about 2.5 points of it.
        assert!((0.89..=0.98).contains(&rate), "covered {rate}");
    }

    /// Pairing removes what two models share: a model that is the reference plus a constant
    /// gets exactly that constant as its interval, however much the frames vary; frames
    /// without a value for either are left out.
    #[test]
    fn paired_differences_cancel_what_the_frames_share() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let reference = normal(&mut rng, 50, 25.0, 5.0);
        let shifted: Vec<Option<f64>> = reference.iter().map(|v| v.map(|v| v + 0.3)).collect();
        let d = paired_difference(&shifted, &reference, 9).unwrap();
        for value in [d.mean, d.low, d.high] {
            assert!((value - 0.3).abs() < 1e-9, "{d:?}");
        }
        assert!(d.above_zero());
        // Unpaired, the same 0.3 dB would be lost in the frames' 5 dB spread.
        let (a, b) = (mean_interval(&shifted, 9).unwrap(), mean_interval(&reference, 9).unwrap());
        assert!(a.low < b.high);
        let mut gappy = shifted.clone();
        gappy[3] = None;
        let mut gappy_reference = reference.clone();
        gappy_reference[7] = None;
        let d = paired_difference(&gappy, &gappy_reference, 9).unwrap();
        assert!((d.low - 0.3).abs() < 1e-9 && (d.high - 0.3).abs() < 1e-9);
    }

    #[test]
    fn seeded_and_undefined_below_two_values() {
        let values: Vec<Option<f64>> = (0..30).map(|i| Some(i as f64)).collect();
        assert_eq!(mean_interval(&values, 3), mean_interval(&values, 3));
        assert_eq!(mean_interval(&[Some(1.0)], 3), None);
        assert_eq!(mean_interval(&[Some(1.0), None, None], 3), None);
    }
}
