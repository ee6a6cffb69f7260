"""Where a model's whole-image error sits: the one-pixel ring around directly seen lights.

    pip install mitsuba numpy          # mitsuba only to read multi-layer EXR files
    python3 tools/emitter-edges/analyze.py --glassbake target/release/glassbake \
        --dataset bake/dataset --eval bake/eval [--recomposite --factor 4]

A frame's ground truth is box-filtered over each pixel (the path tracer jitters its camera
rays across the pixel) while the G-buffer samples the pixel's centre once. A light is far
brighter than 1, so every pixel that a light covers even a few percent of is white in the
clamped ground truth, yet the G-buffer says nothing about the light there unless the centre
is on it. This script measures how much of each model's squared error (clamped linear RGB,
as eval's PSNR) lies in the rings around the pixels whose G-buffer L_d is at least 1 in every
channel (a light seen directly). With --recomposite, also what a model's PSNR would be if each
pixel's light coverage were known: the frame's buffers are rasterized again at --factor times
the resolution (`glassbake buffers`), and each prediction p becomes min(1, E + (1 - c) p), with
c the fraction of the pixel's sub-samples that see a light and E their mean L_d over the pixel
(for models that do not composite the coverage themselves; glassbake's do).

The ring's error is split by what the ground truth holds there: white (a light covers enough of
the pixel to clamp it), dark (no light in the pixel: a model brighter there draws a halo), and
in between (a sliver of light too thin to clamp the pixel, finer than the coverage grid can
say). The last two columns are the models' mean there against the truth's.

Reads eval's frames/NNNNNN_{ground_truth,MODEL}.png (8-bit sRGB, decoded to linear) and the
dataset's cached buffers; prints a Markdown table. PSNRs are per frame, then averaged over the
frames, as eval's are; the ring's share is of the squared error summed over all frames.
"""
import argparse
import glob
import json
import os
import subprocess
import tempfile

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def linear_png(path):
    a = np.array(mi.Bitmap(path)).astype(np.float64) / 255.0
    return np.where(a <= 0.04045, a / 12.92, ((a + 0.055) / 1.055) ** 2.4)


def opaque_ld(exr):
    bitmap = mi.Bitmap(exr)
    names = [bitmap.struct_()[i].name for i in range(bitmap.channel_count())]
    a = np.array(bitmap).astype(np.float64)
    return np.stack([a[..., names.index(f"opaque.Ld.{c}")] for c in "RGB"], -1)


def dilate(mask):
    out = mask.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted = np.zeros_like(mask)
            ys = slice(max(dy, 0), mask.shape[0] + min(dy, 0))
            yd = slice(max(-dy, 0), mask.shape[0] + min(-dy, 0))
            xs = slice(max(dx, 0), mask.shape[1] + min(dx, 0))
            xd = slice(max(-dx, 0), mask.shape[1] + min(-dx, 0))
            shifted[yd, xd] = mask[ys, xs]
            out |= shifted
    return out


