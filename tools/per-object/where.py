"""Where behind each transparent object the error lies: its pixels split by what its through buffer says.

    pip install mitsuba numpy          # mitsuba only to read multi-layer EXR files
    python3 tools/per-object/where.py --dataset bake/dataset --eval bake/eval \
        [--models glassnet,naive,gt-96spp-384glass]

The pixels are analyze.py's (transparency buffer k covers them and no other does; the truth
clamped to [0, 1], a model's image eval's 8-bit sRGB frame decoded to linear). For each
object, one table per split:

- whether the camera sees the point its centre ray reaches (`on_screen`): where it does not,
  the through buffer's L_d is not the G-buffer's but only what the point emits (a light or
  the background), so the networks are given no light for it;
- the share of light the paths let through (`transmittance`);
- how far the footprint spreads behind the glass (`spread`, log2 of the stretch);
- how much detail the truth has there (its distance from its own 3x3 mean), by quantile.

Each row gives the share of the object's pixels, the first model's share of the object's
squared error, and each model's PSNR over those pixels (the squared error summed over all test
frames). With the noise floor's frames among the models (eval writes them as
NNNNNN_gt-*.png), a row whose model PSNR is far under its floor is where the error is.
Prints Markdown.
"""
import numpy as np

from frames import Evaluation


def detail(image):
    """|image - its 3x3 mean|, averaged over the channels (edges replicated)."""
    padded = np.pad(image, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = image.shape[:2]
    mean = sum(padded[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1)) / 9.0
    return np.abs(image - mean).mean(-1)


def psnr(squared):
    mse = squared.mean() if squared.size else 0.0
    return f"{10 * np.log10(1.0 / mse):.2f}" if mse > 0 else "inf"


def table(title, rows, errors, models):
    print(f"\n{title}\n")
    print(f"| pixels | share of them | share of {models[0]}'s squared error | " + " | ".join(f"{m} PSNR" for m in models) + " |")
    print("|---|---|---|" + "---|" * len(models))
    total = errors[models[0]].sum()
    for name, mask in rows:
        if not mask.any():
            continue
        share = errors[models[0]][mask].sum() / total if total > 0 else 0.0
        cells = " | ".join(psnr(errors[m][mask]) for m in models)
        print(f"| {name} | {mask.mean():.3f} | {share:.3f} | {cells} |")


def intervals(values, name, edges):
    return [(f"{name} in [{lo}, {hi})", (values >= lo) & (values < hi)) for lo, hi in zip(edges[:-1], edges[1:])]


def main():
    evaluation = Evaluation(__doc__.split("\n")[0], "comma-separated, the first the one whose error is split; default: every model eval wrote frames for")
    objects, models = evaluation.objects, evaluation.models
    features = {k: {"on_screen": [], "transmittance": [], "spread": [], "detail": []} for k in range(len(objects))}
    errors = {k: {m: [] for m in models} for k in range(len(objects))}
    for buffers, alone, truth, squared in evaluation.test_frames():
        truth_detail = detail(truth)
        for k in range(len(objects)):
            mask = alone[k]
            through = f"transparent.{k}.through."
            features[k]["on_screen"].append(buffers[through + "on_screen.Y"][mask])
            features[k]["transmittance"].append(buffers[through + "transmittance.Y"][mask])
            features[k]["spread"].append(buffers[through + "spread.Y"][mask])
            features[k]["detail"].append(truth_detail[mask])
            for m in models:
                errors[k][m].append(squared[m][mask])

    for k, name in enumerate(objects):
        f = {key: np.concatenate(v) for key, v in features[k].items()}
        e = {m: np.concatenate(v) for m, v in errors[k].items()}
        print(f"\n## {name}: {f['spread'].size} pixels, " + ", ".join(f"{m} {psnr(e[m])}" for m in models))
        seen = f["on_screen"] >= 0.5
        table("Whether the camera sees what the centre ray reaches", [("seen", seen), ("not seen", ~seen)], e, models)
        table("Transmittance", intervals(f["transmittance"], "transmittance", [0, 0.3, 0.6, 0.8, 0.9, 1.01]), e, models)
        table("Spread", intervals(f["spread"], "spread", [0, 0.5, 1, 2, 3, 100]), e, models)
        quantiles = np.quantile(f["detail"], [0.5, 0.8, 0.95])
        bands = np.searchsorted(quantiles, f["detail"], side="right")
        labels = ["lowest 50%", "50-80%", "80-95%", "top 5%"]
        table("The truth's detail, by quantile", [(labels[b], bands == b) for b in range(4)], e, models)


if __name__ == "__main__":
    main()
