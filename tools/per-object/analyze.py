"""Each transparent object's share of the glass: PSNR over the pixels where it alone is in front.

    pip install mitsuba numpy          # mitsuba only to read multi-layer EXR files
    python3 tools/per-object/analyze.py --dataset bake/dataset --eval bake/eval \
        [--models glassnet,naive,gt-96spp]

T.PSNR pools every pixel that shows glass; a scene with a lens and a pane can gain on one and
lose on the other. Here a pixel counts for object k when transparency buffer k covers it and
no other does (where two overlap, the error belongs to neither alone). The ground truth is the
dataset's test-split EXR clamped to [0, 1] (eval's tone map); a model's image is eval's
frames/NNNNNN_MODEL.png (8-bit sRGB, decoded to linear); the coverage comes from the
dataset's cached buffers. The squared error is summed over all frames before the PSNR, so an
object that shows in few frames is not weighted up. Prints a Markdown table.
"""
import argparse
import json
import os

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def layers(path):
    bitmap = mi.Bitmap(path)
    struct = bitmap.struct_()
    names = [struct[i].name for i in range(len(struct))]
    return {name: plane for name, plane in zip(names, np.moveaxis(np.array(bitmap), -1, 0))}


def linear_png(path):
    a = np.array(mi.Bitmap(path)).astype(np.float64) / 255.0
    return np.where(a <= 0.04045, a / 12.92, ((a + 0.055) / 1.055) ** 2.4)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dataset", required=True)
    parser.add_argument("--eval", required=True, help="an eval output directory (its frames/)")
    parser.add_argument("--models", default=None, help="comma-separated; default: every model eval wrote frames for")
    args = parser.parse_args()

    manifest = json.load(open(os.path.join(args.dataset, "manifest.json")))
    objects = manifest["scene"]["transparent_objects"]
    test = [s["index"] for s in manifest["samples"] if s["split"] == "test"]
    frames = os.path.join(args.eval, "frames")
    if args.models:
        models = args.models.split(",")
    else:
        suffixes = {f.split("_", 1)[1][:-4] for f in os.listdir(frames) if f.endswith(".png")}
        models = sorted(suffixes - {"ground_truth"})

    squared = {(m, k): 0.0 for m in models for k in range(len(objects))}
    pixels = [0] * len(objects)
    for index in test:
        buffers = layers(os.path.join(args.dataset, "buffers", f"{index:06d}.exr"))
        coverage = np.array([buffers[f"transparent.{k}.coverage.Y"] > 0 for k in range(len(objects))])
        alone = coverage & (coverage.sum(0) == 1)
        gt = layers(os.path.join(args.dataset, "gt", f"{index:06d}.exr"))
        truth = np.clip(np.stack([gt[c] for c in "RGB"], -1), 0.0, 1.0)
        for k in range(len(objects)):
            pixels[k] += int(alone[k].sum())
        for m in models:
            error = ((linear_png(os.path.join(frames, f"{index:06d}_{m}.png")) - truth) ** 2).mean(-1)
            for k in range(len(objects)):
                squared[(m, k)] += float(error[alone[k]].sum())

    print("| object | pixels | " + " | ".join(models) + " |")
    print("|---|---|" + "---|" * len(models))
    for k, name in enumerate(objects):
        cells = []
        for m in models:
            mse = squared[(m, k)] / max(pixels[k], 1)
            cells.append(f"{10 * np.log10(1.0 / mse):.2f}" if mse > 0 else "inf")
        print(f"| {name} | {pixels[k]} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
