//! Weight initialisation from the run's seed alone. burn's initialisers draw from the device's
//! global RNG, which anything else on the device (another model, a parallel test) also draws
//! from; re-drawing every parameter from its own ChaCha8 stream makes a seed mean one set of
//! weights, whatever else runs.

use burn::module::{Module, ModuleMapper, Param};
use burn::prelude::*;
use burn::tensor::TensorData;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use glassbake_core::seed::sample_seed;

/// Weights ~ U(-1/sqrt(fan_in), 1/sqrt(fan_in)) (PyTorch's and burn's default for convolutions,
/// Kaiming-uniform with a = sqrt 5), biases 0. Parameter k in visiting order uses the stream
/// `sample_seed(seed, k)`.
pub fn initialize<M: Module>(model: M, seed: u64) -> M {
    struct Initializer {
        seed: u64,
        next: u64,
    }
    impl ModuleMapper for Initializer {
        fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            let mut rng = ChaCha8Rng::seed_from_u64(sample_seed(self.seed, self.next));
            self.next += 1;
            param.map(|tensor| {
                let dims = tensor.dims();
                let device = tensor.device();
                let grad = tensor.is_require_grad();
                let count: usize = dims.iter().product();
                let values: Vec<f32> = if D >= 2 {
                    // [out, in, kh, kw] (and [in, out, kh, kw] for transposed convolutions,
                    // where the product over dims 1.. is again the fan-in of one output).
                    let fan_in: usize = dims[1..].iter().product();
                    let bound = 1.0 / (fan_in.max(1) as f32).sqrt();
                    (0..count).map(|_| rng.random_range(-bound..bound)).collect()
                } else {
                    vec![0.0; count]
                };
                let fresh = Tensor::from_data(TensorData::new(values, dims), &device);
                if grad {
                    fresh.require_grad()
                } else {
                    fresh
                }
            })
        }
    }
    model.map(&mut Initializer { seed, next: 0 })
}
