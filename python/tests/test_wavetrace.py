"""Tests of the wavetrace Python package.

Run from the repository root after `pip install .` (and `pip install
pytest OpenEXR`): `pytest python/tests`. The command line the arrays are
compared with is `target/release/wavetrace` (built by `cargo build
--release`) or, where that is missing, `wavetrace` on the PATH.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import wavetrace
from wavetrace import Camera, WavetraceError

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"


def cli() -> str:
    built = ROOT / "target" / "release" / "wavetrace"
    if built.exists():
        return str(built)
    found = shutil.which("wavetrace")
    if found is None:
        pytest.fail("no wavetrace command: run `cargo build --release` first")
    return found


def read_exr(path: Path) -> dict:
    OpenEXR = pytest.importorskip("OpenEXR") if not os.environ.get("CI") else __import__("OpenEXR")
    with OpenEXR.File(str(path)) as f:
        return {name: np.array(c.pixels) for name, c in f.channels().items()}


def layer(layers: dict, name: str, channels: str) -> np.ndarray:
    """An EXR layer of three channels (OpenEXR groups R, G, B, not X, Y, Z)."""
    if name in layers:
        return layers[name]
    return np.stack([layers[f"{name}.{c}"] for c in channels], axis=-1)


# --- the arrays are the command line's images, bit for bit ---------------


@pytest.mark.parametrize(
    "scene, args",
    [
        (None, ["--spp", "8", "--seed", "3"]),
        (SCENES / "textured.glb", ["--spp", "4", "--width", "96", "--height", "64"]),
        (SCENES / "asset-sky.toml", ["--spp", "4", "--width", "80", "--height", "60", "--integrator", "bsdf"]),
    ],
)
def test_arrays_equal_the_command_lines_exr_bit_for_bit(tmp_path, scene, args):
    exr = tmp_path / "cli.exr"
    command = [cli()] + ([str(scene)] if scene else []) + args + ["--aov", "depth,normal,albedo", "--out", str(exr)]
    subprocess.run(command, check=True, capture_output=True)
    layers = read_exr(exr)

    def flag(name, default=None, kind=int):
        return kind(args[args.index(name) + 1]) if name in args else default

    s = wavetrace.load(scene) if scene else wavetrace.cornell()
    out = s.render(
        spp=flag("--spp"),
        seed=flag("--seed", 0),
        width=flag("--width"),
        height=flag("--height"),
        integrator=flag("--integrator", None, str),
        aovs=["depth", "normal", "albedo"],
    )
    assert out["color"].dtype == np.float32
    assert out["color"].shape == layers["RGB"].shape[:2] + (4,)
    assert np.array_equal(out["color"][..., :3], layers["RGB"])
    assert np.array_equal(out["depth"], layers["depth.Z"])
    assert np.array_equal(out["normal"], layer(layers, "normal", "XYZ"))
    assert np.array_equal(out["albedo"], layer(layers, "albedo", "RGB"))


def test_same_seed_same_bits_whatever_the_threads_and_a_kept_renderer():
    s = wavetrace.cornell()
    a = s.render(spp=4, seed=7, width=64, height=64, threads=1)["color"]
    b = s.render(spp=4, seed=7, width=64, height=64, threads=2)["color"]
    assert np.array_equal(a, b)
    # A kept renderer given another camera and back renders the same bits.
    other = Camera.look_at([0.5, 0.2, -2.5], [0, 0, 0], up=[0, -1, 0])
    s.render(other, spp=4, seed=7, width=64, height=64, threads=2)
    c = s.render(spp=4, seed=7, width=64, height=64, threads=2)["color"]
    assert np.array_equal(a, c)
    assert not np.array_equal(a, s.render(spp=4, seed=8, width=64, height=64)["color"])


def test_the_arrays_are_views_of_the_render_not_copies():
    out = wavetrace.cornell().render(spp=1, width=32, height=32)
    color = out["color"]
    assert not color.flags.owndata and not color.flags.writeable
    assert color.base is not None


# --- camera conventions: a known point is seen where the camera says ----


def bright_spot(image: np.ndarray) -> tuple:
    """The centroid (x, y) of the pixels brighter than half the maximum."""
    lum = image[..., :3].sum(axis=-1)
    ys, xs = np.nonzero(lum > 0.5 * lum.max())
    return xs.mean() + 0.5, ys.mean() + 0.5


def marker_scene(tmp_path: Path, center) -> wavetrace.Scene:
    """A small emissive sphere at `center`, nothing else, black background."""
    text = f"""
