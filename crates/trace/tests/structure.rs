//! The tracer's layout stays readable: its modules import each other without a circle (so
//! each can be read after the ones it uses). How long a function may be is the workspace's
//! rule (`crates/cli/tests/structure.rs`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

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
