#!/bin/sh
# glassbake's CPU training step (burn, flex) and the same network's in PyTorch, back to back on
# this machine, with the ratios: the step, and the forward pass without gradients.
#
#     sh tools/torch-compare/compare.sh [batch crop objects]     # PYTHON=... for torch's python
set -eu
cd "$(dirname "$0")/../.."
python=${PYTHON:-python3}
batch=${1:-4} crop=${2:-32} objects=${3:-4}
burn=$(cargo run -q --release -p glassbake-bake --example train_step -- "$batch" "$crop" "$objects")
echo "$burn"
for model in glassnet naive; do
    torch=$("$python" tools/torch-compare/glassnet_step.py --model "$model" --batch "$batch" --crop "$crop" --objects "$objects")
    echo "$torch"
    # The example prints "<model> ... step X ms ..." and, two lines on, "... whole Y ms".
    burn_step=$(echo "$burn" | awk -v m="$model" '$1 == m { for (i = 1; i < NF; i++) if ($i == "step") { print $(i + 1); exit } }')
    burn_forward=$(echo "$burn" | awk -v m="$model" '$1 == m { found = 1 } found && /no-grad forward/ { for (i = 1; i < NF; i++) if ($i == "whole") { print $(i + 1); exit } }')
    torch_step=$(echo "$torch" | sed -n 's/.*: \([0-9.]*\) ms\/step.*/\1/p')
    torch_forward=$(echo "$torch" | sed -n 's/.*no-grad forward \([0-9.]*\) ms.*/\1/p')
    awk -v m="$model" -v bs="$burn_step" -v ts="$torch_step" -v bf="$burn_forward" -v tf="$torch_forward" 'BEGIN {
        printf "%s burn / PyTorch: step %.1f / %.1f ms = %.2fx, no-grad forward %.1f / %.1f ms = %.2fx\n", m, bs, ts, bs / ts, bf, tf, bf / tf }'
done
