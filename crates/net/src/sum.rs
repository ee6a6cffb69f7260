//! The symmetric function of T: an order-independent, bit-exact sum of per-object terms.
//!
//! Floating-point addition is not associative, so summing h's outputs in two orders can differ
//! in the last bit. Every term is therefore snapped to a fixed-point grid first: clamped to
//! [-TERM_BOUND, TERM_BOUND] and rounded to a multiple of 2^-FRACTION_BITS. Any sum of at
//! most MAX_EXACT_OBJECTS such terms is a multiple of 2^-FRACTION_BITS no larger than
//! 2^(24-FRACTION_BITS) in magnitude, which an f32 (24-bit significand) holds exactly; every
//! partial sum is then exact, so the total is the same in any order, on any backend.
//!
//! Training sees the rounding as the identity (a straight-through estimator): the forward value
//! is `x + (q(x) - x).detach()`. That is exactly q(x) too: when |x| >= 2^-FRACTION_BITS, q(x)
//! lies within a factor 2 of x, so `q(x) - x` is exact (Sterbenz), and when |x| is smaller,
//! q(x) is 0 (difference -x, exact) or +-2^-FRACTION_BITS (again within a factor 2 of x).

use burn::prelude::*;

use crate::config::MAX_EXACT_OBJECTS;

/// Resolution of the grid: 2^-16 ~ 1.5e-5, far below what h's features need.
pub const FRACTION_BITS: u32 = 16;

/// Largest magnitude of one term: MAX_EXACT_OBJECTS terms then sum to at most 2^(24-16).
pub const TERM_BOUND: f32 = (1u32 << (24 - FRACTION_BITS)) as f32 / MAX_EXACT_OBJECTS as f32;

/// Snaps one object's term onto the exact grid (straight-through for gradients).
pub fn snap_to_grid(term: Tensor<4>) -> Tensor<4> {
    let scale = (1u64 << FRACTION_BITS) as f64;
    let clamped = term.clamp(-TERM_BOUND, TERM_BOUND);
    let snapped = clamped.clone().mul_scalar(scale).round().div_scalar(scale);
    clamped.clone() + (snapped - clamped).detach()
}

/// tau = sum_i q(h(b_i, sigma)), accumulated one object at a time so that at most one term and
/// the running sum are alive, whatever the number of objects.
#[derive(Default)]
pub struct TransparencySum {
    sum: Option<Tensor<4>>,
    terms: usize,
}

impl TransparencySum {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one object's term; it must already be snapped by [`snap_to_grid`].
    pub fn add(&mut self, term: Tensor<4>) {
        assert!(self.terms < MAX_EXACT_OBJECTS, "more than {MAX_EXACT_OBJECTS} transparency terms would not sum exactly");
        self.terms += 1;
        self.sum = Some(match self.sum.take() {
            Some(sum) => sum + term,
            None => term,
        });
    }

    pub fn terms(&self) -> usize {
        self.terms
    }

    /// The sum, or zeros of `shape` on `device` when no object was added (a scene with no glass
    /// in view: tau is the empty sum).
    pub fn finish(self, shape: [usize; 4], device: &Device) -> Tensor<4> {
        self.sum.unwrap_or_else(|| Tensor::zeros(shape, device))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Distribution, TensorData};
    use rand::seq::SliceRandom;
    use rand::SeedableRng;

    fn bits(t: Tensor<4>) -> Vec<u32> {
        t.into_data().try_to_vec::<f32>().unwrap().into_iter().map(f32::to_bits).collect()
    }

    #[test]
    fn snapped_terms_sum_identically_in_every_order() {
        let device = Device::flex();
        device.seed(7);
        // Wide-ranging magnitudes (including values beyond the bound) make plain f32 sums
        // order-dependent; the test below checks that they really are, so it can fail.
        let terms: Vec<Tensor<4>> =
            (0..MAX_EXACT_OBJECTS).map(|i| Tensor::<4>::random([1, 4, 8, 8], Distribution::Normal(0.0, 10f64.powi(i as i32 % 4 - 1)), &device)).collect();
        let plain = |order: &[usize]| bits(order.iter().map(|&i| terms[i].clone()).reduce(|a, b| a + b).unwrap());
        let exact = |order: &[usize]| {
            let mut sum = TransparencySum::new();
            for &i in order {
                sum.add(snap_to_grid(terms[i].clone()));
            }
            bits(sum.finish([1, 4, 8, 8], &device))
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let forward: Vec<usize> = (0..terms.len()).collect();
        let reference = exact(&forward);
        let mut plain_differed = false;
        for _ in 0..20 {
            let mut order = forward.clone();
            order.shuffle(&mut rng);
            assert_eq!(exact(&order), reference);
            plain_differed |= plain(&order) != plain(&forward);
        }
        assert!(plain_differed, "plain f32 sums never differed: the test inputs do not exercise non-associativity");
    }

    #[test]
    fn snapping_rounds_to_the_grid_and_clamps() {
        let device = Device::flex();
        let step = 1.0 / (1u64 << FRACTION_BITS) as f32;
        let input = [0.3 * step, 0.7 * step, -0.7 * step, 1.0 + 0.49 * step, 1e6, -1e6, 0.0, 3.25];
        let expected = [0.0, step, -step, 1.0, TERM_BOUND, -TERM_BOUND, 0.0, 3.25];
        let x = Tensor::<4>::from_data(TensorData::new(input.to_vec(), [1, 1, 1, input.len()]), &device);
        let got = snap_to_grid(x).into_data().try_to_vec::<f32>().unwrap();
        assert_eq!(got, expected);
    }
}