[camera]
position = [0.0, 0.0, -5.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
vfov_deg = 40.0
width = 64
height = 48

[materials.lamp]
reflectance = [0.0, 0.0, 0.0]
emission = [10.0, 10.0, 10.0]

[[sphere]]
center = [{center[0]}, {center[1]}, {center[2]}]
radius = 0.05
material = "lamp"
"""
    path = tmp_path / "marker.toml"
    path.write_text(text)
    return wavetrace.load(path)


def cameras(center):
    eye = np.array([1.5, 0.8, -3.0])
    look = Camera.look_at(eye, [0.1, -0.1, 0.0], up=[0, 1, 0], fov_y=35.0)
    yield "look_at", look
    yield "from_matrix", Camera.from_matrix(look.matrix(), fov_y=35.0)
    w, h = 64, 48
    r, t = look.extrinsics()
    yield "from_opencv", Camera.from_opencv(look.intrinsics(w, h), r, t, w, h)
    # A general K: fx != fy and the principal point off the centre.
    k = np.array(look.intrinsics(w, h))
    k[0, 0] *= 1.15
    k[0, 2] += 5.3
    k[1, 2] -= 4.1
    yield "from_opencv off-centre", Camera.from_opencv(k, r, t, w, h)


@pytest.mark.parametrize("point", [(0.3, 0.2, 0.1), (-0.4, -0.25, 0.3), (0.0, 0.0, 0.0)])
@pytest.mark.parametrize("size", [(64, 48), (96, 72)])
def test_a_known_point_projects_where_the_render_sees_it(tmp_path, point, size):
    scene = marker_scene(tmp_path, point)
    w, h = size
    for name, camera in cameras(point):
        image = scene.render(camera, spp=16, width=w, height=h, integrator="bsdf")["color"]
        seen = bright_spot(image)
        projected = camera.project(point, w, h)
        assert projected is not None
        assert math.dist(seen, projected) < 0.75, (name, size, seen, projected)
        # OpenCV's K, R, t: pixel centres at integers.
        k = np.array(camera.intrinsics(w, h))
        r, t = (np.array(m) for m in camera.extrinsics())
        x = k @ (r @ np.array(point) + t)
        assert math.dist((x[0] / x[2] + 0.5, x[1] / x[2] + 0.5), projected) < 1e-3, name
        # The OpenGL matrix: camera looks down -Z.
        m = np.array(camera.matrix())
        local = np.linalg.inv(m) @ np.array([*point, 1.0])
        assert local[2] < 0


def test_cameras_round_trip_and_bad_cameras_are_refused():
    cam = Camera.look_at([1, 2, 3], [0, 0, 0], fov_y=50)
    again = Camera.from_matrix(cam.matrix(), fov_y=50)
    assert np.allclose(again.position, cam.position) and np.allclose(again.forward, cam.forward)
    r, t = cam.extrinsics()
    via_cv = Camera.from_opencv(cam.intrinsics(100, 80), r, t, 100, 80)
    assert np.allclose(via_cv.forward, cam.forward, atol=1e-6) and np.allclose(via_cv.up, cam.up, atol=1e-6) and abs(via_cv.fov_y - 50) < 1e-4
    with pytest.raises(ValueError, match="parallel"):
        Camera.look_at([0, 0, 0], [0, 1, 0], up=[0, 1, 0])
    with pytest.raises(ValueError, match="fov_y"):
        Camera.look_at([0, 0, 1], [0, 0, 0], fov_y=180)
    scaled = np.array(cam.matrix())
    scaled[:3, :3] *= 2
    with pytest.raises(ValueError, match="orthonormal"):
        Camera.from_matrix(scaled)
    k = np.array(cam.intrinsics(100, 80))
    k[0, 0] *= 1.2
    k[1, 2] += 3
    general = Camera.from_opencv(k, r, t, 100, 80)
    assert np.allclose(general.intrinsics(100, 80), k, rtol=1e-6)
    assert np.allclose(general.intrinsics(200, 160), k * [[2], [2], [1]] + [[0, 0, 0.5], [0, 0, 0.5], [0, 0, 0]], rtol=1e-6)
    skewed = k.copy()
    skewed[0, 1] = 0.5
    with pytest.raises(ValueError, match="skew"):
        Camera.from_opencv(skewed, r, t, 100, 80)
    with pytest.raises(ValueError, match="focal"):
        Camera.from_opencv(k * [[-1], [1], [1]], r, t, 100, 80)


# --- errors are exceptions with the command line's messages ---------------


def test_bad_scenes_and_arguments_raise_not_crash(tmp_path):
    with pytest.raises(WavetraceError, match="no-such.toml"):
        wavetrace.load(tmp_path / "no-such.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera]\nposition = [0, 0]\n")
    with pytest.raises(WavetraceError, match="bad.toml"):
        wavetrace.load(bad)
    broken = tmp_path / "broken.glb"
    broken.write_bytes(b"glTF\x02\x00\x00\x00" + b"\xff" * 40)
    with pytest.raises(WavetraceError, match="broken.glb"):
        wavetrace.load(broken)
    mesh = tmp_path / "mesh.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(WavetraceError, match="OBJ"):
        wavetrace.load(mesh)
    s = wavetrace.cornell()
    with pytest.raises(WavetraceError, match="integrator"):
        s.render(spp=1, integrator="magic")
    with pytest.raises(WavetraceError, match="aov"):
        s.render(spp=1, aovs=["colour"])
    with pytest.raises(WavetraceError):
        s.render(spp=1, width=0)
    with pytest.raises(WavetraceError, match="samples per pixel"):
        s.render(spp=0)
    with pytest.raises(WavetraceError, match="nothing.exr"):
        s.render(spp=1, env=tmp_path / "nothing.exr")
    with pytest.raises(OverflowError):
        s.render(spp=-1)


def test_a_command_line_error_message_is_the_exception_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera]\nposition = [0, 0]\n")
    run = subprocess.run([cli(), str(bad), "--check"], capture_output=True, text=True)
    assert run.returncode == 1
    with pytest.raises(WavetraceError) as caught:
        wavetrace.load(bad)
    assert run.stderr.strip() == f"error: {caught.value}"


# --- good citizenship ------------------------------------------------------


def test_an_interrupt_from_another_thread_stops_a_long_render_promptly():
    import _thread

    s = wavetrace.cornell()
    s.render(spp=1, width=16, height=16)  # load and build outside the clock
    timer = threading.Timer(0.3, _thread.interrupt_main)
    start = time.monotonic()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        # About a minute of work on two cores.
        s.render(spp=100000, width=256, height=256)
    elapsed = time.monotonic() - start
    timer.cancel()
    assert elapsed < 3.0, elapsed
    # The scene renders again afterwards.
    assert s.render(spp=1, width=16, height=16)["color"].shape == (16, 16, 4)


def test_the_gil_is_released_during_a_render():
    s = wavetrace.cornell()
    ticks = []
    running = threading.Event()

    def count():
        running.set()
        end = time.monotonic() + 0.6
        while time.monotonic() < end:
            ticks.append(time.monotonic())
            time.sleep(0.005)

    s.render(spp=1, width=16, height=16)
    thread = threading.Thread(target=count)
    thread.start()
    running.wait()
    start = time.monotonic()
    s.render(spp=512, width=128, height=128, threads=1)
    end = time.monotonic()
    thread.join()
    during = [t for t in ticks if start < t < end]
    # The other thread ran all along the render, not only before or after.
    assert end - start > 0.2
    assert len(during) > 10, (len(during), end - start)


def test_progress_reaches_a_callback_and_a_tqdm_like_object():
    s = wavetrace.cornell()
    calls = []
    s.render(spp=40, width=16, height=16, progress=lambda done, total: calls.append((done, total)))
    assert calls and calls[-1] == (40, 40)
    assert all(b[0] > a[0] for a, b in zip(calls, calls[1:]))

    class Bar:
        n = 0

        def update(self, k):
            self.n += k

    bar = Bar()
    s.render(spp=40, width=16, height=16, progress=bar)
    assert bar.n == 40

    def boom(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        s.render(spp=400, width=64, height=64, progress=boom)


def test_nothing_is_printed_on_stdout(tmp_path):
    glb = SCENES / "textured.glb"
    code = (
        "import wavetrace; s = wavetrace.load(%r); s.render(spp=1, width=8, height=8); "
        "wavetrace.cornell().render(spp=1, width=8, height=8)" % str(glb)
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout == "" and run.stderr == ""


def test_scene_properties():
    s = wavetrace.load(SCENES / "textured.glb")
    lo, hi = s.bounds
    assert (lo < hi).all() and s.triangles > 0
    assert s.name == "textured"
    assert Path(s.sources[0]).name == "textured.glb"
    assert s.resolution[1] == 480


def test_alpha_object_ids_and_zdepth_are_the_command_lines(tmp_path):
    scene = SCENES / "asset-sky.toml"
    exr = tmp_path / "t.exr"
    args = ["--spp", "4", "--width", "80", "--height", "60", "--transparent", "--aov", "zdepth,object_id"]
    subprocess.run([cli(), str(scene)] + args + ["--out", str(exr)], check=True, capture_output=True)
    layers = read_exr(exr)
    s = wavetrace.load(scene)
    out = s.render(spp=4, width=80, height=60, transparent=True, aovs=["zdepth", "object_id"])
    rgba = layers["RGBA"] if "RGBA" in layers else np.dstack([layers["RGB"], layers["A"]])
    assert np.array_equal(out["color"], rgba)
    alpha = out["color"][..., 3]
    assert 0 < alpha.mean() < 1 and alpha.min() == 0 and alpha.max() == 1
    assert np.array_equal(out["zdepth"], layers["zdepth.Z"])
    ids = out["object_id"]
    assert ids.dtype == np.uint32
    assert np.array_equal(ids, layers["object_id.id"].astype(np.uint32))
    assert set(np.unique(ids)) - {0} <= set(s.objects)
    # The background: no object, no alpha, black where transparent.
    assert (alpha[ids == 0] < 1).all()
    assert (out["color"][alpha == 0][:, :3] == 0).all()
    # Visible, the sky is seen, but alpha still counts the hits.
    seen = s.render(spp=4, width=80, height=60)["color"]
    assert np.array_equal(seen[..., 3], alpha)
    assert seen[alpha == 0][:, :3].min() > 0


# --- wavetrace.views: a views job streamed as arrays ------------------------


def views_job(tmp_path: Path, files, views=3, extra="") -> Path:
    text = f"""
[assets]
files = {[str(f) for f in files]!r}
normalize = true

[cameras]
kind = "orbit"
views = {views}
elevations = [30.0]
fov = 40.0
distance = 1.6

[[environment]]
file = "{SCENES / 'env' / 'sky.exr'}"

[render]
width = 40
height = 30
spp = 4
seed = 5

[outputs]
color = ["exr"]
aov = ["alpha", "depth", "zdepth", "normal", "albedo", "object_id"]
{extra}
""".replace("'", '"')
    path = tmp_path / "job.toml"
    path.write_text(text)
    return path


def test_views_are_the_command_lines_files_bit_for_bit(tmp_path):
    import json

    Image = pytest.importorskip("PIL.Image") if not os.environ.get("CI") else __import__("PIL.Image").Image
    job = views_job(tmp_path, [SCENES / "textured.glb"], extra='normals = "camera"')
    out = tmp_path / "out"
    subprocess.run([cli(), "views", str(job), "--out-dir", str(out), "--threads", "2"], check=True, capture_output=True)
    folder = out / "textured"
    frames = json.loads((folder / "transforms.json").read_text())["frames"]
    legend = json.loads((folder / "objects.json").read_text())
    seen = []
    for v in wavetrace.views(job, threads=1):
        seen.append((v.asset, v.view))
        exr = read_exr(folder / f"{v.view}.exr")
        assert np.array_equal(v.arrays["color"], exr["RGBA"]), v.view
        for name in ("depth", "zdepth"):
            assert np.array_equal(v.arrays[name], read_exr(folder / f"{v.view}.{name}.exr")["Z"]), name
        normal = read_exr(folder / f"{v.view}.normal.exr")
        assert np.array_equal(v.arrays["normal"], np.dstack([normal[c] for c in "XYZ"]))
        assert np.array_equal(v.arrays["albedo"], read_exr(folder / f"{v.view}.albedo.exr")["RGB"])
        ids = np.array(Image.open(folder / f"{v.view}.object_id.png")).astype(np.uint32)
        assert np.array_equal(v.arrays["object_id"], ids)
        assert (ids > 0).any()
        assert v.objects == {o["id"]: o["name"] for o in legend["objects"]}
        # The camera is transforms.json's, in the job's world.
        assert np.allclose(v.camera.matrix(), frames[v.view]["transform_matrix"], atol=1e-6)
    assert seen == [("textured", 0), ("textured", 1), ("textured", 2)]


def test_views_shards_progress_close_and_broken_assets(tmp_path):
    broken = tmp_path / "broken.glb"
    broken.write_bytes(b"glTF not really")
    job = views_job(tmp_path, [SCENES / "textured.glb", broken, SCENES / "textured.glb"], views=2)
    calls = []
    with pytest.warns(RuntimeWarning, match="broken.glb"):
        every = list(wavetrace.views(job, threads=2, progress=lambda done, total: calls.append((done, total))))
    assert [(v.asset, v.view) for v in every] == [("textured-0", 0), ("textured-0", 1), ("textured-2", 0), ("textured-2", 1)]
    assert calls == [(1, 6), (2, 6), (3, 6), (4, 6)]
    # Two shards: the command line's --shard split, the same bits.
    with pytest.warns(RuntimeWarning):
        halves = [list(wavetrace.views(job, shard=(i, 2))) for i in range(2)]
    joined = halves[0] + halves[1]
    assert [(v.asset, v.view) for v in joined] == [(v.asset, v.view) for v in every]
    for a, b in zip(joined, every):
        assert np.array_equal(a.arrays["color"], b.arrays["color"])
    # close() ends the job early; the iterator then ends.
    it = wavetrace.views(job)
    first = next(it)
    it.close()
    assert first.view == 0 and list(it) == []
    with pytest.raises(WavetraceError, match="no-such-job.toml"):
        wavetrace.views(tmp_path / "no-such-job.toml")
    with pytest.raises(WavetraceError, match="shard"):
        wavetrace.views(job, shard=(2, 2))
