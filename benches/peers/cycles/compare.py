"""wavetrace against Blender Cycles on the views workload: images per hour
at equal relMSE, both renderers at the same thread count, in one run.

Run it with the Python of a venv that has `bpy==5.0.1` and `OpenEXR`
(benches/peers/cycles/README.md):

    python benches/peers/cycles/compare.py --wavetrace target/release/wavetrace \
        --out /tmp/peers [--size 128] [--views 4] [--threads 2] \
        [--ref-spp 1024] [--spp 4,16,64]

For every asset it writes a `wavetrace views` job (an orbit of cameras
around the asset, the shipped sky at a rotation, max_depth 5), then
1. renders a converged reference with each renderer (`--ref-spp`, another
   seed), and checks that the two agree: the sky pixels must match, and the
   mean of the whole image is reported (the material models differ: glTF's
   Appendix B BRDF against Blender's Principled BSDF);
2. renders every `--spp` count with each renderer, timed: wavetrace's whole
   `views` command (load, build, render, write), Cycles' import plus each
   `render.render` call;
3. computes each image's relMSE against its own renderer's reference and
   each renderer's time per image at a common target relMSE (the geometric
   mean of the two at the middle spp count), interpolating log(time) in
   log(relMSE) between the two nearest spp counts, so images per hour are
   compared at equal error.
It prints a table and writes `results.json` in `--out`.
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import OpenEXR

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
ASSETS = [
    ROOT / "scenes/textured.glb",
    Path("/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb"),
]
ENV = ROOT / "scenes/env/sky.exr"
ROTATION = 30.0
MAX_DEPTH = 5


def load_exr(path):
    with OpenEXR.File(str(path)) as f:
        ch = f.channels()
        for key in ("RGB", "RGBA"):
            if key in ch:
                return np.asarray(ch[key].pixels, dtype=np.float64)[..., :3]
        return np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"], -1)


def relmse(a, ref):
    """wavetrace's definition (src/metrics.rs): mean of (a - r)^2 / (r^2 + 0.01)."""
    return float(np.mean((a - ref) ** 2 / (ref**2 + 0.01)))


def job_text(asset, a, spp, seed, adaptive=False):
    extra = ""
    if adaptive and a.noise_threshold is not None:
        # One threshold for every run, or one per --spp count.
        ts = [float(t) for t in str(a.noise_threshold).split(",")]
        counts = [int(c) for c in a.spp.split(",")]
        t = ts[counts.index(spp)] if len(ts) == len(counts) and spp in counts else ts[0]
        extra = f"noise_threshold = {t}\n"
        if a.min_spp is not None:
            extra += f"min_spp = {min(a.min_spp, spp)}\n"
    return f"""[assets]
files = ["{asset}"]
normalize = false

[cameras]
kind = "orbit"
views = {a.views}
elevations = [25.0]
azimuth = 15.0
fov = 40.0

[[environment]]
file = "{ENV}"
strength = 1.0
rotation = {ROTATION}

[render]
width = {a.size}
height = {a.size}
spp = {spp}
seed = {seed}
max_depth = {MAX_DEPTH}
{extra}
[outputs]
color = ["exr"]
"""


