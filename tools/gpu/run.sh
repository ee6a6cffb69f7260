#!/usr/bin/env bash
# glassbake's GPU figures in one run (tools/gpu/README.md): the GPU tracer against the CPU's,
# a dataset traced on the GPU, training steps per second for the `quick` and `paper` networks,
# the real-time frame (Table 4 of the paper: FPS per resolution and transparent-object count,
# with the zero-copy hand-over and through host memory, with the x2 super-sampler) and the GPU
# memory it holds. Each result is a file under $OUT; tools/gpu/tables.py turns them into the
# tables of docs/benchmarks.md.
#
# On the GPU machine, from the folder holding tools/gpu, .gpu and .gl:
#   bash tools/gpu/run.sh            # the full run (not yet timed on a GPU; larger than --short)
#   bash tools/gpu/run.sh --smoke    # every stage at toy sizes (a minute or two; checks the kit)
#   bash tools/gpu/run.sh --short    # every stage at reduced sizes, 5 minutes on an H200 (2026-11-26)
# GPU_KIT_MODELS=DIR takes ready-made cornellbox models from DIR/quick, DIR/paper and DIR/sr
# (trained anywhere: frame times depend on a network's size, not on how well it learned) and
# runs the real-time benches first; without it they are trained here after the dataset stage.
# GPU_KIT_STAGE_TIMEOUT=S stops any one stage after S seconds (default 900); GPU_KIT_SKIP="NAME ..."
# skips the stages of those names (trace_bench, dataset, train_quick, bench_paper, ...).
# GLASSBAKE_BIN_DIR=DIR takes the binaries from DIR instead of .gpu/*.xz (a build machine's
# target/release, say; GPU_KIT_CUDA=1 when that glassbake was built with the `cuda` feature);
# without .gl/ the system's Vulkan loader is used.
set -uo pipefail

smoke=0 short=0
[ "${1:-}" = "--smoke" ] && smoke=1
[ "${1:-}" = "--short" ] && short=1
out="${OUT:-gpu-out}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
work="${GPU_KIT_WORK:-/tmp/glassbake-gpu-kit}"
rm -rf "$work"
mkdir -p "$work"

if [ "$smoke" = 1 ]; then
  trace_res=32 trace_spp=16 data_res=32 data_spp=4 frames=4 steps_few=1 steps=3 paper_steps_few=1 paper_steps=2 bench_res=32,64 objects=1,2 bench_frames=2 warmup=1
elif [ "$short" = 1 ]; then
  trace_res=256 trace_spp=128 data_res=256 data_spp=128 frames=8 steps_few=50 steps=250 paper_steps_few=5 paper_steps=25 bench_res=256,512 objects=1,2,4,8 bench_frames=30 warmup=5
else
  trace_res=256 trace_spp=1024 data_res=256 data_spp=256 frames=32 steps_few=100 steps=600 paper_steps_few=20 paper_steps=120 bench_res=256,512 objects=1,2,4,8 bench_frames=50 warmup=5
fi

