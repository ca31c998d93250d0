#!/usr/bin/env python3
"""Generates the instanced example scenes (issue 24; pure Python 3.11, no dependencies).

    python3 rooms/tools/gen_instanced.py [--trees 10000] [--tree-triangles 100000]

Writes
  rooms/forest/       a forest of --trees copies of one tree of about --tree-triangles
                      triangles (10^9 triangles in all by default) on a 1 km ground: the
                      rendering scale test. The tree and the scene file are generated (not in
                      git: tree.obj is about 4 MB and scene.toml 1 MB).
  rooms/city_block/   a city block for radio: 48 buildings, all copies of one unit box
                      stretched per axis, some with a brick override, on a ground plane.
  rooms/auditorium/   a 24 x 18 x 9 m hall whose 192 seats are copies of the "seat" object of
                      its own OBJ (room acoustics).

Conventions as gen_rooms.py: metres, +z up; a room shell and the obstacles in it are wound
with normals out of the air (the seats' normals point into the seat); the buildings and trees,
outdoors, are wound with normals out of the solid, the ground faces up.
"""
import argparse
import math
import os
import random

HERE = os.path.dirname(os.path.abspath(__file__))
ROOMS = os.path.dirname(HERE)


def f(x):
    """Short OBJ/TOML float."""
    s = f"{x:.4f}".rstrip("0")
    return s + "0" if s.endswith(".") else s


def v3(p):
    return "[" + ", ".join(f(c) for c in p) + "]"


