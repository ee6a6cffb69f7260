"""Render the same scene instance with glassbake's path tracer and with Mitsuba 3, and print
the wall time, samples per second and image statistics of both.

    pip install mitsuba numpy
    python3 tools/mitsuba-compare/compare.py --glassbake target/release/glassbake \
        --scene cornellbox --sample 0 --res 128 --spp 256 [--variant scalar_rgb] [--threads N]

--scene is anything `glassbake` accepts: a built-in name or a manifest / glTF / OBJ path
(make_scenes.py beside this file writes two glTF test scenes with manifests).

Both renderers use all cores unless --threads is given, max depth 64 unless --max-depth, Russian roulette from
depth 5. The scene goes to Mitsuba through `glassbake scene mitsuba` (docs/design.md,
"Decisions made in the repo": Mitsuba export).
Lambertian surfaces and glass map one to one; glassbake's default opaque material goes out
as a blend that is 1-3% brighter in Mitsuba (docs/trace.md), metals as `principled` (Disney
diffuse), so image means differ by design there.
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
    p.add_argument("--scene", default="cornell-glass")
    p.add_argument("--sample", type=int, default=0)
    p.add_argument("--res", type=int, default=128)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--variant", default="scalar_rgb")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--max-depth", type=int, default=64, help="path vertices as Mitsuba counts them (2 = direct light only)")
    a = p.parse_args()

    import mitsuba as mi
    import numpy as np

    mi.set_variant(a.variant)
    if a.threads:
        mi.set_log_level(mi.LogLevel.Warn)
        mi.Thread.set_thread_count(a.threads)
    work = tempfile.mkdtemp(prefix="gb-mitsuba-")
    xml = os.path.join(work, "scene.xml")
    subprocess.run([a.glassbake, "scene", "mitsuba", a.scene, "--sample", str(a.sample), "--out", xml], check=True, stdout=subprocess.DEVNULL)
    gb_exr = os.path.join(work, "glassbake.exr")
    cmd = [a.glassbake, "trace", a.scene, "--sample", str(a.sample), "--res", str(a.res), "--spp", str(a.spp), "--max-depth", str(a.max_depth), "--out", gb_exr]
    if a.threads:
        cmd += ["--threads", str(a.threads)]
    t0 = time.time()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    gb_time = time.time() - t0

    scene = mi.load_file(xml, res=a.res, spp=a.spp, max_depth=a.max_depth)
    mi.render(scene, spp=1)  # warm-up: kernel compilation on JIT variants
    t0 = time.time()
    img = mi.render(scene, spp=a.spp)
    mi_img = np.array(img)[..., :3]
    mi_time = time.time() - t0
    mi.Bitmap(img).write(os.path.join(work, "mitsuba.exr"))
    gb_img = np.array(mi.Bitmap(gb_exr))[..., :3]

    samples = a.res * a.res * a.spp
    print(f"scene {a.scene} sample {a.sample}, {a.res}x{a.res}, {a.spp} spp, threads {a.threads or 'all'}")
    print(f"  glassbake trace : {gb_time:7.2f} s  {samples / gb_time:12,.0f} samples/s (process wall time, BVH build and EXR write included)")
    print(f"  mitsuba {a.variant:<8}: {mi_time:7.2f} s  {samples / mi_time:12,.0f} samples/s (render call only)")
    gb_mean, mi_mean = gb_img.mean(axis=(0, 1)), mi_img.mean(axis=(0, 1))
    print(f"  mean RGB glassbake {gb_mean}, mitsuba {mi_mean}")
    print(f"  ratio glassbake / mitsuba per channel: {' / '.join(f'{r:.4f}' for r in gb_mean / mi_mean)}")
    print(f"  images in {work}")


if __name__ == "__main__":
    sys.exit(main())
