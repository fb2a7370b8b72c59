#!/usr/bin/env python3
"""wavetrace's default Cornell box against Mitsuba 3's path tracer: the same
scene (exported from scenes/cornell.toml, which is the built-in default),
size, path depth, samples and threads; relMSE against
scenes/refs/cornell-256-d3.exr, seconds, and efficiency 1 / (relMSE x s),
in one run, interleaved rounds, medians. See README.md."""
import argparse, json, math, os, statistics, subprocess, sys, tempfile, time, tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]


def relmse(img, ref):
    """wavetrace's relMSE (src/metrics.rs): mean of (a - r)^2 / (r^2 + 0.01)."""
    d = img.astype(np.float64) - ref.astype(np.float64)
    return float(np.mean(d * d / (ref.astype(np.float64) ** 2 + 0.01)))


def write_objs(scene, out):
    """One OBJ per material. wavetrace's clockwise front, (v2 - v0) x (v1 - v0),
    is Mitsuba's counter-clockwise (v0, v2, v1). Only emission is one-sided."""
    by = {}
    for t in scene["triangle"]:
        by.setdefault(t["material"], []).append(t["vertices"])
    assert scene.get("front_face") == "clockwise"
    files = {}
    for m, tris in by.items():
        lines = []
        for k, (a, b, c) in enumerate(tris):
            for v in (a, c, b):
                lines.append("v %r %r %r" % tuple(v))
        for k in range(len(tris)):
            lines.append("f %d %d %d" % (3 * k + 1, 3 * k + 2, 3 * k + 3))
        files[m] = out / f"{m}.obj"
        files[m].write_text("\n".join(lines) + "\n")
    return files


