//! The workspace stays readable: no function in any crate's sources outgrows a page, no source
//! file outgrows a sitting, the binary stays a thin shell over the libraries, and a preset is
//! chosen by its name in one place only.

use std::path::{Path, PathBuf};

mod common;

/// Longest function allowed, in lines from signature to closing brace.
const MAX_FUNCTION_LINES: usize = 120;
const MAX_FILE_LINES: usize = 700;
/// The `glassbake` binary's sources, all files together.
const MAX_CLI_LINES: usize = 1200;

fn crates_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

/// Every `.rs` file under `dir`, recursively.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    common::files_under(dir).into_iter().filter(|p| p.extension().is_some_and(|e| e == "rs")).collect()
}

/// The `src/` files of every crate.
fn sources() -> Vec<PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(crates_dir()).unwrap() {
        let src = entry.unwrap().path().join("src");
        if src.is_dir() {
            files.extend(rust_files(&src));
        }
    }
    files
}

/// (name, lines) of each function in `text`: rustfmt closes a function at its signature's
/// indentation.
fn functions(text: &str) -> Vec<(String, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut found = Vec::new();
    for (start, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let signature = ["fn ", "pub fn ", "pub(crate) fn ", "pub(super) fn "].iter().any(|p| trimmed.starts_with(p));
        if !signature || trimmed.ends_with(';') {
            continue;
        }
        let close = format!("{}}}", &line[..line.len() - trimmed.len()]);
        if let Some(length) = lines[start + 1..].iter().position(|l| *l == close) {
            found.push((trimmed.split('(').next().unwrap().to_string(), length + 2));
        }
    }
    found
}

#[test]
fn functions_fit_on_a_page_and_files_in_a_sitting() {
    let files = sources();
    assert!(files.len() > 100, "read {} files", files.len());
    let mut measured = 0;
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        let lines = text.lines().count();
        assert!(lines <= MAX_FILE_LINES, "{} is {lines} lines long", file.display());
        for (name, length) in functions(&text) {
            measured += 1;
            assert!(length <= MAX_FUNCTION_LINES, "{}: {name} is {length} lines long", file.display());
        }
    }
    assert!(measured > 1000, "only {measured} functions measured");
}

#[test]
fn the_binary_is_a_thin_shell() {
    let lines: usize = rust_files(&crates_dir().join("cli").join("src")).iter().map(|f| std::fs::read_to_string(f).unwrap().lines().count()).sum();
    assert!(lines <= MAX_CLI_LINES, "crates/cli/src is {lines} lines");
}

#[test]
fn a_preset_is_named_in_its_definition_only() {
    let definition = crates_dir().join("bake").join("src").join("preset.rs");
    for file in sources().into_iter().filter(|f| *f != definition) {
        let text = std::fs::read_to_string(&file).unwrap();
        // Unit tests inside a source file may name a preset.
        let code = text.split("#[cfg(test)]").next().unwrap();
        for name in ["\"tiny\"", "\"quick\"", "\"paper\""] {
            assert!(!code.contains(name), "{} names the preset {name}", file.display());
        }
    }
}

#[test]
fn the_measure_finds_long_functions() {
    let body = "    let x = 1;\n".repeat(MAX_FUNCTION_LINES);
    let text = format!("pub fn long() {{\n{body}}}\n\nfn short() {{\n}}\n");
    assert_eq!(functions(&text), [("pub fn long".to_string(), MAX_FUNCTION_LINES + 2), ("fn short".to_string(), 2)]);
}
