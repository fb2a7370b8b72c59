"""Render a GLB asset under an HDR environment and show its image and depth.

    python python/examples/render_glb.py [ASSET.glb] [--env ENV.exr] [--out figure.png]

Defaults: the shipped scenes/textured.glb under scenes/env/sky.exr. Shows
the figure in a window where there is a display, and writes it to --out.
"""

import argparse
from pathlib import Path

import matplotlib

import numpy as np
import wavetrace

ROOT = Path(__file__).resolve().parents[2]

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("asset", nargs="?", default=ROOT / "scenes" / "textured.glb")
parser.add_argument("--env", default=ROOT / "scenes" / "env" / "sky.exr")
parser.add_argument("--spp", type=int, default=64)
parser.add_argument("--out", default="render_glb.png")
parser.add_argument("--show", action="store_true", help="open a window too")
args = parser.parse_args()
if not args.show:
    matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 (after the backend is chosen)

scene = wavetrace.load(args.asset)
# Three quarters around the asset, a little above it.
lo, hi = scene.bounds
center = scene.center
radius = float(np.linalg.norm(hi - lo)) / 2
eye = center + radius * np.array([1.6, 1.0, 2.2])
camera = wavetrace.Camera.look_at(eye, center, up=[0, 1, 0], fov_y=40)

out = scene.render(camera, spp=args.spp, width=480, height=360, env=args.env, aovs=["depth"])
color, depth = out["color"], out["depth"]

# Linear radiance to display: clip, then the sRGB curve.
srgb = np.where(color[..., :3] <= 0.0031308, 12.92 * color[..., :3], 1.055 * np.power(color[..., :3], 1 / 2.4) - 0.055)
figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
left.imshow(np.clip(srgb, 0, 1))
left.set_title(f"{scene.name}: colour ({args.spp} spp)")
shown = np.where(np.isfinite(depth), depth, np.nan)
image = right.imshow(shown, cmap="viridis")
right.set_title("depth (distance along the ray)")
figure.colorbar(image, ax=right, fraction=0.046)
for axis in (left, right):
    axis.axis("off")
figure.tight_layout()
figure.savefig(args.out, dpi=100)
print(f"wrote {args.out}")
if args.show:
    plt.show()
