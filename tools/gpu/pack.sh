#!/usr/bin/env bash
# Build what the GPU measurement needs and pack it for a GPU machine without a Rust toolchain (tools/gpu/README.md):
# the stripped release binaries, xz-compressed into .gpu/, and the Vulkan loader packages in
# .gl/. Both folders are git-ignored; copy them to the GPU machine with tools/gpu/.
set -euo pipefail
cd "$(dirname "$0")/../.."

# With burn's CUDA backend (`--device cuda`) beside wgpu, built offline by tools/cuda/cargo-cuda.sh
# (cubecl-cuda without its LLVM backend: kernels go through NVRTC). cudarc loads the driver's
# libcuda and NVRTC at run time, so no CUDA toolkit is needed here, only the version it should
# expect (CUDARC_CUDA_VERSION, 12080 = CUDA 12.8 by default); NVRTC itself is packed from PyPI's
# nvidia-cuda-nvrtc-cu12 wheel below, where this machine reaches PyPI. GPU_KIT_CUDA=0 builds
# glassbake without CUDA.
features=()
if [ "${GPU_KIT_CUDA:-1}" = 1 ]; then
  if bash tools/cuda/cargo-cuda.sh build --release -p glassbake-cli; then
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

# NVRTC for the CUDA backend, with GPU_KIT_NVRTC=1: 31 MB xz-compressed, so only for a GPU machine
# without PyTorch (run.sh finds the NVRTC PyTorch's wheels install). From PyPI's
# nvidia-cuda-nvrtc-cu12 wheel of CUDARC_CUDA_VERSION's major.minor.
if [ "${#features[@]}" -gt 0 ] && [ "${GPU_KIT_NVRTC:-0}" = 1 ] && ! ls .gpu/nvrtc/libnvrtc.so*.xz >/dev/null 2>&1; then
  cuda="${CUDARC_CUDA_VERSION:-12080}"
  wheel_dir=$(mktemp -d)
  python3 -m pip download -q --no-deps --only-binary=:all: --platform manylinux2014_x86_64 -d "$wheel_dir" \
    "nvidia-cuda-nvrtc-cu12==$((cuda / 1000)).$((cuda % 1000 / 10)).*"
  mkdir -p .gpu/nvrtc
  python3 - "$wheel_dir"/*.whl .gpu/nvrtc <<'PY'
import lzma, sys, zipfile
wheel = zipfile.ZipFile(sys.argv[1])
for name in wheel.namelist():
    file = name.rsplit("/", 1)[1]
    if "/lib/libnvrtc" in name and ".alt." not in file:
        with lzma.open(f"{sys.argv[2]}/{file}.xz", "wb", preset=6) as out:
            out.write(wheel.read(name))
PY
  rm -rf "$wheel_dir"
fi

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
