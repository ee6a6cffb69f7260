//! Half precision, emulated on any backend, to measure what it costs in quality before a
//! backend runs it: weights rounded to f16 ([`round_weights_to_f16`]), and, when
//! [`set_f16_activations`] is on, every convolution's input and output rounded to f16 while
//! the convolution itself computes in f32: what GPUs compute with f16 storage and f32
//! accumulation (tensor cores, cooperative matrices). The permutation-invariant sum of the
//! transparency terms stays in f32, as a half-precision network would keep it.

use std::sync::atomic::{AtomicBool, Ordering};

use burn::module::{Module, ModuleMapper, Param};
use burn::prelude::*;
use burn::tensor::FloatDType;

static F16_ACTIVATIONS: AtomicBool = AtomicBool::new(false);

/// Rounds `x` to the nearest f16 and back.
fn through_f16<const D: usize>(x: Tensor<D>) -> Tensor<D> {
    x.cast(FloatDType::F16).cast(FloatDType::F32)
}

/// `model` with every float parameter rounded to the nearest f16 (kept in f32).
pub fn round_weights_to_f16<M: Module>(model: M) -> M {
    struct Rounder;
    impl ModuleMapper for Rounder {
        fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            param.map(through_f16)
        }
    }
    model.map(&mut Rounder)
}

/// Turns the rounding of the convolutions' inputs and outputs on or off, for the whole
/// process (a measurement's switch, not a setting of one model).
pub fn set_f16_activations(on: bool) {
    F16_ACTIVATIONS.store(on, Ordering::Relaxed);
}

/// `x` rounded to f16 when [`set_f16_activations`] is on, else `x`.
pub(crate) fn activation(x: Tensor<4>) -> Tensor<4> {
    if F16_ACTIVATIONS.load(Ordering::Relaxed) {
        through_f16(x)
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::conv::Conv2dConfig;
    use burn::tensor::TensorData;

    // The switch is process-wide and other tests of this crate convolve in parallel: these
    // tests leave it off and check the rounding itself.

    #[test]
    fn rounding_to_f16_keeps_f16s_and_rounds_to_the_nearest() {
        let device = Device::flex();
        // 1 + 2^-10 is an f16; 1 + 2^-12 lies a quarter step above 1 and rounds down;
        // 2049 lies halfway between the f16s 2048 and 2050 and rounds to the even 2048;
        // 0.1's nearest f16 is 1638 / 16384.
        let x = Tensor::<4>::from_data(TensorData::new(vec![1.0 + 2f32.powi(-10), 1.0 + 2f32.powi(-12), 2049.0, 0.1], [1, 1, 2, 2]), &device);
        let rounded = through_f16(x.clone()).into_data().try_to_vec::<f32>().unwrap();
        assert_eq!(rounded, [1.0 + 2f32.powi(-10), 1.0, 2048.0, 1638.0 / 16384.0]);
        let kept = activation(x).into_data().try_to_vec::<f32>().unwrap();
        assert_eq!(kept[1], 1.0 + 2f32.powi(-12), "with the switch off, nothing is rounded");
    }

    #[test]
    fn rounded_weights_are_f16_values_within_half_a_step() {
        let device = Device::flex();
        let conv = Conv2dConfig::new([3, 5], [3, 3]).init(&device);
        let before = conv.weight.val().into_data().try_to_vec::<f32>().unwrap();
        let after = round_weights_to_f16(conv).weight.val().into_data().try_to_vec::<f32>().unwrap();
        assert_eq!(before.len(), after.len());
        let mut changed = 0;
        for (&b, &a) in before.iter().zip(&after) {
            // f16 has 11 significant bits: within 2^-11 of the value, relatively.
            assert!((a - b).abs() <= b.abs() * 2f32.powi(-11), "{b} rounded to {a}");
            // An f16 value rounds to itself.
            let again = through_f16(Tensor::<1>::from_data(TensorData::new(vec![a], [1]), &device)).into_data().try_to_vec::<f32>().unwrap()[0];
            assert_eq!(again, a);
            changed += usize::from(a != b);
        }
        assert!(changed > before.len() / 2, "only {changed} of {} weights moved", before.len());
    }
}