def mitsuba_scene(mi, scene, objs, size, spp, sampler, max_depth):
    cam = scene["camera"]
    f = cam["focal_length_px"] * size / cam["height"]  # scales with the height
    fov = 2 * math.degrees(math.atan(0.5 * size / f))
    o = cam["position"]
    t = [o[i] + cam["forward"][i] for i in range(3)]
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth, "hide_emitters": False},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": fov,
            "to_world": mi.ScalarTransform4f().look_at(origin=o, target=t, up=cam["up"]),
            "sampler": {"type": sampler, "sample_count": spp},
            "film": {
                "type": "hdrfilm",
                "width": size,
                "height": size,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
        },
    }
    for m, path in objs.items():
        mat = scene["materials"][m]
        shape = {
            "type": "obj",
            "filename": str(path),
            "face_normals": True,
            "bsdf": {
                "type": "twosided",
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": mat["reflectance"]}},
            },
        }
        if "emission" in mat:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": mat["emission"]}}
        d[m] = shape
    return mi.load_dict(d)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--wavetrace", default=str(ROOT / "target/release/wavetrace"))
    ap.add_argument("--variant", default="llvm_ad_rgb", help="llvm_ad_rgb, else scalar_rgb")
    ap.add_argument("--samplers", default="multijitter,ldsampler,independent")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--check-spp", type=int, default=1024, help="converged-mean check (0: skip)")
    ap.add_argument("--out", default=None, help="results.json here")
    a = ap.parse_args()

    # Dr.Jit's LLVM backend needs a recent libLLVM (Debian 12's 14 and 15
    # fail); use Debian's libllvm19 where it is installed.
    llvm19 = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"
    if "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(llvm19):
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm19
    import drjit as dr
    import mitsuba as mi

    try:
        mi.set_variant(a.variant)
    except Exception as e:  # no LLVM here: the scalar variant
        print(f"variant {a.variant} unavailable ({e}); scalar_rgb", file=sys.stderr)
        a.variant = "scalar_rgb"
        mi.set_variant(a.variant)
    dr.set_thread_count(a.threads)

    toml = tomllib.loads((ROOT / "scenes/cornell.toml").read_text())
    max_depth = toml["integrator"]["max_depth"]
    ref_path = ROOT / "scenes/refs/cornell-256-d3.exr"
    ref = np.array(mi.Bitmap(str(ref_path)), dtype=np.float32)[:, :, :3]
    assert ref.shape[0] == a.size, "the reference is 256x256"
    tmp = Path(tempfile.mkdtemp(prefix="mitsuba-cornell-"))
    objs = write_objs(toml, tmp)
    # wavetrace's max depth counts path segments (camera ray included), as
    # Mitsuba's max_depth does: 3 = emission seen directly, after one bounce
    # and after two (direct light at the second vertex); no roulette below
    # Mitsuba's rr_depth 5.
    scenes = {s: mitsuba_scene(mi, toml, objs, a.size, a.spp, s, max_depth) for s in a.samplers.split(",")}

    def mitsuba(s, seed, spp=None):
        t0 = time.perf_counter()
        img = np.array(mi.render(scenes[s], seed=seed, spp=spp or a.spp))[:, :, :3]
        return time.perf_counter() - t0, img

    def wavetrace(seed):
        js = tmp / "wt.json"
        cmd = [a.wavetrace, "render", "--width", str(a.size), "--height", str(a.size), "-s", str(a.spp),
               "-t", str(a.threads), "--max-depth", str(max_depth), "--seed", str(seed), "-q",
               "-o", str(tmp / "wt.exr"), "--reference", str(ref_path), "--stats", str(js)]
        subprocess.run(cmd, check=True, capture_output=True)
        st = json.loads(js.read_text())
        return st["seconds"], st["relmse"]

    out = {"variant": a.variant, "threads": a.threads, "spp": a.spp, "size": a.size,
           "max_depth": max_depth, "load_average": os.getloadavg()}
    for s in scenes:  # warm-up: the LLVM kernels are compiled (and cached) here
        mitsuba(s, 0)
    if a.check_spp:
        _, hi = mitsuba(a.samplers.split(",")[0], 12345, a.check_spp)
        means = hi.reshape(-1, 3).mean(0) / ref.reshape(-1, 3).mean(0)
        out["check"] = {"spp": a.check_spp, "mean_ratio_rgb": means.tolist(), "relmse": relmse(hi, ref)}
        print(f"converged check, {a.check_spp} spp: mean Mitsuba/reference per channel "
              f"{' '.join('%.4f' % m for m in means)}, relMSE {relmse(hi, ref):.3e}")
    rows = {"wavetrace": []} | {s: [] for s in scenes}
    for r in range(a.rounds):
        rows["wavetrace"].append(wavetrace(r + 1))
        for s in scenes:
            sec, img = mitsuba(s, r + 1)
            rows[s].append((sec, relmse(img, ref)))
    out["load_average_after"] = os.getloadavg()
    med = {k: (statistics.median(x[0] for x in v), statistics.median(x[1] for x in v)) for k, v in rows.items()}
    eff = {k: 1 / (s * e) for k, (s, e) in med.items()}
    print(f"Mitsuba {mi.__version__} {a.variant}, {a.size}x{a.size}, {a.spp} spp, max depth {max_depth}, "
          f"{a.threads} threads, medians of {a.rounds} interleaved rounds, load average "
          f"{out['load_average'][0]:.1f} -> {out['load_average_after'][0]:.1f}")
    print(f"{'renderer':<22} {'seconds':>8} {'relMSE':>10} {'efficiency':>11} {'wavetrace/x':>11}")
    for k, (s, e) in med.items():
        name = "wavetrace (nee+sobol)" if k == "wavetrace" else f"mitsuba {k}"
        print(f"{name:<22} {s:8.3f} {e:10.3e} {eff[k]:11.1f} {eff['wavetrace'] / eff[k]:10.2f}x")
    out["rows"] = rows
    out["medians"] = med
    out["efficiency"] = eff
    if a.out:
        Path(a.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