def wavetrace(a, asset, spp, seed, out, adaptive=False):
    # A fresh folder: `views` skips the views an earlier run finished there.
    shutil.rmtree(out, ignore_errors=True)
    job = out.with_suffix(".toml")
    job.parent.mkdir(parents=True, exist_ok=True)
    job.write_text(job_text(asset, a, spp, seed, adaptive))
    t = time.perf_counter()
    subprocess.run(
        [a.wavetrace, "views", str(job), "--out-dir", str(out), "--threads", str(a.threads)],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    seconds = time.perf_counter() - t
    folder = next(p for p in out.iterdir() if p.is_dir())
    digits = len(str(a.views - 1))  # views' names are padded to the view count's digits
    images = [load_exr(folder / f"{i:0{digits}d}.exr") for i in range(a.views)]
    return images, seconds, folder / "transforms.json"


def cycles(a, asset, transforms, spp, seed, out, adaptive=False):
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    r = subprocess.run(
        [sys.executable, str(HERE / "cycles_views.py"), "--glb", str(asset), "--env", str(ENV),
         "--rotation", str(ROTATION), "--transforms", str(transforms), "--out", str(out),
         "--spp", str(spp), "--bounces", str(MAX_DEPTH - 2), "--threads", str(a.threads),
         "--seed", str(seed)]
        + (["--adaptive", "--threshold", str(a.cycles_threshold),
            "--min-samples", str(min(a.cycles_min_samples, spp))] if adaptive else []),
        check=True, capture_output=True, text=True,
    )
    seconds = time.perf_counter() - t
    report = json.loads(r.stdout.strip().splitlines()[-1])
    images = [load_exr(out / f"{i:04d}.exr") for i in range(a.views)]
    # Blender's own start-up (the Python module's import) is not counted:
    # only the import of the asset and the renders.
    return images, report["load_seconds"] + sum(report["render_seconds"]), seconds


def reference(a, name, folder, kind, render):
    """An asset's converged images (and wavetrace's camera file): rendered
    by `render`, or, with --reuse-references, loaded from `folder` where an
    earlier run with the same settings left them (its settings are checked)."""
    stamp = folder / "settings.json"
    settings = {"size": a.size, "views": a.views, "ref_spp": a.ref_spp, "kind": kind}
    if a.reuse_references and stamp.exists() and json.loads(stamp.read_text()) == settings:
        print(f"{name}: reusing {folder}", file=sys.stderr)
        if kind == "wt":
            sub = next(p for p in folder.iterdir() if p.is_dir())
            digits = len(str(a.views - 1))
            images = [load_exr(sub / f"{i:0{digits}d}.exr") for i in range(a.views)]
            return images, sub / "transforms.json"
        return [load_exr(folder / f"{i:04d}.exr") for i in range(a.views)], None
    result = render()
    stamp.write_text(json.dumps(settings))
    return result[0], result[2]


def time_at(points, target):
    """Time per image at relMSE `target`, from (relmse, seconds) points:
    log-log interpolation between the two nearest, else 1/t extrapolation."""
    pts = sorted(points, key=lambda p: -p[0])
    for (e0, t0), (e1, t1) in zip(pts, pts[1:]):
        if e1 <= target <= e0:
            s = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + s * (math.log(t1) - math.log(t0)))
    e, t = min(pts, key=lambda p: abs(math.log(p[0] / target)))
    return t * e / target


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--wavetrace", default=str(ROOT / "target/release/wavetrace"))
    p.add_argument("--out", required=True)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--views", type=int, default=4)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--ref-spp", type=int, default=1024)
    p.add_argument("--spp", default="4,16,64")
    p.add_argument("--reuse-references", action="store_true",
                   help="load the references an earlier run with the same settings left in --out "
                        "(rendered afresh where missing): time the renders later, on a quiet machine")
    p.add_argument("--adaptive", action="store_true",
                   help="Cycles' adaptive sampling on (not for the references)")
    p.add_argument("--cycles-threshold", type=float, default=0.01,
                   help="with --adaptive: Cycles' noise threshold (its default 0.01)")
    p.add_argument("--cycles-min-samples", type=int, default=0,
                   help="with --adaptive: Cycles' minimum samples (0: its automatic choice)")
    p.add_argument("--noise-threshold", default=None,
                   help="wavetrace's adaptive sampling (render.noise_threshold) in the timed renders: "
                        "one value, or one per --spp count (then each count is a run's most)")
    p.add_argument("--min-spp", type=int, default=None,
                   help="with --noise-threshold: wavetrace's first round (render.min_spp)")
    a = p.parse_args()
    out = Path(a.out)
    counts = [int(s) for s in a.spp.split(",")]
    results = {"settings": vars(a), "assets": {}}
    for asset in [x for x in ASSETS if x.exists()]:
        name = asset.stem
        print(f"{name}: references at {a.ref_spp} spp", file=sys.stderr)
        wt_ref, transforms = reference(a, name, out / name / "wt-ref", "wt",
                                       lambda: wavetrace(a, asset, a.ref_spp, 7, out / name / "wt-ref"))
        cy_ref, _ = reference(a, name, out / name / "cy-ref", "cy",
                              lambda: cycles(a, asset, transforms, a.ref_spp, 7, out / name / "cy-ref"))
        agree = []
        for v in range(a.views):
            w, c = wt_ref[v], cy_ref[v]
            rows = slice(0, max(1, a.size // 8))  # the sky above the asset
            agree.append({
                "mean_wavetrace": float(w.mean()),
                "mean_cycles": float(c.mean()),
                "sky_ratio": float(c[rows].mean() / w[rows].mean()),
                "ratio": float(c.mean() / w.mean()),
            })
        runs = {"wavetrace": [], "cycles": []}
        for spp in counts:
            print(f"{name}: {spp} spp", file=sys.stderr)
            imgs, secs, _ = wavetrace(a, asset, spp, 1, out / name / f"wt-{spp}", adaptive=True)
            e = float(np.mean([relmse(x, r) for x, r in zip(imgs, wt_ref)]))
            runs["wavetrace"].append({"spp": spp, "relmse": e, "seconds_per_image": secs / a.views})
            imgs, secs, wall = cycles(a, asset, transforms, spp, 1, out / name / f"cy-{spp}", a.adaptive)
            e = float(np.mean([relmse(x, r) for x, r in zip(imgs, cy_ref)]))
            runs["cycles"].append({"spp": spp, "relmse": e, "seconds_per_image": secs / a.views,
                                   "wall_seconds_per_image": wall / a.views})
        mid = len(counts) // 2
        target = math.sqrt(runs["wavetrace"][mid]["relmse"] * runs["cycles"][mid]["relmse"])
        per_hour = {k: 3600.0 / time_at([(r["relmse"], r["seconds_per_image"]) for r in v], target)
                    for k, v in runs.items()}
        results["assets"][name] = {"references": agree, "runs": runs, "target_relmse": target,
                                   "images_per_hour": per_hour,
                                   "ratio": per_hour["wavetrace"] / per_hour["cycles"]}
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(results, indent=2))
    print(f"{'asset':<18} {'renderer':<10} " + " ".join(f"{'relMSE@'+str(s):>12} {'s/img':>7}" for s in counts) + f" {'img/h @ equal relMSE':>22}")
    ratios = []
    for name, r in results["assets"].items():
        for k in ("wavetrace", "cycles"):
            cells = " ".join(f"{x['relmse']:12.3e} {x['seconds_per_image']:7.2f}" for x in r["runs"][k])
            print(f"{name:<18} {k:<10} {cells} {r['images_per_hour'][k]:22.0f}")
        ratios.append(r["ratio"])
        m = r["references"]
        print(f"{name:<18} ratio {r['ratio']:.2f}x at relMSE {r['target_relmse']:.3e}; references: "
              f"sky Cycles/wavetrace {np.mean([x['sky_ratio'] for x in m]):.4f}, image {np.mean([x['ratio'] for x in m]):.4f}")
    if ratios:
        print(f"overall (geometric mean) {math.exp(np.mean(np.log(ratios))):.2f}x")


if __name__ == "__main__":
    main()
