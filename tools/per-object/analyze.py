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
import numpy as np

from frames import Evaluation


def main():
    evaluation = Evaluation(__doc__.split("\n")[0])
    objects, models = evaluation.objects, evaluation.models
    squared = {(m, k): 0.0 for m in models for k in range(len(objects))}
    pixels = [0] * len(objects)
    for _, alone, _, error in evaluation.test_frames():
        for k in range(len(objects)):
            pixels[k] += int(alone[k].sum())
            for m in models:
                squared[(m, k)] += float(error[m][alone[k]].sum())

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
