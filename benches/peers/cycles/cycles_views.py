"""Render a wavetrace views job's cameras with Blender Cycles (run with the
Python of a venv that has `bpy==5.0.1`).

It imports the GLB with Blender's bundled glTF importer, lights it with the
same equirectangular environment (strength, rotation about glTF's +Y), and
renders every camera of the `transforms.json` that `wavetrace views` wrote
for the asset, as linear float EXRs, timing each render.

    python cycles_views.py --glb A.glb --env sky.exr --transforms T.json \
        --out DIR --spp 64 --bounces 3 --threads 2 [--rotation 0] [--adaptive]

Conventions (checked by compare.py, which measures the mean difference of
the two renderers' converged images):
- glTF is +Y up, Blender +Z up: the importer maps glTF (x, y, z) to Blender
  (x, -z, y); the cameras of transforms.json (OpenGL axes, glTF world) are
  mapped the same way.
- wavetrace's environment mapping is Blender's (docs/lights.md), written in
  +Y-up axes; its rotation R about +Y is a Mapping node's rotation -R about
  +Z (compare.py finds the sky pixels of the two references equal to four
  digits at R = 30 degrees).
- wavetrace's max_depth D counts path segments; Cycles' max_bounces counts
  bounces: D segments = D - 2 bounces (the last segment is the shadow ray).
- Pixel filter: a box one pixel wide (wavetrace integrates over the pixel's
  area); no denoiser; the view transform Standard, no exposure, linear EXR.
"""

import argparse
import json
import math
import sys
import time

import bpy
from mathutils import Matrix


def parse():
    p = argparse.ArgumentParser()
    p.add_argument("--glb", required=True)
    p.add_argument("--env", required=True)
    p.add_argument("--strength", type=float, default=1.0)
    p.add_argument("--rotation", type=float, default=0.0, help="degrees about glTF's +Y, wavetrace's sense")
    p.add_argument("--transforms", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--spp", type=int, required=True)
    p.add_argument("--bounces", type=int, required=True)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--adaptive", action="store_true", help="Cycles' adaptive sampling (default off)")
    p.add_argument("--threshold", type=float, default=0.01, help="with --adaptive: Cycles' noise threshold")
    p.add_argument("--min-samples", type=int, default=0, help="with --adaptive: Cycles' minimum samples (0: automatic)")
    p.add_argument("--views", type=str, default="", help="comma-separated view indices (default all)")
    return p.parse_args()


def setup_scene(a):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    t = time.perf_counter()
    bpy.ops.import_scene.gltf(filepath=a.glb)
    load = time.perf_counter() - t
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = a.spp
    c.use_adaptive_sampling = a.adaptive
    c.adaptive_threshold = a.threshold
    c.adaptive_min_samples = a.min_samples
    c.use_denoising = False
    c.seed = a.seed
    c.max_bounces = a.bounces
    c.diffuse_bounces = a.bounces
    c.glossy_bounces = a.bounces
    c.transmission_bounces = a.bounces
    c.volume_bounces = 0
    c.transparent_max_bounces = 64
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.blur_glossy = 0.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.use_light_tree = True
    scene.render.threads_mode = "FIXED"
    scene.render.threads = a.threads
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.exr_codec = "NONE"
    scene.render.use_persistent_data = True  # keep the BVH between views

    world = bpy.data.worlds.new("env")
    scene.world = world
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    coord = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    # wavetrace turns the content by R about glTF +Y (= Blender +Z after the
    # axis change); the mapping node rotates the lookup vector, so -R.
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, -math.radians(a.rotation))
    tex = nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(a.env)
    tex.interpolation = "Linear"
    bg = nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = a.strength
    out = nodes.new("ShaderNodeOutputWorld")
    links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bg.inputs["Color"])
    links.new(bg.outputs["Background"], out.inputs["Surface"])
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = 1024
    return scene, load


def one_sided_emission():
    """wavetrace's emitters are one-sided (docs/assets.md); Cycles' emission
    shader emits from both faces. Multiply each Principled BSDF's emission
    strength by (1 - backfacing) so that the back of an emitter is dark."""
    for mat in bpy.data.materials:
        if not mat.use_nodes:
            continue
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        for node in list(nodes):
            if node.type != "BSDF_PRINCIPLED":
                continue
            socket = node.inputs["Emission Strength"]
            if socket.is_linked or socket.default_value == 0.0:
                continue
            geometry = nodes.new("ShaderNodeNewGeometry")
            front = nodes.new("ShaderNodeMath")
            front.operation = "MULTIPLY_ADD"  # backfacing * -s + s
            front.inputs[1].default_value = -socket.default_value
            front.inputs[2].default_value = socket.default_value
            links.new(geometry.outputs["Backfacing"], front.inputs[0])
            links.new(front.outputs["Value"], socket)


def main():
    a = parse()
    doc = json.load(open(a.transforms))
    scene, load = setup_scene(a)
    one_sided_emission()
    w, h = doc["w"], doc["h"]
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    cam_data = bpy.data.cameras.new("cam")
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    # glTF (Y up) to Blender (Z up): (x, y, z) -> (x, -z, y).
    yup_to_zup = Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))
    frames = doc["frames"]
    pick = [int(v) for v in a.views.split(",")] if a.views else range(len(frames))
    times = []
    for i in pick:
        f = frames[i]
        fl_x = f.get("fl_x", doc["fl_x"])
        cam_data.sensor_fit = "HORIZONTAL"
        cam_data.sensor_width = 36.0
        cam_data.lens = fl_x * 36.0 / w
        cam.matrix_world = yup_to_zup @ Matrix(f["transform_matrix"])
        # No clipping (Blender's default far plane is 100 units).
        reach = max(1.0, cam.matrix_world.translation.length)
        cam_data.clip_start = 1e-5 * reach
        cam_data.clip_end = 1e5 * reach
        scene.render.filepath = f"{a.out}/{i:04d}.exr"
        t = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        times.append(time.perf_counter() - t)
    json.dump({"load_seconds": load, "render_seconds": times, "views": list(pick)}, sys.stdout)
    print()


if __name__ == "__main__":
    main()
