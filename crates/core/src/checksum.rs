//! SHA-256 checksums of the files glassbake writes and reads back later (dataset frames,
//! training checkpoints), in the format of `sha256sum`, so a damaged file is named instead of
//! silently used.

use sha2::{Digest, Sha256};

/// Lower-case hex SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// One `sha256sum` line: the digest, two spaces, the file's name.
pub fn sha256sum_line(bytes: &[u8], name: &str) -> String {
    format!("{}  {name}\n", sha256_hex(bytes))
}

/// The (digest, name) pairs of `sha256sum` output; lines that are not one are skipped.
pub fn parse_sha256sum(text: &str) -> Vec<(String, String)> {
    text.lines()
        .filter_map(|line| {
            let (digest, name) = line.split_once("  ")?;
            (digest.len() == 64 && digest.bytes().all(|b| b.is_ascii_hexdigit())).then(|| (digest.to_ascii_lowercase(), name.to_string()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digests_match_the_published_test_vectors() {
        // FIPS 180-2, appendix B.1, and the empty message.
        assert_eq!(sha256_hex(b"abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
        assert_eq!(sha256_hex(b""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    }

    #[test]
    fn lines_round_trip_and_foreign_lines_are_skipped() {
        let text = format!("{}{}garbage\n", sha256sum_line(b"abc", "a.exr"), sha256sum_line(b"", "b.bpk"));
        let parsed = parse_sha256sum(&text);
        assert_eq!(parsed, vec![(sha256_hex(b"abc"), "a.exr".to_string()), (sha256_hex(b""), "b.bpk".to_string())]);
    }
}
