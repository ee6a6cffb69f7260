#!/usr/bin/env bash
# The GPU tracer's figures in one run (tools/gpu/README.md). Run on the GPU machine from the folder
# holding tools/gpu, .gpu and .gl; results go to $OUT (or ./gpu-out).
#   bash tools/gpu/run.sh [RES] [SPP]
set -uo pipefail
res="${1:-256}"
spp="${2:-1024}"
out="${OUT:-gpu-out}"
mkdir -p "$out"

for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -f "$icd" ] && [ -z "${VK_DRIVER_FILES:-}" ]; then export VK_DRIVER_FILES="$icd"; fi

bin=/tmp/glassbake-gpu
mkdir -p "$bin"
for name in glassbake gpu_trace_bench; do
  python3 -c "import lzma, shutil, sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], 'wb'))" ".gpu/$name.xz" "$bin/$name"
  chmod +x "$bin/$name"
done

{ nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv; nproc; date -u; } > "$out/machine.txt" 2>&1

# Throughput of both tracers on the built-in scenes (the CPU column uses this machine's cores).
"$bin/gpu_trace_bench" --res "$res" --spp "$spp" 2>&1 | tee "$out/trace_bench.md"

# A dataset on the GPU: frames per hour at the paper's resolution (made afresh each run).
rm -rf /tmp/gb-dataset
"$bin/glassbake" dataset cornellbox --device wgpu --out /tmp/gb-dataset --train 16 --val 0 --test 0 \
  --res "$res" --spp "$spp" --cache-buffers 2>&1 | tee "$out/dataset.txt"
"$bin/glassbake" trace cornellbox --sample 0 --device wgpu --res "$res" --spp "$spp" --out "$out/cornellbox_gpu.exr" 2>&1 | tee -a "$out/dataset.txt"
