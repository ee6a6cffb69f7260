//! Peak resident memory of this process, per measurement: Linux keeps a high-water mark
//! (`VmHWM` in /proc/self/status) that writing "5" to /proc/self/clear_refs resets.

/// Resets the peak-RSS mark; false where the kernel does not offer it.
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

fn status_kib(field: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    line[field.len()..].trim().trim_end_matches("kB").trim().parse::<f64>().ok()
}

/// Peak resident memory since the last reset, MiB.
pub fn peak_rss_mib() -> Option<f64> {
    status_kib("VmHWM:").map(|kib| kib / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_rss_follows_a_large_allocation_and_resets() {
        if !reset_peak_rss() {
            eprintln!("no /proc/self/clear_refs here; nothing to test");
            return;
        }
        let before = peak_rss_mib().unwrap();
        let block = vec![1u8; 256 << 20];
        std::hint::black_box(&block);
        let during = peak_rss_mib().unwrap();
        assert!(during - before > 200.0, "{before} -> {during} MiB");
        drop(block);
        assert!(reset_peak_rss());
        let after = peak_rss_mib().unwrap();
        assert!(during - after > 200.0, "the reset forgets the freed block: {during} -> {after}");
    }
}
