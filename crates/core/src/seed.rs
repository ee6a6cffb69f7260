//! Per-sample seeds: sample `i` of a dataset with seed `s` gets its own 64-bit seed, so any
//! subset of samples can be regenerated independently and bit-identically (docs/design.md §2).

/// SplitMix64 finaliser (Steele, Lea & Flood 2014): a bijective avalanche mix of 64 bits.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of sample `index` in a set generated with `dataset_seed`. Mixing twice keeps
/// neighbouring (seed, index) pairs from producing correlated streams.
pub fn sample_seed(dataset_seed: u64, index: u64) -> u64 {
    mix64(mix64(dataset_seed) ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03))
}

/// A seed for a named purpose within one sample (e.g. "camera", "trace"), so that adding a
/// new consumer of randomness never shifts the streams of the existing ones.
pub fn purpose_seed(sample_seed: u64, purpose: &str) -> u64 {
    // FNV-1a of the purpose name; stable across platforms and Rust versions.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in purpose.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01B3);
    }
    mix64(sample_seed ^ h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_are_deterministic_and_distinct() {
        assert_eq!(sample_seed(7, 3), sample_seed(7, 3));
        let mut seen = std::collections::HashSet::new();
        for s in 0..16 {
            for i in 0..256 {
                assert!(seen.insert(sample_seed(s, i)), "collision at seed {s} index {i}");
            }
        }
        assert_ne!(purpose_seed(1, "camera"), purpose_seed(1, "trace"));
    }
}
