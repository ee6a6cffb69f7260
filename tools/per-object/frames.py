"""What analyze.py and where.py share: their arguments, the test split of a dataset, and for each
test frame its cached buffers, each transparent object's pixels (those only its transparency
buffer covers), the truth clamped to [0, 1] (eval's tone map) and each model's squared error
against it (eval's frames/NNNNNN_MODEL.png, 8-bit sRGB decoded to linear)."""
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


class Evaluation:
    """A dataset's test split and the models an eval directory holds frames for."""

    def __init__(self, description, models_help="comma-separated; default: every model eval wrote frames for"):
        parser = argparse.ArgumentParser(description=description)
        parser.add_argument("--dataset", required=True)
        parser.add_argument("--eval", required=True, help="an eval output directory (its frames/)")
        parser.add_argument("--models", default=None, help=models_help)
        args = parser.parse_args()
        self.dataset = args.dataset
        manifest = json.load(open(os.path.join(args.dataset, "manifest.json")))
        self.objects = manifest["scene"]["transparent_objects"]
        self.test = [s["index"] for s in manifest["samples"] if s["split"] == "test"]
        self.frames = os.path.join(args.eval, "frames")
        if args.models:
            self.models = args.models.split(",")
        else:
            suffixes = {f.split("_", 1)[1][:-4] for f in os.listdir(self.frames) if f.endswith(".png")}
            self.models = sorted(suffixes - {"ground_truth"})

    def test_frames(self):
        """(buffers, alone, truth, squared) per test frame: alone [objects, H, W] the pixels each
        object alone covers, squared[model] [H, W] the mean over RGB of its squared error."""
        for index in self.test:
            buffers = layers(os.path.join(self.dataset, "buffers", f"{index:06d}.exr"))
            coverage = np.array([buffers[f"transparent.{k}.coverage.Y"] > 0 for k in range(len(self.objects))])
            alone = coverage & (coverage.sum(0) == 1)
            gt = layers(os.path.join(self.dataset, "gt", f"{index:06d}.exr"))
            truth = np.clip(np.stack([gt[c] for c in "RGB"], -1), 0.0, 1.0)
            squared = {m: ((linear_png(os.path.join(self.frames, f"{index:06d}_{m}.png"))[..., :3] - truth) ** 2).mean(-1) for m in self.models}
            yield buffers, alone, truth, squared
