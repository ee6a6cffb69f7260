#!/usr/bin/env python3
"""Turns the files of one tools/gpu/run.sh run into the Markdown tables of docs/benchmarks.md.

    python3 tools/gpu/tables.py OUT_DIR > tables.md

The real-time table follows the paper's Table 4: frames per second and milliseconds per frame
for each resolution and transparent-object count, the cost of one more object (a least-squares
slope over the counts), and the GPU and host memory the frame pipeline held. Standard library
only: the GPU machine may have nothing but Python.
"""

import csv
import json
import re
import sys
from pathlib import Path


def read_text(path):
    return path.read_text(errors="replace") if path.is_file() else ""


def stage_seconds(out, name):
    """Wall seconds of a run.sh stage, from the last line of its NAME.txt."""
    match = re.search(r"== exit (\d+), ([0-9.]+) s", read_text(out / f"{name}.txt"))
    if not match:
        return None, None
    return int(match.group(1)), float(match.group(2))


def slope(points):
    """Least-squares slope of (x, y) points; None for fewer than two distinct x."""
    if len({x for x, _ in points}) < 2:
        return None
    n = len(points)
    mx = sum(x for x, _ in points) / n
    my = sum(y for _, y in points) / n
    return sum((x - mx) * (y - my) for x, y in points) / sum((x - mx) ** 2 for x, _ in points)


def peak_gpu_mib(out, name):
    """Largest per-process GPU memory nvidia-smi reported while the bench ran (MiB)."""
    path = out / f"gpu_memory_{name}.csv"
    values = []
    for row in csv.reader(read_text(path).splitlines()):
        if len(row) >= 2:
            try:
                values.append(float(row[1]))
            except ValueError:
                pass
    return max(values) if values else None


def hours(ms_per_step):
    return f"{100_000 * ms_per_step / 3.6e6:.1f}"


def memory(mib):
    return "-" if mib is None else f"{mib:.0f}"


def bench_table(out, name, title):
    path = out / f"bench_{name}.json"
    if not path.is_file():
        return f"### {title}\n\nnot measured (no {path.name}; see bench_{name}.txt)\n"
    report = json.loads(path.read_text())
    rows = report["rows"]
    resolutions = sorted({r["resolution"] for r in rows})
    counts = sorted({r["objects"] for r in rows})
    lines = [f"### {title}", "", f"Device: {report['device']}; {report['frames']} timed frames after {report['warmup']} warm-up frames, medians.", ""]
    lines.append("| size | " + " | ".join(f"t = {t}" for t in counts) + " | one more object | GPU memory (peak) | host memory (peak) |")
    lines.append("|---|" + "---|" * (len(counts) + 3))
    gpu = peak_gpu_mib(out, name)
    for res in resolutions:
        at = {r["objects"]: r for r in rows if r["resolution"] == res}
        cells = []
        for t in counts:
            r = at.get(t)
            cells.append(f"{r['fps']:.1f} FPS / {r['ms_per_frame']:.2f} ms" if r else "-")
        per_object = slope([(t, at[t]["ms_per_frame"]) for t in counts if t in at])
        host = [at[t]["peak_ram_mib"] for t in counts if t in at and at[t].get("peak_ram_mib") is not None]
        reported_gpu = [at[t]["peak_gpu_mib"] for t in counts if t in at and at[t].get("peak_gpu_mib") is not None]
        gpu_cell = f"{max(reported_gpu):.0f} MiB" if reported_gpu else (f"{gpu:.0f} MiB (nvidia-smi, whole run)" if gpu else "-")
        lines.append(
            f"| {res}x{res} | " + " | ".join(cells)
            + f" | {'+%.2f ms' % per_object if per_object is not None else '-'} | {gpu_cell} | {'%.0f MiB' % max(host) if host else '-'} |"
        )
    split = [r for r in rows if r["objects"] == counts[-1]]
    if split:
        lines.append("")
        lines.append(
            f"Raster / through rays / network split at t = {counts[-1]}: "
            + ", ".join(
                f"{r['resolution']}x{r['resolution']} {r['raster_ms']:.2f} / {r.get('through_ms', 0.0):.2f} / {r['network_ms']:.2f} ms" for r in split
            )
            + "."
        )
    return "\n".join(lines) + "\n"


def last_log_row(path):
    """(step, elapsed seconds) of the last row of a train_log.csv; None when there is none."""
    rows = list(csv.DictReader(read_text(path).splitlines()))
    if not rows:
        return None
    return int(rows[-1]["step"]), float(rows[-1]["elapsed_s"])