# The Vulkan loader packed by pack.sh (the NVIDIA driver's ICD is on the GPU machine).
if ls .gl/*.deb >/dev/null 2>&1; then
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
fi
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -f "$icd" ] && [ -z "${VK_DRIVER_FILES:-}" ]; then export VK_DRIVER_FILES="$icd"; fi

# NVRTC for the CUDA backend: the one pack.sh packed (GPU_KIT_NVRTC=1), else the one PyTorch's
# wheels installed.
nvrtc_dir=""
if ls .gpu/nvrtc/libnvrtc*.xz >/dev/null 2>&1; then
  nvrtc_dir="$work/nvrtc"
  mkdir -p "$nvrtc_dir"
  for f in .gpu/nvrtc/*.xz; do
    python3 -c "import lzma, shutil, sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], 'wb'))" "$f" "$nvrtc_dir/$(basename "$f" .xz)"
  done
else
  nvrtc_dir=$(python3 -c "import nvidia.cuda_nvrtc, os; print(os.path.join(list(nvidia.cuda_nvrtc.__path__)[0], 'lib'))" 2>/dev/null || true)
fi
[ -z "$nvrtc_dir" ] || export LD_LIBRARY_PATH="$nvrtc_dir${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"

bin="${GLASSBAKE_BIN_DIR:-}"
if [ -z "$bin" ]; then
  bin="$work/bin"
  mkdir -p "$bin"
  for name in glassbake gpu_trace_bench; do
    [ -f ".gpu/$name.xz" ] || continue
    python3 -c "import lzma, shutil, sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], 'wb'))" ".gpu/$name.xz" "$bin/$name"
    chmod +x "$bin/$name"
  done
fi
glassbake="$bin/glassbake"
[ -x "$glassbake" ] || { echo "no glassbake binary in $bin (run tools/gpu/pack.sh on the build machine)" >&2; exit 1; }
failed=()
stage() { # stage NAME COMMAND...: runs a command, its output into $out/NAME.txt, its exit status noted
  local name="$1"; shift
  if [[ " ${GPU_KIT_SKIP:-} " == *" $name "* ]]; then echo "== $name: skipped (GPU_KIT_SKIP)"; return; fi
  echo "== $name: $*" | tee "$out/$name.txt"
  local start end
  start=$(date +%s.%N)
  timeout "${GPU_KIT_STAGE_TIMEOUT:-900}" "$@" >> "$out/$name.txt" 2>&1
  local code=$?
  end=$(date +%s.%N)
  echo "== exit $code, $(python3 -c "print(round($end - $start, 2))") s" >> "$out/$name.txt"
  tail -n 3 "$out/$name.txt"
  [ "$code" = 0 ] || failed+=("$name")
}

{
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>/dev/null || echo "nvidia-smi: not found (no NVIDIA driver)"
  echo "cpu cores: $(nproc)"
  grep -m1 "model name" /proc/cpuinfo || true
  echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
  "$glassbake" --version 2>/dev/null || true
  echo "smoke: $smoke, short: $short"
} > "$out/machine.txt"

# The real-time frame, the paper's Table 4: zero-copy, through host memory, the `paper` widths,
# with the super-sampler; GPU memory sampled by nvidia-smi every 100 ms while each runs.
models="${GPU_KIT_MODELS:-}"
[ -z "$models" ] || models="$(cd "$models" && pwd)"
sampler=""
memory_start() { # memory_start NAME: nvidia-smi samples the GPU memory into $out/gpu_memory_NAME.csv until memory_stop
  if command -v nvidia-smi >/dev/null; then
    nvidia-smi --query-compute-apps=pid,used_memory --format=csv,noheader,nounits -lms 100 > "$out/gpu_memory_$1.csv" 2>/dev/null &
    sampler=$!
  fi
}
memory_stop() { [ -z "$sampler" ] || kill "$sampler" 2>/dev/null; sampler=""; }
bench() { # bench NAME MODEL_DIR DEVICE EXTRA...
  local name="$1" model="$2" device="$3"; shift 3
  local scene=()
  [ -z "$models" ] || scene=(--scene cornellbox)
  memory_start "$name"
  stage "bench_$name" "$glassbake" bench "$model" "${scene[@]}" --device "$device" --res "$bench_res" --objects "$objects" \
    --frames "$bench_frames" --warmup "$warmup" --out "$out/bench_$name.json" "$@"
  memory_stop
}
devices=(wgpu)
if grep -qx cuda .gpu/features.txt 2>/dev/null || [ "${GPU_KIT_CUDA:-0}" = 1 ]; then
  devices+=(cuda)
fi
benches() { # benches DIR: DIR/quick, DIR/paper and DIR/sr hold the models
  local dir="$1"
  bench quick "$dir/quick" wgpu
  bench quick_host_copy "$dir/quick" wgpu --host-copy
  # A GlassNet reading through buffers: their rays on the CPU instead of the GPU pass.
  bench quick_through_cpu "$dir/quick" wgpu --through-rays cpu
  bench paper "$dir/paper" wgpu
  bench quick_sr "$dir/quick" wgpu --sr "$dir/sr"
  # The CUDA backend: buffers reach it through host memory.
  [[ " ${devices[*]} " != *" cuda "* ]] || bench quick_cuda "$dir/quick" cuda
}
[ -z "$models" ] || benches "$models"

# A dataset path-traced on the GPU (frames per hour), one validation frame so that the
# training runs below spend their time on steps.
stage dataset "$glassbake" dataset cornellbox --device wgpu --out "$work/dataset" --train "$frames" --val 1 --test 2 \
  --res "$data_res" --spp "$data_spp" --test-spp "$data_spp" --cache-buffers

# Training steps per second, the `quick` and `paper` networks (train_log.csv: elapsed_s per
# step), on wgpu and, where the binary was built with the `cuda` feature, on burn's CUDA
# backend; the same `quick` step in PyTorch on the same GPU where PyTorch is installed.
# Each network trains twice, for a few steps and for more: the difference of the two runs' times
# is the steady-state step, start-up (shader compilation, autotuning) and the final validation
# cancelling out.
train_pair() { # train_pair SUFFIX PRESET DEVICE EXTRA...: the few-step and the many-step run
  local suffix="$1" preset="$2" device="$3" few=$steps_few many=$steps; shift 3
  [ "$preset" != paper ] || { few=$paper_steps_few; many=$paper_steps; }
  stage "train_${suffix}_few" "$glassbake" train "$work/dataset" --model glassnet --preset "$preset" --device "$device" --steps "$few" --out "$work/${suffix}_few" "$@"
  cp "$work/${suffix}_few/train_log.csv" "$out/train_log_${suffix}_few.csv" 2>/dev/null
  memory_start "train_$suffix"
  stage "train_$suffix" "$glassbake" train "$work/dataset" --model glassnet --preset "$preset" --device "$device" --steps "$many" --out "$work/$suffix" "$@"
  memory_stop
  cp "$work/$suffix/train_log.csv" "$out/train_log_$suffix.csv" 2>/dev/null
}
# Each also with the convolutions as matrix products (`--gpu-convolutions matmul`), which
# decides the default.
for device in "${devices[@]}"; do
  for preset in quick paper; do
    suffix="$preset"; [ "$device" = wgpu ] || suffix="${preset}_$device"
    train_pair "$suffix" "$preset" "$device"
    train_pair "${suffix}_matmul" "$preset" "$device" --gpu-convolutions matmul
  done
done
# Data parallelism on a machine with several GPUs: the `paper` batch shared by all of them.
gpus=$(nvidia-smi -L 2>/dev/null | grep -c '^GPU' || true)
if [ "${gpus:-0}" -ge 2 ]; then
  for device in "${devices[@]}"; do
    suffix="paper_x$gpus"; [ "$device" = wgpu ] || suffix="paper_${device}_x$gpus"
    train_pair "$suffix" paper "$device" --devices "$gpus"
  done
fi
if python3 -c "import torch; assert torch.cuda.is_available()" 2>/dev/null; then
  for model in glassnet naive; do
    memory_start "torch_$model"
    stage "torch_$model" python3 "$(dirname "$0")/../torch-compare/glassnet_step.py" --model "$model" --device cuda --steps "$steps"
    memory_stop
  done
  # The `paper` network at its batch: 8 whole frames of the dataset's size.
  memory_start torch_glassnet_paper
  stage torch_glassnet_paper python3 "$(dirname "$0")/../torch-compare/glassnet_step.py" --model glassnet --preset paper \
    --batch 8 --crop "$data_res" --device cuda --steps "$paper_steps"
  memory_stop
fi
stage train_sr "$glassbake" train-sr "$work/dataset" --glassnet "$work/quick" --preset quick --device wgpu --steps "$steps" --out "$work/sr"
[ -n "$models" ] || benches "$work"

# Both tracers' samples per second on the built-in scenes (the CPU on all of this machine's cores).
if [ -x "$bin/gpu_trace_bench" ]; then
  stage trace_bench "$bin/gpu_trace_bench" --res "$trace_res" --spp "$trace_spp"
fi

python3 "$(dirname "$0")/tables.py" "$out" > "$out/tables.md" || failed+=(tables)
cat "$out/tables.md"
if [ "${#failed[@]}" -gt 0 ]; then
  echo "failed stages: ${failed[*]} (their output is in $out/NAME.txt)" >&2
  exit 1
fi