class Obj:
    """An OBJ being written: vertices, and faces grouped by object and material."""

    def __init__(self, mtllib=None):
        self.lines = [f"mtllib {mtllib}"] if mtllib else []
        self.count = 0

    def vertex(self, p):
        self.lines.append("v " + " ".join(f(c) for c in p))
        self.count += 1
        return self.count

    def obj(self, name):
        self.lines.append(f"o {name}")

    def mtl(self, name):
        self.lines.append(f"usemtl {name}")

    def face(self, *idx):
        self.lines.append("f " + " ".join(str(i) for i in idx))

    def box(self, lo, hi, outward=True):
        """A closed box; outward normals unless `outward` is false."""
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        c = [self.vertex((x, y, z)) for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
        # c index: x + 2y + 4z
        faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
        for q in faces:
            q = q if outward else q[::-1]
            self.face(*(c[i] for i in q))

    def write(self, path):
        with open(path, "w") as fh:
            fh.write("\n".join(self.lines) + "\n")


def ellipsoid(o, centre, radii, nu, nv):
    """A closed UV ellipsoid, outward normals, poles shared: 2 nu (nv - 1) triangles."""
    cx, cy, cz = centre
    rx, ry, rz = radii
    top = o.vertex((cx, cy, cz + rz))
    rings = []
    for j in range(1, nv):
        th = math.pi * j / nv
        ring = []
        for i in range(nu):
            ph = 2 * math.pi * i / nu
            ring.append(o.vertex((cx + rx * math.sin(th) * math.cos(ph), cy + ry * math.sin(th) * math.sin(ph),
                                  cz + rz * math.cos(th))))
        rings.append(ring)
    bottom = o.vertex((cx, cy, cz - rz))
    for i in range(nu):
        i2 = (i + 1) % nu
        o.face(top, rings[0][i], rings[0][i2])
        for j in range(nv - 2):
            a, b, c, d = rings[j][i], rings[j + 1][i], rings[j + 1][i2], rings[j][i2]
            o.face(a, b, c)
            o.face(a, c, d)
        o.face(bottom, rings[-1][i2], rings[-1][i])
    return 2 * nu * (nv - 1)


def cylinder(o, radius, height, nu, nh):
    """A closed cylinder on z = 0, outward normals: 2 nu nh + 2 nu triangles."""
    rings = [[o.vertex((radius * math.cos(2 * math.pi * i / nu), radius * math.sin(2 * math.pi * i / nu),
                        height * k / nh)) for i in range(nu)] for k in range(nh + 1)]
    for k in range(nh):
        for i in range(nu):
            i2 = (i + 1) % nu
            a, b, c, d = rings[k][i], rings[k][i2], rings[k + 1][i2], rings[k + 1][i]
            o.face(a, b, c)
            o.face(a, c, d)
    lo, hi = o.vertex((0, 0, 0)), o.vertex((0, 0, height))
    for i in range(nu):
        i2 = (i + 1) % nu
        o.face(lo, rings[0][i2], rings[0][i])
        o.face(hi, rings[nh][i], rings[nh][i2])
    return 2 * nu * nh + 2 * nu


def forest(trees, tree_triangles):
    d = os.path.join(ROOMS, "forest")
    os.makedirs(d, exist_ok=True)
    o = Obj("tree.mtl")
    o.obj("tree")
    o.mtl("bark")
    n = cylinder(o, 0.25, 4.0, 48, 20)
    o.mtl("foliage")
    blobs = [((0, 0, 6.5), (2.4, 2.4, 3.0)), ((1.2, 0.6, 5.0), (1.6, 1.5, 1.6)),
             ((-1.1, 0.8, 5.2), (1.5, 1.7, 1.6)), ((0.2, -1.3, 5.1), (1.7, 1.4, 1.5)),
             ((0.5, 0.4, 8.6), (1.5, 1.5, 1.6)), ((-0.8, -0.6, 7.6), (1.5, 1.4, 1.5)),
             ((1.0, -0.5, 7.4), (1.4, 1.6, 1.4)), ((-0.3, 1.2, 7.8), (1.3, 1.3, 1.5))]
    per_blob = max(200, (tree_triangles - n) // len(blobs))
    # 2 nu (nv - 1) triangles with nu = 2 nv.
    nv = max(4, int(round((1 + math.sqrt(1 + 4 * per_blob)) / 4)))
    for centre, radii in blobs:
        n += ellipsoid(o, centre, radii, 2 * nv, nv)
    o.write(os.path.join(d, "tree.obj"))
    with open(os.path.join(d, "tree.mtl"), "w") as fh:
        fh.write("newmtl bark\nKd 0.30 0.20 0.12\nnewmtl foliage\nKd 0.12 0.35 0.10\n")
    side = math.ceil(math.sqrt(trees))
    spacing = 8.0
    half = side * spacing / 2 + 20
    g = Obj("ground.mtl")
    g.obj("ground")
    g.mtl("grass")
    c = [g.vertex((x, y, 0.0)) for (x, y) in ((-half, -half), (half, -half), (half, half), (-half, half))]
    g.face(*c)
    g.write(os.path.join(d, "ground.obj"))
    with open(os.path.join(d, "ground.mtl"), "w") as fh:
        fh.write("newmtl grass\nKd 0.25 0.30 0.12\n")
    rng = random.Random(24)
    lines = [
        f"# A forest: {trees} copies of one {n}-triangle tree ({n * trees} triangles),",
        "# written by rooms/tools/gen_instanced.py. Render test of issue 24:",
        "#   /usr/bin/time -v propsim render rooms/forest/scene.toml -o forest.png",
        'obj = "ground.obj"', "",
        "[camera]", f"eye = {v3((-half * 0.55, -half * 0.55, 40.0))}", "target = [0.0, 0.0, 0.0]",
        "fov_deg = 50.0", "",
        "[render]", "width = 640", "height = 360", "spp = 16", "max_depth = 3",
        "background = [0.55, 0.65, 0.85]", "",
        "[[lights]]", f"position = {v3((2000.0, -1500.0, 3000.0))}", "intensity = [4.0e7, 3.8e7, 3.4e7]", "",
    ]
    for k in range(trees):
        i, j = k % side, k // side
        x = (i - (side - 1) / 2) * spacing + rng.uniform(-2, 2)
        y = (j - (side - 1) / 2) * spacing + rng.uniform(-2, 2)
        lines.append(
            f'[[instances]]\nmesh = "tree.obj"\ntranslate = {v3((x, y, 0.0))}\n'
            f"rotate_euler_deg = [0.0, 0.0, {f(rng.uniform(0, 360))}]\nscale = {f(rng.uniform(0.7, 1.3))}"
        )
    with open(os.path.join(d, "scene.toml"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"forest: {trees} trees of {n} triangles = {n * trees} triangles")


def city_block():
    d = os.path.join(ROOMS, "city_block")
    os.makedirs(d, exist_ok=True)
    b = Obj()
    b.obj("building")
    # A unit building [-0.5, 0.5]^2 x [0, 1], normals out of the building: walls concrete,
    # the +y facade glass, the roof concrete.
    c = [b.vertex((x, y, z)) for z in (0.0, 1.0) for y in (-0.5, 0.5) for x in (-0.5, 0.5)]
    b.mtl("concrete")
    for q in [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (0, 4, 6, 2), (1, 3, 7, 5)]:
        b.face(*(c[i] for i in q))
    b.mtl("glass")
    b.face(*(c[i] for i in (2, 6, 7, 3)))
    b.write(os.path.join(d, "building.obj"))
    g = Obj()
    g.obj("ground")
    g.mtl("medium_dry_ground")
    q = [g.vertex((x, y, 0.0)) for (x, y) in ((-120, -120), (120, -120), (120, 120), (-120, 120))]
    g.face(*q)
    g.write(os.path.join(d, "ground.obj"))
    rng = random.Random(7)
    lines = [
        "# A city block for radio: 48 buildings, all copies of one unit box (building.obj)",
        "# stretched per axis, every third in brick; streets 16 m wide every 40 m.",
        "# Written by rooms/tools/gen_instanced.py.",
        'obj = "ground.obj"', "",
        "[camera]", "eye = [-150.0, -170.0, 140.0]", "target = [0.0, 0.0, 0.0]", "fov_deg = 45.0", "",
        "[render]", "width = 640", "height = 400", "spp = 16", "max_depth = 3",
        "background = [0.55, 0.65, 0.8]", "",
        "[[lights]]", "position = [120.0, -200.0, 300.0]", "intensity = [200000.0, 190000.0, 170000.0]", "",
        "[rf]", "freq_ghz = 3.5", "max_depth = 3", "rays = 1000000", "",
        "[[rf.transmitters]]", 'name = "TX1"', "position = [0.0, 0.0, 12.0]", "power_dbm = 30.0",
        'antenna = "isotropic"', 'polarization = "vertical"', "",
        "[rf.grid]", "height_m = 1.5", "cell_m = 2.0", "min = [-100.0, -100.0]", "max = [100.0, 100.0]", "",
    ]
    k = 0
    for bx in (-100, -60, -20, 20, 60):
        for by in (-100, -60, -20, 20, 60):
            if (bx, by) == (-20, -20):
                continue  # the square where the transmitter stands
            for sx, sy in ((0.25, 0.25), (0.75, 0.75)):
                if k >= 48:
                    break
                w, dd, h = rng.uniform(8, 11), rng.uniform(8, 11), rng.uniform(8, 40)
                cx, cy = bx + 24 * sx + 2, by + 24 * sy + 2
                k += 1
                lines.append(f'[[instances]]\nname = "B{k:02d}"\nmesh = "building.obj"\ntranslate = {v3((cx, cy, 0.0))}\n'
                             f"scale = {v3((w, dd, h))}" + ('\nmaterial = "brick"' if k % 3 == 0 else ""))
    with open(os.path.join(d, "scene.toml"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"city block: {k} buildings")


def auditorium():
    d = os.path.join(ROOMS, "auditorium")
    os.makedirs(d, exist_ok=True)
    o = Obj()
    L, W, H = 24.0, 18.0, 9.0
    o.obj("hall")
    c = [o.vertex((x, y, z)) for z in (0.0, H) for y in (0.0, W) for x in (0.0, L)]
    for name, q in [("audience_floor_wood", (0, 2, 3, 1)), ("ceiling_board", (4, 5, 7, 6)),
                    ("plasterboard", (0, 1, 5, 4)), ("plasterboard", (2, 6, 7, 3)),
                    ("plasterboard", (0, 4, 6, 2)), ("plasterboard", (1, 3, 7, 5))]:
        # Outward normals: out of the air, the rooms' convention.
        o.mtl(name)
        o.face(*(c[i] for i in q))
    # The seat: an L-shaped prism (seat 0.5 deep, 0.45 high; back 0.1 deep, 0.9 high), 0.5 wide
    # along x, facing -y (the stage at low y); normals into the seat (out of the air).
    o.obj("seat")
    o.mtl("seats_upholstered_empty")
    prof = [(0.0, 0.0), (0.5, 0.0), (0.5, 0.45), (0.1, 0.45), (0.1, 0.9), (0.0, 0.9)]
    # profile points (y', z) with y' = distance behind the front edge; the back is at the rear.
    prof = [(0.5 - y, z) for (y, z) in prof]
    left = [o.vertex((0.0, y, z)) for (y, z) in prof]
    right = [o.vertex((0.5, y, z)) for (y, z) in prof]
    # Caps (the L split into a 4-gon and a 4-gon): wound so normals point into the seat.
    for cap, flip in ((left, True), (right, False)):
        for tri in ((0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 5)):
            t = [cap[i] for i in tri]
            o.face(*(t[::-1] if flip else t))
    n = len(prof)
    for i in range(n):
        i2 = (i + 1) % n
        o.face(left[i], left[i2], right[i2], right[i])
    o.write(os.path.join(d, "auditorium.obj"))
    lines = [
        "# An auditorium for room acoustics: a 24 x 18 x 9 m hall and 192 seats, copies of the",
        "# \"seat\" object of auditorium.obj (which, as a prototype, leaves the hall itself).",
        "# Written by rooms/tools/gen_instanced.py.",
        'obj = "auditorium.obj"', "",
        "[camera]", "eye = [12.0, 17.0, 6.0]", "target = [12.0, 2.0, 1.0]", "fov_deg = 60.0", "",
        "[render]", "width = 640", "height = 360", "spp = 16", "max_depth = 3", "",
        "[[lights]]", "position = [12.0, 9.0, 8.5]", "intensity = [400.0, 390.0, 370.0]", "",
        "[acoustic]", "rays = 100000", "",
        "[[acoustic.sources]]", 'name = "S1"', "position = [12.0, 2.5, 1.6]", "",
        "[[acoustic.receivers]]", 'name = "R1"', "position = [9.3, 8.3, 1.2]", "",
        "[[acoustic.receivers]]", 'name = "R2"', "position = [15.3, 14.3, 1.2]", "",
        "[[acoustic.receivers]]", 'name = "R3"', "position = [4.3, 11.3, 1.2]", "",
    ]
    for row in range(12):
        for col in range(16):
            x = 4.0 + col * 1.0 + (0.5 if col >= 8 else 0.0) - 0.25
            y = 6.0 + row * 1.0
            lines.append(f'[[instances]]\nname = "row{row + 1:02d}-{col + 1:02d}"\nmesh = "seat"\n'
                         f"translate = {v3((x, y, 0.0))}")
    with open(os.path.join(d, "scene.toml"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("auditorium: 192 seats")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trees", type=int, default=10000)
    ap.add_argument("--tree-triangles", type=int, default=100000)
    ap.add_argument("--only", choices=["forest", "city_block", "auditorium"])
    a = ap.parse_args()
    if a.only in (None, "forest"):
        forest(a.trees, a.tree_triangles)
    if a.only in (None, "city_block"):
        city_block()
    if a.only in (None, "auditorium"):
        auditorium()


if __name__ == "__main__":
    main()
