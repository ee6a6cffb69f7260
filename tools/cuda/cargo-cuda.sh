#!/usr/bin/env bash
# Runs cargo with burn's CUDA backend (glassbake-net's `cuda` feature, `--device cuda`) built
# offline. cubecl-cuda, as published, always builds its LLVM backend, whose build script
# downloads a prebuilt LLVM; cubecl-cuda-nvrtc.patch makes that backend an optional feature
# (`llvm`, off), so the CUDA C++ backend compiles the kernels: NVRTC at run time, loaded with
# the driver's libcuda by cudarc. No CUDA toolkit is needed to build, only the CUDA version to
# expect (CUDARC_CUDA_VERSION, default 12080 = CUDA 12.8).
#
#   tools/cuda/cargo-cuda.sh check -p glassbake-cli
#   tools/cuda/cargo-cuda.sh build --release -p glassbake-cli
#   tools/cuda/cargo-cuda.sh clippy -p glassbake-cli -- -D warnings
#
# The registry's cubecl-cuda (the version Cargo.lock pins) is copied to target/cubecl-cuda-nvrtc
# and patched there; cargo sees it through `--config patch.crates-io`, which changes Cargo.lock,
# so Cargo.lock is put back as it was when cargo ends.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
version=$(awk '$0 == "name = \"cubecl-cuda\"" { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
[ -n "$version" ] || { echo "cargo-cuda.sh: Cargo.lock pins no cubecl-cuda" >&2; exit 2; }
cargo fetch --locked --target "$(rustc -vV | sed -n 's/^host: //p')" >/dev/null
src=$(ls -d "${CARGO_HOME:-$HOME/.cargo}"/registry/src/*/"cubecl-cuda-$version" 2>/dev/null | head -1)
[ -n "$src" ] || { echo "cargo-cuda.sh: cubecl-cuda $version is not in the cargo registry after cargo fetch" >&2; exit 2; }
dest=target/cubecl-cuda-nvrtc
rm -rf "$dest"
mkdir -p target
cp -r "$src" "$dest"
chmod -R u+w "$dest"
# Outside any repository (git apply in a subfolder of one skips the paths outside it, silently).
GIT_CEILING_DIRECTORIES="$root/target" git -C "$dest" apply "$root/tools/cuda/cubecl-cuda-nvrtc.patch"
grep -q '^llvm = \["dep:cubecl-llvm"\]' "$dest/Cargo.toml" || { echo "cargo-cuda.sh: the patch did not apply to $dest" >&2; exit 2; }
cp Cargo.lock target/Cargo.lock.before-cuda
trap 'cp target/Cargo.lock.before-cuda Cargo.lock' EXIT
CUDARC_CUDA_VERSION="${CUDARC_CUDA_VERSION:-12080}" \
  cargo "$1" --config "patch.crates-io.cubecl-cuda.path=\"$root/$dest\"" --features glassbake-net/cuda "${@:2}"
