//! Stratified sample values for the first dimensions of a path: randomized quasi-Monte Carlo.
//!
//! A pixel's samples take their sub-pixel position, and at each of the first vertices their
//! light and BSDF samples (smooth glass's choice between reflection and transmission
//! included: `integrator.rs`), from 2D points of the Sobol
//! (0,2)-sequence instead of independent random numbers. Any 2^k consecutive points of that sequence form a (0,k,2)-net: one point in
//! every elementary box of area 2^-k, so a pixel's samples cover the pixel, the light and the
//! BSDF lobe evenly, and the error of smooth integrands (soft shadows, glossy and blurred
//! views, edges) falls faster than with independent samples.
//!
//! Each 2D pair ("dimension") is randomized on its own (padding; Kollig and Keller 2002): the
//! order of the samples is shuffled by an Owen scramble of the index, and both coordinates are
//! Owen-scrambled, with seeds hashed from (image seed, pixel, pass, dimension). Hash-based
//! nested uniform scrambling as in Burley 2020, "Practical Hash-based Owen Scrambling"
//! (JCGT 9(4)): reverse the bits, apply a permutation in which every bit depends only on
//! itself and the bits below it, reverse again. With a uniformly random seed each
//! scrambled point is uniformly distributed on [0,1)^2 (the `+ seed` step makes every output
//! bit its input bit XOR an independent seed bit, and the rest is a bijection), so every
//! sample stays an unbiased estimate; scrambling keeps the net property, shuffling keeps the
//! padded dimensions from correlating.

use glam::Vec2;

/// Direction numbers of the Sobol sequence's second dimension (primitive polynomial x + 1):
/// v_0 = 2^31, v_k = v_{k-1} XOR (v_{k-1} >> 1). The first dimension is the van der Corput
/// sequence (the index's bits reversed).
const SOBOL_SECOND: [u32; 32] = {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    v
};

/// The second dimension is linear over GF(2) in the index's bits: XOR of the direction
/// numbers of its set bits, looked up a byte at a time. `SOBOL_SECOND_BY_BYTE[b][v]` is the
/// XOR over the set bits of `v` of the direction numbers of bits 8b..8b+7.
const SOBOL_SECOND_BY_BYTE: [[u32; 256]; 4] = {
    let mut table = [[0u32; 256]; 4];
    let mut byte = 0;
    while byte < 4 {
        let mut value = 0;
        while value < 256 {
            let mut result = 0;
            let mut bit = 0;
            while bit < 8 {
                if value & (1 << bit) != 0 {
                    result ^= SOBOL_SECOND[8 * byte + bit];
                }
                bit += 1;
            }
            table[byte][value] = result;
            value += 1;
        }
        byte += 1;
    }
    table
};

fn sobol_second(index: u32) -> u32 {
    let b = index.to_le_bytes();
    SOBOL_SECOND_BY_BYTE[0][b[0] as usize]
        ^ SOBOL_SECOND_BY_BYTE[1][b[1] as usize]
        ^ SOBOL_SECOND_BY_BYTE[2][b[2] as usize]
        ^ SOBOL_SECOND_BY_BYTE[3][b[3] as usize]
}

/// A permutation of u32 in which output bit j depends only on input bits 0..=j (Laine and
/// Karras 2011; these multipliers are the ones Burley 2020 gives). Multiplying by an even
/// constant moves bits only upwards, so `x ^= x * c` keeps that property and is invertible.
fn laine_karras_permutation(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Owen scrambling of a 32-bit binary fraction: each bit flipped by a function of the bits
/// above it (more significant) and the seed.
fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    laine_karras_permutation(x.reverse_bits(), seed).reverse_bits()
}

/// SplitMix64's finalizer: a well-mixed 64-bit hash.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// [0, 1) from the top 24 bits (exactly representable in f32).
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Which 2D dimension each stratified use reads: the sub-pixel position, then per vertex the
/// light sample and the BSDF sample, for the first [`STRATIFIED_VERTICES`] vertices (later
/// ones draw independent numbers: little of an image's noise is decided that deep).
pub const PIXEL_DIMENSION: u32 = 0;
pub const STRATIFIED_VERTICES: u32 = 4;
const DIMENSIONS: usize = 1 + 2 * STRATIFIED_VERTICES as usize;

/// The scrambling seeds of one dimension: sample order, x, y.
#[derive(Clone, Copy, Debug, Default)]
struct DimensionSeeds {
    order: u32,
    x: u32,
    y: u32,
}

/// One pixel's randomization of every dimension, for one pass: hashed once per pixel.
#[derive(Clone, Debug)]
pub struct StratifiedPixel {
    dimensions: [DimensionSeeds; DIMENSIONS],
}

impl StratifiedPixel {
    /// Seeds from (pass seed, pixel): a pass with another seed (a pilot, an independent
    /// re-trace) gets an independent randomization.
    pub fn new(pass_seed: u64, pixel_index: u64) -> Self {
        let pixel_key = mix64(mix64(pass_seed ^ 0x5157_4d43_2d51_4d43) ^ pixel_index);
        let mut dimensions = [DimensionSeeds::default(); DIMENSIONS];
        for (d, seeds) in dimensions.iter_mut().enumerate() {
            let a = mix64(pixel_key ^ mix64(d as u64 + 1));
            *seeds = DimensionSeeds { order: mix64(a) as u32, x: a as u32, y: (a >> 32) as u32 };
        }
        StratifiedPixel { dimensions }
    }

