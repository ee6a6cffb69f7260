"""Error against a converged reference at equal wall time: glassbake's tracer (an estimator of
choice) vs Mitsuba 3's path tracer on the same exported scene instance.

    pip install mitsuba numpy
    # llvm_ad_rgb (the default variant) aborts with LLVM 15, whose x86 backend cannot select
    # the `fminimum` Dr.Jit emits; LLVM 19 works (Debian 12 has both):
    apt-get install libllvm19
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
    python3 tools/mitsuba-compare/equal_time.py --glassbake target/release/glassbake \
        [--scenes cornellbox,desk] [--sample 0] [--res 128] [--spp 256] [--ref-factor 16] \
        [--repeats 3] [--estimator caustic+adaptive+stratified] [--variant llvm_ad_rgb]

Per scene: glassbake traces the instance at --spp, --repeats times with different image
seeds (process wall time, BVH build and EXR write included; t is their mean); Mitsuba renders
it --repeats times with as many spp as fit in t (calibrated on a first render, kernel
compilation excluded, each render timed). Each renderer's error, the mean over its repeats,
is measured against its own reference, traced with independent random numbers at --ref-factor
times the spp of that renderer's test renders, so that the reference's noise adds the same
fraction, 1/ref-factor, to both renderers' error and cancels in the ratio (a reference at a
fixed spp would add more to the renderer that fits more samples in t). Own references: the two renderers interpret a few materials differently by design (docs/trace.md:
the default opaque blend is 1-3% brighter in Mitsuba), so a shared reference would measure
that difference, not convergence. With an estimator that merges photons (`+merging`)
glassbake's test render is biased while its reference, the same estimator without
`+merging`, stays unbiased, so the error counts the bias. The printed MSE is not corrected
for the reference's noise. Prints a Markdown table:
seconds, spp, MSE over all pixels and over the pixels away from emitters (no reference value
above 1 in a pixel's 3x3 neighbourhood: the light's edge pixels, whose box-filtered noise is
the same for any estimator, dominate the all-pixel figure) and over all pixels clamped to
[0, 1] (what every image metric sees), and the ratios Mitsuba / glassbake. Both renderers'
images stay in the printed directory.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--glassbake", required=True)
    p.add_argument("--scenes", default="cornell-glass,cornellbox,cornellbox8,desk,bathroom")
    p.add_argument("--sample", type=int, default=0)
    p.add_argument("--res", type=int, default=128)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--ref-factor", type=int, default=16)
    p.add_argument("--repeats", type=int, default=3, help="test renders per renderer, with different seeds; errors and times averaged")
    p.add_argument("--estimator", default="caustic+adaptive+stratified", help="glassbake trace --estimator (its reference: the same without +merging)")
    p.add_argument("--variant", default="llvm_ad_rgb")
    p.add_argument("--max-depth", type=int, default=64)
    a = p.parse_args()

    import mitsuba as mi
    import numpy as np

    mi.set_variant(a.variant)
    work = tempfile.mkdtemp(prefix="gb-mitsuba-equal-time-")
    reference_estimator = "+".join(part for part in a.estimator.split("+") if part != "merging")
    print(f"{a.res}x{a.res}, sample {a.sample}, glassbake --estimator {a.estimator} at {a.spp} spp, "
          f"Mitsuba {a.variant} `path` at equal wall time; mean of {a.repeats} renders each;")
    print(f"references: each renderer at {a.ref_factor}x the spp of its own test renders, independent seeds; "
          "MSE over all pixels and RGB")
    print()
    print("| scene | glassbake s | glassbake spp | Mitsuba s | Mitsuba spp | glassbake MSE | Mitsuba MSE | ratio "
          "| glassbake MSE away from emitters | Mitsuba | ratio | glassbake MSE clamped | Mitsuba | ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")

    def trace(scene, spp, out, estimator, image_seed=None):
        cmd = [a.glassbake, "trace", scene, "--sample", str(a.sample), "--res", str(a.res), "--spp", str(spp),
               "--max-depth", str(a.max_depth), "--estimator", estimator, "--out", out]
        if image_seed is not None:
            cmd += ["--image-seed", str(image_seed)]
        t0 = time.time()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return time.time() - t0, np.array(mi.Bitmap(out))[..., :3].astype(np.float64)

    for name in a.scenes.split(","):
        xml = os.path.join(work, f"{name}.xml")
        subprocess.run([a.glassbake, "scene", "mitsuba", name, "--sample", str(a.sample), "--out", xml], check=True, stdout=subprocess.DEVNULL)
        gb_runs = [trace(name, a.spp, os.path.join(work, f"{name}_gb_{i}.exr"), a.estimator, image_seed=1000 + i)
                   for i in range(a.repeats)]
        gb_time = sum(t for t, _ in gb_runs) / a.repeats
        _, gb_ref = trace(name, a.spp * a.ref_factor, os.path.join(work, f"{name}_gb_ref.exr"), reference_estimator, image_seed=1)

        scene = mi.load_file(xml, res=a.res, spp=a.spp, max_depth=a.max_depth)

        def render(spp, seed):
            # In passes of at most 256 spp: the LLVM variant keeps every sample of a pass in
            # flight at once.
            total, done, k = 0.0, 0, 0
            while done < spp:
                n = min(256, spp - done)
                total = total + np.array(mi.render(scene, spp=n, seed=seed * 100_003 + k))[..., :3].astype(np.float64) * n
                done += n
                k += 1
            return total / spp

        render(1, 7)  # kernel compilation on JIT variants
        t0 = time.time()
        render(a.spp, 3)
        per_spp = (time.time() - t0) / a.spp
        mi_spp = max(1, int(gb_time / per_spp))
        mi_runs = []
        for i in range(a.repeats):
            t0 = time.time()
            image = render(mi_spp, 10 + i)
            mi_runs.append((time.time() - t0, image))
        mi_time = sum(t for t, _ in mi_runs) / a.repeats
        mi_ref = render(mi_spp * a.ref_factor, 1)

        for label, image in [(f"mitsuba_{i}", im) for i, (_, im) in enumerate(mi_runs)] + [("mitsuba_ref", mi_ref)]:
            mi.Bitmap(image.astype(np.float32)).write(os.path.join(work, f"{name}_{label}.exr"))
        bright = np.maximum(gb_ref.max(axis=2), mi_ref.max(axis=2)) > 1.0
        padded = np.pad(bright, 1)
        near_emitter = np.zeros_like(bright)
        for dy in range(3):
            for dx in range(3):
                near_emitter |= padded[dy:dy + bright.shape[0], dx:dx + bright.shape[1]]
        away = ~near_emitter

        def mse(image, reference, mask=None):
            e = ((image - reference) ** 2).mean(axis=2)
            return float(e.mean() if mask is None else e[mask].mean())

        def clamped(image):
            return np.clip(image, 0.0, 1.0)

        def mean_mse(runs, reference, mask=None, transform=lambda x: x):
            return sum(mse(transform(image), transform(reference), mask) for _, image in runs) / len(runs)

        gb_all, mi_all = mean_mse(gb_runs, gb_ref), mean_mse(mi_runs, mi_ref)
        gb_away, mi_away = mean_mse(gb_runs, gb_ref, away), mean_mse(mi_runs, mi_ref, away)
        gb_clamped, mi_clamped = mean_mse(gb_runs, gb_ref, transform=clamped), mean_mse(mi_runs, mi_ref, transform=clamped)
        print(f"| {name} | {gb_time:.1f} | {a.spp} | {mi_time:.1f} | {mi_spp} | {gb_all:.3e} | {mi_all:.3e} | {mi_all / gb_all:.2f}x "
              f"| {gb_away:.3e} | {mi_away:.3e} | {mi_away / gb_away:.2f}x | {gb_clamped:.3e} | {mi_clamped:.3e} | {mi_clamped / gb_clamped:.2f}x |")
        sys.stdout.flush()
    print()
    print(f"images in {work}")


if __name__ == "__main__":
    sys.exit(main())
