#!/usr/bin/env bash
# Build what the GPU measurement needs and pack it for a GPU machine without a Rust toolchain (tools/gpu/README.md):
# the stripped release binaries, xz-compressed into .gpu/, and the Vulkan loader packages in
# .gl/. Both folders are git-ignored; copy them to the GPU machine with tools/gpu/.
set -euo pipefail
cd "$(dirname "$0")/../.."

# With burn's CUDA backend (`--device cuda`) beside wgpu: cudarc loads the driver's libcuda and
# NVRTC at run time, so no CUDA toolkit is needed here, only the version it should expect
# (CUDARC_CUDA_VERSION, 12080 = CUDA 12.8 by default). The backend's PTX compiler links a
# prebuilt LLVM that a build script downloads from github.com/tracel-ai/tracel-llvm, so this
# needs that site; without it (or with GPU_KIT_CUDA=0) the binary is built without CUDA.
features=()
if [ "${GPU_KIT_CUDA:-1}" = 1 ]; then
  if CUDARC_CUDA_VERSION="${CUDARC_CUDA_VERSION:-12080}" cargo build --release --locked -p glassbake-cli --features cuda; then
    features=(--features cuda)
  else
    echo "pack.sh: the CUDA build failed (above); building glassbake without the cuda feature" >&2
  fi
fi
[ "${#features[@]}" -gt 0 ] || cargo build --release --locked -p glassbake-cli
cargo build --release --locked -p glassbake-trace-gpu --example gpu_trace_bench

exclude="$(git rev-parse --git-path info/exclude)"
mkdir -p "$(dirname "$exclude")"
for dir in .gpu .gl; do
  mkdir -p "$dir"
  grep -qx "/$dir/" "$exclude" 2>/dev/null || echo "/$dir/" >> "$exclude"
done
# The release profile strips symbols; xz because the GPU machine decompresses with Python's lzma.
xz -T0 -6 -c target/release/glassbake > .gpu/glassbake.xz
if [ "${#features[@]}" -gt 0 ]; then echo cuda > .gpu/features.txt; else rm -f .gpu/features.txt; fi
xz -T0 -6 -c target/release/examples/gpu_trace_bench > .gpu/gpu_trace_bench.xz

# The Vulkan loader (the NVIDIA driver's ICD is on the GPU machine, the loader may not be), amd64
# packages whatever this machine's architecture.
if ! ls .gl/libvulkan1_*.deb >/dev/null 2>&1; then
  mkdir -p /tmp/amd64/partial
  o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
  # shellcheck disable=SC2086
  apt-get $o update -qq
  # shellcheck disable=SC2086
  (cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
fi
du -ch .gpu/* .gl/* | tail -1
