//! The per-pixel random number generator. Each pixel owns one stream seeded from
//! (image seed, pixel index) and consumes it in a fixed order, which is what makes an image
//! bit-identical whatever the thread count.

use glam::Vec2;
use glassbake_core::seed::mix64;

/// PCG32 (O'Neill 2014, "PCG: A Family of Simple Fast Space-Efficient Statistically Good
/// Algorithms for Random Number Generation"), XSH-RR output, 64-bit state.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    increment: u64,
}

const PCG_MULTIPLIER: u64 = 6_364_136_223_846_793_005;

impl Pcg32 {
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Pcg32 { state: 0, increment: (stream << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The stream of pixel `pixel_index` of an image rendered with `image_seed`.
    pub fn for_pixel(image_seed: u64, pixel_index: u64) -> Self {
        Pcg32::new(mix64(image_seed ^ mix64(pixel_index)), mix64(image_seed.wrapping_add(pixel_index)))
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULTIPLIER).wrapping_add(self.increment);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1): the top 24 bits, so every value is exactly representable.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    pub fn next_vec2(&mut self) -> Vec2 {
        let x = self.next_f32();
        Vec2::new(x, self.next_f32())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_in_unit_interval_with_the_right_mean() {
        let mut rng = Pcg32::new(42, 7);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        let mean = sum / n as f64;
        // Standard error of the mean of U(0,1) is 0.2887/sqrt(n) = 9.1e-4; allow 5 sigma.
        assert!((mean - 0.5).abs() < 4.6e-3, "{mean}");
    }

    #[test]
    fn pixel_streams_differ_and_repeat() {
        let a: Vec<u32> = (0..4).map(|_| 0).scan(Pcg32::for_pixel(1, 0), |r, _: u32| Some(r.next_u32())).collect();
        let b: Vec<u32> = (0..4).map(|_| 0).scan(Pcg32::for_pixel(1, 0), |r, _: u32| Some(r.next_u32())).collect();
        let c: Vec<u32> = (0..4).map(|_| 0).scan(Pcg32::for_pixel(1, 1), |r, _: u32| Some(r.next_u32())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }
}