    pub fn sample(&self, index: u32) -> StratifiedSample<'_> {
        StratifiedSample { pixel: self, index }
    }
}

/// The stratified values of one sample of one pixel.
#[derive(Clone, Copy, Debug)]
pub struct StratifiedSample<'a> {
    pixel: &'a StratifiedPixel,
    /// The sample's index among the pixel's samples of this pass.
    index: u32,
}

impl StratifiedSample<'_> {
    /// The sample's point in 2D dimension `dimension` (below `1 + 2 * STRATIFIED_VERTICES`).
    pub fn get_2d(&self, dimension: u32) -> Vec2 {
        let seeds = self.pixel.dimensions[dimension as usize];
        let shuffled = nested_uniform_scramble(self.index, seeds.order);
        let x = nested_uniform_scramble(shuffled.reverse_bits(), seeds.x);
        let y = nested_uniform_scramble(sobol_second(shuffled), seeds.y);
        Vec2::new(to_unit(x), to_unit(y))
    }
}

pub fn light_dimension(vertex: u32) -> Option<u32> {
    (vertex < STRATIFIED_VERTICES).then(|| 1 + 2 * vertex)
}

pub fn bsdf_dimension(vertex: u32) -> Option<u32> {
    (vertex < STRATIFIED_VERTICES).then(|| 2 + 2 * vertex)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sobol_pairs_form_nets_and_scrambling_keeps_them() {
        // 256 consecutive points: one in each of the 2^a x 2^(8-a) elementary boxes.
        for (pixel, dimension) in [(0u64, 0u32), (7, 3), (123_456, 8)] {
            let stratified = StratifiedPixel::new(42, pixel);
            let points: Vec<Vec2> = (0..256).map(|i| stratified.sample(i).get_2d(dimension)).collect();
            for a in 0..=8u32 {
                let (nx, ny) = (1u32 << a, 1u32 << (8 - a));
                let mut seen = vec![false; 256];
                for p in &points {
                    let cell = (p.x * nx as f32) as u32 + nx * (p.y * ny as f32) as u32;
                    assert!(!seen[cell as usize], "pixel {pixel}, dimension {dimension}: two points in box {cell} of {nx}x{ny}");
                    seen[cell as usize] = true;
                }
            }
        }
        // Unscrambled, the second dimension is Sobol's: 0, 1/2, 3/4, 1/4, ...; the byte tables
        // agree with the bit-by-bit definition.
        let firsts: Vec<u32> = (0..4).map(sobol_second).collect();
        assert_eq!(firsts, [0, 1 << 31, 3 << 30, 1 << 30]);
        for index in [5u32, 0xdead_beef, u32::MAX, 1 << 31, 0x0102_0304] {
            let by_bits = (0..32).filter(|k| index & (1 << k) != 0).fold(0, |acc, k| acc ^ SOBOL_SECOND[k]);
            assert_eq!(sobol_second(index), by_bits, "{index:#x}");
        }
    }

    /// Every scrambled point is uniform over the pixels and seeds: a chi-square test of one
    /// fixed sample index over 4,096 pixels, on a 16 x 16 grid, per dimension.
    #[test]
    fn each_sample_is_uniformly_distributed() {
        for (index, dimension) in [(0u32, 0u32), (5, 1), (200, 6)] {
            let mut counts = [0u32; 256];
            let n = 4096 * 4;
            for pixel in 0..n as u64 {
                let p = StratifiedPixel::new(9, pixel).sample(index).get_2d(dimension);
                assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                counts[(p.x * 16.0) as usize + 16 * (p.y * 16.0) as usize] += 1;
            }
            let expected = n as f64 / 256.0;
            let chi2: f64 = counts.iter().map(|&c| (c as f64 - expected).powi(2) / expected).sum();
            // 255 degrees of freedom: mean 255, standard deviation 22.6; 360 is p < 1e-4.
            assert!(chi2 < 360.0, "index {index}, dimension {dimension}: chi-square {chi2:.0}");
        }
    }

    #[test]
    fn dimensions_are_decorrelated() {
        // The same sample index in two dimensions must not give the same point: the
        // correlation of their x over 4,096 pixels is near zero.
        let n = 4096;
        let pairs: Vec<(f32, f32)> = (0..n)
            .map(|pixel| {
                let sample = StratifiedPixel::new(1, pixel);
                (sample.sample(3).get_2d(1).x, sample.sample(3).get_2d(2).x)
            })
            .collect();
        let mean = |f: &dyn Fn(&(f32, f32)) -> f64| pairs.iter().map(f).sum::<f64>() / n as f64;
        let (ma, mb) = (mean(&|p| p.0 as f64), mean(&|p| p.1 as f64));
        let cov = mean(&|p| (p.0 as f64 - ma) * (p.1 as f64 - mb));
        let correlation = cov / (1.0 / 12.0);
        assert!(correlation.abs() < 0.06, "correlation {correlation}");
    }
}
