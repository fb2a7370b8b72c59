#!/usr/bin/env python3
"""Write the low-poly UV spheres of scenes/smooth-mesh.toml.

    python3 scenes/meshes/gen_sphere.py

sphere-smooth.obj has a vertex normal per vertex (`f v//vn`); sphere-flat.obj
is the same polygons without normals. Unit radius, centred at the origin,
faces counter-clockwise seen from outside; 12 segments, 8 rings (quads,
triangles at the poles).
"""
import math
import os

SEGMENTS, RINGS = 12, 8
here = os.path.dirname(os.path.abspath(__file__))
verts = [(0.0, 1.0, 0.0)]
for r in range(1, RINGS):
    th = math.pi * r / RINGS
    for s in range(SEGMENTS):
        ph = 2 * math.pi * s / SEGMENTS
        verts.append((math.sin(th) * math.cos(ph), math.cos(th), -math.sin(th) * math.sin(ph)))
verts.append((0.0, -1.0, 0.0))
south = len(verts)


def ring(r, s):  # 1-based index of vertex s of ring r (1..RINGS-1)
    return 2 + (r - 1) * SEGMENTS + s % SEGMENTS


faces = []
for s in range(SEGMENTS):
    faces.append([1, ring(1, s), ring(1, s + 1)])
    for r in range(1, RINGS - 1):
        faces.append([ring(r, s), ring(r + 1, s), ring(r + 1, s + 1), ring(r, s + 1)])
    faces.append([ring(RINGS - 1, s), south, ring(RINGS - 1, s + 1)])

for name, smooth in (("sphere-smooth.obj", True), ("sphere-flat.obj", False)):
    with open(os.path.join(here, name), "w") as f:
        f.write(f"# {SEGMENTS}x{RINGS} UV sphere, written by gen_sphere.py\n")
        for v in verts:
            f.write("v %.6f %.6f %.6f\n" % v)
        if smooth:
            for v in verts:  # on a unit sphere the normal is the position
                f.write("vn %.6f %.6f %.6f\n" % v)
        for face in faces:
            f.write("f " + " ".join(f"{i}//{i}" if smooth else str(i) for i in face) + "\n")