def psnr(squared_error_sum, pixels):
    # eval's floor on the mean squared error (metrics::psnr_from_mse).
    return 10.0 * np.log10(1.0 / max(squared_error_sum / pixels, 1e-10))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--glassbake", required=True)
    parser.add_argument("--dataset", required=True)
    parser.add_argument("--eval", required=True)
    parser.add_argument("--factor", type=int, default=4)
    parser.add_argument("--recomposite", action="store_true")
    args = parser.parse_args()
    manifest = json.load(open(os.path.join(args.dataset, "manifest.json")))
    spec = manifest["spec"]
    res, factor = spec["resolution"], args.factor
    truths = sorted(glob.glob(os.path.join(args.eval, "frames", "*_ground_truth.png")))
    models = sorted({os.path.basename(p)[7:-4] for p in glob.glob(os.path.join(args.eval, "frames", "*.png"))} - {"ground_truth"})
    totals = {m: {"all": 0.0, "ring": 0.0, "psnr": [], "outside": [], "composite": [], "white": 0.0, "dark": 0.0, "between": 0.0, "dark_mean": [], "between_mean": []} for m in models}
    pixels = ring_pixels = 0
    truth_dark, truth_between = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for truth_path in truths:
            index = int(os.path.basename(truth_path)[:6])
            truth = linear_png(truth_path)
            seen_light = opaque_ld(os.path.join(args.dataset, "buffers", f"{index:06}.exr")).min(-1) >= 1.0
            ring = dilate(seen_light) & ~seen_light
            white = ring & (truth.min(-1) >= 0.99)
            dark = ring & (truth.max(-1) < 0.5)
            between = ring & ~white & ~dark
            truth_dark.extend(truth[dark].mean(-1))
            truth_between.extend(truth[between].mean(-1))
            if args.recomposite:
                fine_exr = os.path.join(tmp, f"{index}.exr")
                subprocess.run(
                    [args.glassbake, "buffers", spec["scene"], "--sample", str(index), "--seed", str(spec["seed"]), "--res", str(res * factor), "--out", fine_exr],
                    check=True,
                    capture_output=True,
                )
                fine = opaque_ld(fine_exr)
                fine_light = fine.min(-1) >= 1.0
                coverage = fine_light.reshape(res, factor, res, factor).mean((1, 3))
                light = (fine * fine_light[..., None]).reshape(res, factor, res, factor, 3).mean((1, 3))
            pixels += truth.shape[0] * truth.shape[1]
            ring_pixels += ring.sum()
            for m in models:
                prediction = linear_png(truth_path.replace("ground_truth", m))
                error = ((truth - prediction) ** 2).mean(-1)
                if args.recomposite:
                    composite = np.minimum(1.0, light + (1.0 - coverage)[..., None] * prediction)
                    totals[m]["composite"].append(psnr(((truth - composite) ** 2).mean(-1).sum(), error.size))
                totals[m]["all"] += error.sum()
                totals[m]["ring"] += error[ring].sum()
                totals[m]["psnr"].append(psnr(error.sum(), error.size))
                totals[m]["outside"].append(psnr(error[~ring].sum(), (~ring).sum()))
                for part, mask in [("white", white), ("dark", dark), ("between", between)]:
                    totals[m][part] += error[mask].sum()
                totals[m]["dark_mean"].extend(prediction[dark].mean(-1))
                totals[m]["between_mean"].extend(prediction[between].mean(-1))
    print(f"{len(truths)} frames, {res} px; ring: {ring_pixels} of {pixels} pixels ({100.0 * ring_pixels / pixels:.2f}%)\n")
    mean = lambda values: f"{np.mean(values):.3f}" if len(values) else "-"
    print(f"ring pixels whose truth is dark: mean {mean(truth_dark)}; in between: mean {mean(truth_between)}\n")
    print(
        f"| model | PSNR | share of squared error in the ring | PSNR without the ring | PSNR recomposited at {factor}x{factor} "
        "| ring's error: white / dark / in between | mean where the truth is dark / in between |"
    )
    print("|---|---|---|---|---|---|---|")
    for m in models:
        t = totals[m]
        # A traced image (the noise floor's gt-SPPspp) already holds the light's coverage.
        composite = "-" if m.startswith("gt-") or not t["composite"] else f"{np.mean(t['composite']):.2f}"
        ring = max(t["ring"], 1e-30)
        split = " / ".join(f"{t[part] / ring:.2f}" for part in ["white", "dark", "between"])
        print(
            f"| {m} | {np.mean(t['psnr']):.2f} | {t['ring'] / t['all']:.3f} | {np.mean(t['outside']):.2f} | {composite} "
            f"| {split} | {mean(t['dark_mean'])} / {mean(t['between_mean'])} |"
        )


if __name__ == "__main__":
    main()
