#!/usr/bin/env bash
# Builds the web page's module: crates/web for wasm32 and its JavaScript glue (wasm-bindgen),
# into target/web-module/, where `glassbake export-web` finds it (docs/web.md). Installs the wasm32
# target and the wasm-bindgen CLI of the version Cargo.lock pins, if missing.
#   bash tools/web/build.sh            # the `web` profile: release code, function names kept
#   GLASSBAKE_WEB_PROFILE=web-ci bash tools/web/build.sh   # the same at opt-level 1 (CI's test)
set -euo pipefail
cd "$(dirname "$0")/../.."
out="${GLASSBAKE_WEB_MODULE:-target/web-module}"
profile="${GLASSBAKE_WEB_PROFILE:-web}"

if ! rustup target list --installed | grep -qx wasm32-unknown-unknown; then
  rustup target add wasm32-unknown-unknown
fi
# The CLI must be the wasm-bindgen crate's own version: the two speak one format.
version=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
if [ "$(wasm-bindgen --version 2>/dev/null | awk '{print $2}')" != "$version" ]; then
  # Not --locked: the CLI's own lock file names a webpki-roots release the registry no longer
  # serves; its dependencies resolve afresh within their semver ranges.
  cargo install wasm-bindgen-cli --version "=$version"
fi

cargo build --locked --profile "$profile" --target wasm32-unknown-unknown -p glassbake-web
wasm-bindgen --target web --no-typescript --out-dir "$out" "target/wasm32-unknown-unknown/$profile/glassbake_web.wasm"
ls -l "$out"
