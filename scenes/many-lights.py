# Writes scenes/many-lights.toml (deterministic: a fixed LCG). Corners on
# a grid of 1/1024 so that each quad is an exact parallelogram (one emitter).
import math
state = 12345
def rnd():
    global state
    state = (state * 6364136223846793005 + 1442695040888963407) % (1 << 64)
    return (state >> 40) / float(1 << 24)
def norm(v):
    l = math.sqrt(sum(c*c for c in v)); return [c/l for c in v]
def cross(a,b): return [a[1]*b[2]-a[2]*b[1], a[2]*b[0]-a[0]*b[2], a[0]*b[1]-a[1]*b[0]]
def v(p): return "[" + ", ".join(repr(float(c)) for c in p) + "]"
N = 300
out = []
out.append("""# A room lit by 300 small emissive quads of varied power, colour, size
# and orientation, hanging above a white floor among three grey blocks
# (docs/lights.md: many emitters, the light tree). Written by
# scenes/many-lights.py (a fixed seed); y points up, the floor is y = 0, [-6, 6] x [-6, 6].
# About a third of the quads turn their light away from the floor (their
# fronts face up or sideways): a light tree's orientation cones skip them.

name = "many-lights"

[camera]
position = [0.0, 7.0, -10.0]
look_at = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
vfov_deg = 50.0
width = 320
height = 240

[integrator]
max_depth = 3

[materials.floor]
reflectance = [0.8, 0.8, 0.8]

[materials.block]
reflectance = [0.5, 0.5, 0.5]
""")
# Lamp materials: 12 colours x powers.
mats = []
for k in range(24):
    hue = rnd()
    c = [0.5 + 0.5*math.cos(2*math.pi*(hue + s/3)) for s in range(3)]
    c = [0.25 + 0.75*x for x in c]
    power = math.exp(math.log(2.0) + rnd()*math.log(60.0/2.0))
    mats.append([x*power for x in c])
    out.append(f"[materials.lamp{k}]\nreflectance = [0.0, 0.0, 0.0]\nemission = {v(mats[-1])}\n")
out.append("""[[quad]]
name = "floor"
material = "floor"
vertices = [[-6.0, 0.0, -6.0], [-6.0, 0.0, 6.0], [6.0, 0.0, 6.0], [6.0, 0.0, -6.0]]
""")
# Three blocks (5 visible faces each, no bottom), counterclockwise fronts outward.
def box(name, lo, hi):
    (x0,y0,z0),(x1,y1,z1) = lo, hi
    faces = {
      "top": [[x0,y1,z0],[x0,y1,z1],[x1,y1,z1],[x1,y1,z0]],
      "front": [[x0,y0,z0],[x0,y1,z0],[x1,y1,z0],[x1,y0,z0]],
      "back": [[x1,y0,z1],[x1,y1,z1],[x0,y1,z1],[x0,y0,z1]],
      "left": [[x0,y0,z1],[x0,y1,z1],[x0,y1,z0],[x0,y0,z0]],
      "right": [[x1,y0,z0],[x1,y1,z0],[x1,y1,z1],[x1,y0,z1]],
    }
    for fn, q in faces.items():
        out.append(f'[[quad]]\nname = "{name}_{fn}"\nmaterial = "block"\nvertices = [{", ".join(v(p) for p in q)}]\n')
box("block_a", [-3.5, 0, -1.0], [-2.0, 1.5, 0.5])
box("block_b", [1.0, 0, 1.5], [2.2, 2.5, 2.7])
box("block_c", [2.5, 0, -3.0], [3.3, 0.8, -2.2])
for k in range(N):
    c = [-5.5 + 11*rnd(), 0.6 + 3.4*rnd(), -5.5 + 11*rnd()]
    # A direction: 2/3 roughly downward, 1/3 anywhere.
    if rnd() < 0.67:
        n = norm([rnd()-0.5, -1.0 - rnd(), rnd()-0.5])
    else:
        while True:
            n = [2*rnd()-1, 2*rnd()-1, 2*rnd()-1]
            if 0.05 < sum(x*x for x in n) < 1: break
        n = norm(n)
    t = norm(cross(n, [0.3, 0.5, 0.8]))
    b = cross(n, t)
    s = 0.06 + 0.2*rnd()
    q = lambda x: round(x * 1024) / 1024
    c0 = [q(c[i] - s*(t[i] + b[i])) for i in range(3)]
    e1 = [q(2*s*t[i]) for i in range(3)]
    e2 = [q(2*s*b[i]) for i in range(3)]
    corners = [c0, [c0[i]+e1[i] for i in range(3)], [c0[i]+e1[i]+e2[i] for i in range(3)], [c0[i]+e2[i] for i in range(3)]]
    # Counterclockwise seen from n: (v1-v0)x(v2-v0) = t x b * ... check orientation.
    e1 = [corners[1][i]-corners[0][i] for i in range(3)]
    e2 = [corners[2][i]-corners[0][i] for i in range(3)]
    if sum(x*y for x,y in zip(cross(e1,e2), n)) < 0:
        corners.reverse()
    m = int(rnd()*len(mats)) % len(mats)
    out.append(f'[[quad]]\nmaterial = "lamp{m}"\nvertices = [{", ".join(v(p) for p in corners)}]\n')
open(__import__("os").path.join(__import__("os").path.dirname(__file__), "many-lights.toml"), "w").write("\n".join(out))