def training_table(out):
    lines = [
        "### Training steps per second",
        "",
        "`glassbake train --device D --steps N` (batch and crop of the preset; quick: 4 x 32 px crops, 4 objects), also with"
        " `--gpu-convolutions matmul` (im2col and matrix products instead of burn's convolution kernels), and the same `quick`"
        " and `paper` steps in PyTorch on the same GPU (`tools/torch-compare/glassnet_step.py --device cuda`), with `--devices N`"
        " where the machine has several GPUs; GPU memory as nvidia-smi sampled it every 100 ms.",
        "",
        "| network | device | steps | seconds | steps/s | ms/step | 100k steps (h) | GPU memory (MiB, peak) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    runs = []
    for preset in ["quick", "paper"]:
        for device in ["wgpu", "cuda"]:
            suffix = preset if device == "wgpu" else f"{preset}_{device}"
            runs += [(preset, device, suffix), (preset, f"{device}, matmul convolutions", f"{suffix}_matmul")]
    # Data-parallel runs (`--devices N`) where the machine had several GPUs.
    for log in sorted(out.glob("train_log_paper*_x*_few.csv")):
        suffix = log.name[len("train_log_") : -len("_few.csv")]
        device = "cuda" if "_cuda_" in suffix else "wgpu"
        runs.append(("paper", f"{device} x {suffix.rsplit('_x', 1)[1]}", suffix))
    for preset, device, suffix in runs:
        few, many = last_log_row(out / f"train_log_{suffix}_few.csv"), last_log_row(out / f"train_log_{suffix}.csv")
        if few is None or many is None or many[0] <= few[0]:
            if device.startswith("wgpu") or (out / f"train_{suffix}.txt").is_file():
                lines.append(f"| {preset} | burn {device} | - | - | not measured (see train_{suffix}_few.txt, train_{suffix}.txt) | - | - | - |")
            continue
        steps, seconds = many[0] - few[0], many[1] - few[1]
        rate = steps / seconds if seconds > 0 else float("nan")
        lines.append(
            f"| {preset} | burn {device} | {few[0]} -> {many[0]} | {seconds:.1f} | {rate:.2f} | {1000 / rate:.1f}"
            f" | {hours(1000 / rate)} | {memory(peak_gpu_mib(out, f'train_{suffix}'))} |"
        )
    for name, label in [("glassnet", "quick (glassnet)"), ("naive", "quick (naive)"), ("glassnet_paper", "paper (glassnet)")]:
        match = re.search(r"([0-9.]+) ms/step", read_text(out / f"torch_{name}.txt"))
        if match:
            ms = float(match.group(1))
            lines.append(f"| {label} | PyTorch cuda | - | - | {1000 / ms:.2f} | {ms:.1f} | {hours(ms)} | {memory(peak_gpu_mib(out, f'torch_{name}'))} |")
    lines.append("")
    lines.append(
        "burn rows: two runs of the same network, for the first and the second step count; the difference of their times over the"
        " difference of their steps (start-up and the final validation cancel). PyTorch: after three untimed steps; its `paper`"
        " twin at the `paper` batch (8 whole frames). 100k steps: the `paper` preset's length at that step time."
    )
    return "\n".join(lines) + "\n"


def dataset_line(out):
    code, seconds = stage_seconds(out, "dataset")
    text = read_text(out / "dataset.txt")
    frames = re.search(r"--train (\d+) --val (\d+) --test (\d+)", text)
    if code != 0 or seconds is None or not frames:
        return "### Dataset on the GPU\n\nnot measured (see dataset.txt)\n"
    total = sum(int(g) for g in frames.groups())
    return f"### Dataset on the GPU\n\n`glassbake dataset cornellbox --device wgpu`: {total} frames in {seconds:.1f} s, {3600 * total / seconds:.0f} frames/hour (buffers cached, the test split at the training spp).\n"


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: tables.py OUT_DIR")
    out = Path(sys.argv[1])
    parts = ["## GPU figures", "", "```", read_text(out / "machine.txt").strip(), "```", ""]
    trace = read_text(out / "trace_bench.txt")
    table = [line for line in trace.splitlines() if line.startswith("|")]
    parts.append("### Path tracer: GPU against all CPU cores\n")
    parts.append("\n".join(table) + "\n" if table else "not measured (see trace_bench.txt)\n")
    parts.append(dataset_line(out))
    parts.append(training_table(out))
    parts.append(bench_table(out, "quick", "Real-time frame, `quick` GlassNet, zero-copy hand-over"))
    parts.append(bench_table(out, "paper", "Real-time frame, `paper` GlassNet (the paper's widths), zero-copy hand-over"))
    parts.append(bench_table(out, "quick_host_copy", "Real-time frame, `quick` GlassNet, buffers through host memory (`--host-copy`)"))
    parts.append(bench_table(out, "quick_through_cpu", "Real-time frame, `quick` GlassNet, through rays cast on the CPU (`--through-rays cpu`, buffers through host memory)"))
    parts.append(bench_table(out, "quick_sr", "Real-time frame, `quick` GlassNet at half resolution + the x2 super-sampler (`--sr`)"))
    if (out / "bench_quick_cuda.json").is_file():
        parts.append(bench_table(out, "quick_cuda", "Real-time frame, `quick` GlassNet on burn's CUDA backend (buffers through host memory)"))
    print("\n".join(parts))


if __name__ == "__main__":
    main()
