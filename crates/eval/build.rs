//! With the `oidn` feature and OIDN_DIR set (docs/eval.md), the binaries and tests find
//! libOpenImageDenoise where they were linked against it, without LD_LIBRARY_PATH. The CLI
//! crate uses this same script (its Cargo.toml `build`).

fn main() {
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    if std::env::var_os("CARGO_FEATURE_OIDN").is_none() {
        return;
    }
    if let Some(dir) = std::env::var_os("OIDN_DIR").filter(|d| !d.is_empty()) {
        let lib = std::path::Path::new(&dir).join("lib");
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
    }
}
