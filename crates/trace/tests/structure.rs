//! The tracer's layout stays readable: its modules import each other without a circle (so
//! each can be read after the ones it uses), and no function on the hot path of an image
//! (the image driver, the path integrator, the caustic estimator's modules) outgrows a page.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Longest function allowed in the hot-path modules, in lines from signature to closing brace.
const MAX_FUNCTION_LINES: usize = 120;
const HOT_PATH: [&str; 7] =
    ["render/mod.rs", "render/light_passes.rs", "integrator.rs", "caustic_paths.rs", "photon_merging.rs", "light_tracing.rs", "prepared.rs"];

/// Each module of `src/` and the modules it names as `crate::module`, tests included.
fn module_imports() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut modules = BTreeMap::new();
    for entry in std::fs::read_dir(&src).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        if path.extension().is_none_or(|e| e != "rs") || name == "lib" {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let imports = text
            .match_indices("crate::")
            .map(|(i, _)| text[i + 7..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect::<String>())
            .filter(|module| !module.is_empty() && *module != name)
            .collect();
        modules.insert(name, imports);
    }
    modules
}

#[test]
fn modules_import_each_other_without_a_circle() {
    let modules = module_imports();
    assert!(modules.len() > 15 && modules.contains_key("integrator"), "read {} modules", modules.len());
    // Depth-first search for a back edge, reporting the circle it closes.
    fn visit(module: &str, modules: &BTreeMap<String, BTreeSet<String>>, path: &mut Vec<String>, done: &mut BTreeSet<String>) {
        if let Some(start) = path.iter().position(|m| m == module) {
            panic!("module circle: {} -> {module}", path[start..].join(" -> "));
        }
        if done.contains(module) {
            return;
        }
        path.push(module.to_string());
        for next in modules.get(module).into_iter().flatten() {
            if modules.contains_key(next) {
                visit(next, modules, path, done);
            }
        }
        path.pop();
        done.insert(module.to_string());
    }
    let mut done = BTreeSet::new();
    for module in modules.keys() {
        visit(module, &modules, &mut Vec::new(), &mut done);
    }
}

#[test]
fn hot_path_functions_fit_on_a_page() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut measured = 0;
    for file in HOT_PATH {
        let lines: Vec<String> = std::fs::read_to_string(src.join(file)).unwrap().lines().map(String::from).collect();
        for (start, line) in lines.iter().enumerate() {
            let trimmed = line.trim_start();
            let is_fn = ["fn ", "pub fn ", "pub(crate) fn "].iter().any(|p| trimmed.starts_with(p));
            if !is_fn {
                continue;
            }
            let indent = &line[..line.len() - trimmed.len()];
            // rustfmt closes a function at its signature's indentation.
            let Some(length) = lines[start + 1..].iter().position(|l| *l == format!("{indent}}}")) else { continue };
            measured += 1;
            assert!(length + 2 <= MAX_FUNCTION_LINES, "{file}: {} is {} lines long", trimmed.split('(').next().unwrap(), length + 2);
        }
    }
    assert!(measured > 40, "only {measured} functions measured");
}
