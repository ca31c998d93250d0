#!/usr/bin/env python3
"""Generates the propsim example scenes under rooms/ (pure Python 3.11, no dependencies).

    python3 rooms/tools/gen_rooms.py [--shared /work/shared/rooms]

Writes rooms/{cornell_box,shoebox,l_room,street_canyon}/ (OBJ + MTL + scene.toml) and
rooms/{bras_cr2,bras_cr4}/ (OBJ/MTL/ATTRIBUTION copied unchanged from the shared BRAS
conversion, scene.toml written from the CR*.json), then runs the mesh checks of objcheck.py.

Conventions: metres, +z up, right-handed. Faces are wound (right-hand rule) so that the normal
points OUT of the air volume: a room shell's normals point away from the room interior (the
signed volume of the shell is positive), an obstacle inside a room (the Cornell blocks) has
normals pointing into the obstacle. Two documented exceptions, both as requested in the brief
or fixed by upstream data: the street-canyon buildings are ordinary outward-wound boxes
(BUILDING_NORMALS_OUT below) with an up-facing ground, and the BRAS obstacles keep their upstream
winding (out of the obstacle).
"""
import argparse
import json
import math
import os
import shutil
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOMS = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import objcheck  # noqa: E402

# Street-canyon buildings: True = normals point out of each building into the air (as the brief
# asked for this scene); False = the room convention (normals out of the air, into the building).
BUILDING_NORMALS_OUT = True
# Cornell blocks: False = room convention (normals into the block, away from the air).
CORNELL_BLOCK_NORMALS_OUT = False


# ----------------------------------------------------------------------------- helpers

def f(x):
    """TOML/OBJ float: shortest repr that round-trips, always with a decimal point."""
    x = float(x)
    if x == 0:
        x = 0.0
    r = repr(round(x, 6))
    if 'e' in r or 'E' in r:
        r = f'{x:.6f}'.rstrip('0')
        if r.endswith('.'):
            r += '0'
    return r if ('.' in r) else r + '.0'


def vec(v):
    return '[' + ', '.join(f(x) for x in v) + ']'


def srgb_to_linear(hexstr):
    h = hexstr.lstrip('#')
    out = []
    for i in (0, 2, 4):
        c = int(h[i:i + 2], 16) / 255.0
        out.append(round(c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4, 4))
    return out


def signed_volume(verts, faces):
    vol = 0.0
    for face in faces:
        for k in range(1, len(face) - 1):
            a, b, c = verts[face[0]], verts[face[k]], verts[face[k + 1]]
            vol += objcheck.dot(a, objcheck.cross(b, c)) / 6.0
    return vol


class Part:
    """One `o` object: its own vertices and usemtl groups of faces (local 0-based indices)."""

    def __init__(self, name, comment=''):
        self.name, self.comment = name, comment
        self.verts, self.vcomments, self.groups = [], [], []

    def v(self, p, comment=''):
        self.verts.append(tuple(float(x) for x in p))
        self.vcomments.append(comment)
        return len(self.verts) - 1

    def face(self, mtl, idx):
        if not self.groups or self.groups[-1][0] != mtl:
            self.groups.append((mtl, []))
        self.groups[-1][1].append(tuple(idx))

    def all_faces(self):
        return [fc for _, fs in self.groups for fc in fs]

    def orient(self, outward):
        """Flip every face if the closed part's signed volume has the wrong sign."""
        vol = signed_volume(self.verts, self.all_faces())
        if (vol > 0) != outward:
            self.groups = [(m, [tuple(reversed(fc)) for fc in fs]) for m, fs in self.groups]
        return abs(vol)


def write_obj(path, header, mtllib, parts):
    lines = ['# ' + h for h in header] + [f'mtllib {mtllib}', '']
    base = 1
    for p in parts:
        lines.append(f'o {p.name}')
        if p.comment:
            lines += ['# ' + c for c in p.comment.split('\n')]
        for (x, y, z), c in zip(p.verts, p.vcomments):
            lines.append(f'v {f(x)} {f(y)} {f(z)}' + (f'  # {c}' if c else ''))
        for mtl, faces in p.groups:
            lines.append(f'usemtl {mtl}')
            for fc in faces:
                lines.append('f ' + ' '.join(str(base + i) for i in fc))
        base += len(p.verts)
        lines.append('')
    with open(path, 'w') as fh:
        fh.write('\n'.join(lines))


def write_mtl(path, header, mats):
    """mats: list of (name, kd, extra lines)."""
    lines = ['# ' + h for h in header] + ['']
    for name, kd, extra in mats:
        lines += [f'newmtl {name}', f'Kd {kd[0]:.4f} {kd[1]:.4f} {kd[2]:.4f}', 'Ka 0 0 0',
                  'Ks 0 0 0', 'd 1', 'illum 1'] + list(extra) + ['']
    with open(path, 'w') as fh:
        fh.write('\n'.join(lines))


def box_part(name, lo, hi, side_mtl, comment=''):
    """Axis-aligned box with its own 8 vertices. side_mtl: dict with keys
    bottom, top, south (y=min), east (x=max), north (y=max), west (x=min) -> usemtl name.
    Faces are wound outward (normals out of the box); call orient() to change."""
    p = Part(name, comment)
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    for z in (z0, z1):
        for (x, y) in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):
            p.v((x, y, z))
    faces = {'bottom': (0, 3, 2, 1), 'top': (4, 5, 6, 7), 'south': (0, 1, 5, 4),
             'east': (1, 2, 6, 5), 'north': (2, 3, 7, 6), 'west': (3, 0, 4, 7)}
    order = sorted(faces, key=lambda k: side_mtl[k])  # group faces by material
    for k in order:
        p.face(side_mtl[k], faces[k])
    return p


def toml_sources(kind, items):
    out = []
    for it in items:
        out.append(f'[[{kind}]]')
        for k, val in it.items():
            if isinstance(val, str):
                out.append(f'{k} = "{val}"')
            elif isinstance(val, (list, tuple)):
                out.append(f'{k} = {vec(val)}')
            elif isinstance(val, float):
                out.append(f'{k} = {f(val)}')
            else:
                out.append(f'{k} = {val}')
        out.append('')
    return out


def write(path, text):
    with open(path, 'w') as fh:
        fh.write(text)


# ----------------------------------------------------------------------------- 1. Cornell box

def cornell():
    d = os.path.join(ROOMS, 'cornell_box')
    os.makedirs(d, exist_ok=True)
    # Original data (Cornell Program of Computer Graphics, "Cornell Box data", mm, y up, camera at
    # z = -800 looking +z, red wall at x ~ 556 on the viewer's left). Mapping to z-up metres,
    # a proper rotation (det +1) plus a shift: X = (556 - x)/1000, Y = z/1000, Z = y/1000.
    # The camera now looks along +Y with +Z up, red wall at X ~ 0 (left), green at X = 0.556.
    def cv(x, y, z):
        return ((556.0 - x) / 1000.0, z / 1000.0, y / 1000.0)

    shell = Part('cornell_shell', 'Room shell: 8 corners of the original data (mm / 1000). The '
                 'classic open front (Y = 0) is closed with\na white front wall. Normals point out '
                 'of the room (away from the air). The red wall of the\noriginal data is slightly '
                 'non-planar (3 mm), so it is written as two explicit triangles.')
    c = {}
    for key, p in {
        'f0': (552.8, 0.0, 0.0), 'f1': (0.0, 0.0, 0.0), 'f2': (0.0, 0.0, 559.2), 'f3': (549.6, 0.0, 559.2),
        'c0': (556.0, 548.8, 0.0), 'c1': (0.0, 548.8, 0.0), 'c2': (0.0, 548.8, 559.2), 'c3': (556.0, 548.8, 559.2),
    }.items():
        c[key] = shell.v(cv(*p), {'f0': 'floor front left', 'f1': 'floor front right', 'f2': 'floor back right',
                                  'f3': 'floor back left', 'c0': 'ceiling front left', 'c1': 'ceiling front right',
                                  'c2': 'ceiling back right', 'c3': 'ceiling back left'}[key])
    # faces in original order, wound outward below by orient()
    shell.face('cornell_white', (c['f0'], c['f1'], c['f2'], c['f3']))    # floor
    shell.face('cornell_white', (c['c0'], c['c3'], c['c2'], c['c1']))    # ceiling
    shell.face('cornell_white', (c['f3'], c['f2'], c['c2'], c['c3']))    # back wall
    shell.face('cornell_white', (c['f1'], c['f0'], c['c0'], c['c1']))    # front wall (added)
    shell.face('cornell_red', (c['f0'], c['f3'], c['c3']))              # left (red) wall, tri 1
    shell.face('cornell_red', (c['f0'], c['c3'], c['c0']))              # left (red) wall, tri 2
    shell.face('cornell_green', (c['f2'], c['f1'], c['c1'], c['c2']))    # right (green) wall
    shell_vol = shell.orient(outward=True)

    def block(name, top, h):
        p = Part(name, f'Closed block (own vertices, bottom face included), height {h / 1000} m; '
                 'normals point into the block (away from the air).')
        for (x, z) in top:
            p.v(cv(x, 0.0, z))
        for (x, z) in top:
            p.v(cv(x, h, z))
        p.face('cornell_white', (4, 5, 6, 7))
        p.face('cornell_white', (0, 3, 2, 1))
        for i in range(4):
            j = (i + 1) % 4
            p.face('cornell_white', (i, j, j + 4, i + 4))
        vol = p.orient(outward=CORNELL_BLOCK_NORMALS_OUT)
        return p, vol

    short, vs = block('short_block', [(130.0, 65.0), (82.0, 225.0), (240.0, 272.0), (290.0, 114.0)], 165.0)
    tall, vt = block('tall_block', [(423.0, 247.0), (265.0, 296.0), (314.0, 456.0), (472.0, 406.0)], 330.0)

    light = Part('light', 'Area light: the original 130 x 105 mm light, moved 1 mm below the ceiling '
                 '(Z = 0.5478). Open quad,\nnormal pointing down (-Z) into the room.')
    zl = 547.8
    for p in [(343.0, zl, 227.0), (343.0, zl, 332.0), (213.0, zl, 332.0), (213.0, zl, 227.0)]:
        light.v(cv(*p))
    light.face('cornell_light', (0, 1, 2, 3))
    n = objcheck.cross(objcheck.sub(light.verts[1], light.verts[0]), objcheck.sub(light.verts[2], light.verts[0]))
    if n[2] > 0:
        light.groups = [(m, [tuple(reversed(fc)) for fc in fs]) for m, fs in light.groups]

    write_obj(os.path.join(d, 'cornell_box.obj'),
              ['Cornell box, closed (front wall added), for propsim. Units: metres, +z up, right-handed.',
               'Source data: Cornell University Program of Computer Graphics, "Cornell Box Data"',
               '(https://www.graphics.cornell.edu/online/box/data.html), converted from mm, y up.',
               'Room interior: X in [0, 0.556], Y in [0, 0.5592] (front wall at Y = 0), Z in [0, 0.5488].'],
              'cornell_box.mtl', [shell, short, tall, light])
    write_mtl(os.path.join(d, 'cornell_box.mtl'), ['Cornell box display colours (linear RGB reflectance).'],
              [('cornell_white', (0.73, 0.73, 0.73), []), ('cornell_red', (0.65, 0.05, 0.05), []),
               ('cornell_green', (0.12, 0.45, 0.15), []),
               ('cornell_light', (0.78, 0.78, 0.78), ['Ke 17 12 4'])])
    air = shell_vol - vs - vt
    toml = f'''# Cornell box (closed) - propsim example scene.
# The classic Cornell box converted to metres, +z up; the open front is closed by a white wall so
# the room is watertight. Shell {shell_vol:.5f} m^3, blocks {vs:.5f} + {vt:.5f} m^3, air {air:.5f} m^3.
# All usemtl names are built-in materials (cornell_white/red/green/light); the light quad hangs 1 mm
# below the ceiling, facing down.
obj = "cornell_box.obj"

[camera]
# The classic camera sits 0.8 m in front of the opening (Y = -0.8) with a 39.3 degree field of view.
# Inside the closed box the camera is 5 mm behind the front wall; with 40 degrees it would see only
# the back wall, so the field of view is widened so that the side walls, floor and ceiling frame the
# view as in the classic image.
eye = [0.278, 0.005, 0.273]
target = [0.278, 0.5592, 0.273]
up = [0.0, 0.0, 1.0]
fov_deg = 75.0

[render]
width = 512
height = 512
spp = 64
max_depth = 8
background = [0.0, 0.0, 0.0]

[acoustic]
# A 0.55 m box: for completeness and smoke tests only (first reflections arrive within ~3 ms).
temperature_c = 20.0
relative_humidity_percent = 50.0
pressure_kpa = 101.325
rays = 20000
max_time_s = 0.1

[[acoustic.sources]]
name = "S1"
position = [0.45, 0.45, 0.25]

[[acoustic.receivers]]
name = "R1"
position = [0.12, 0.12, 0.2]
radius_m = 0.03

[rf]
# 60 GHz (wavelength 5 mm, ~100 wavelengths across the box) so ray optics is not absurd.
freq_ghz = 60.0
max_depth = 3
rays = 200000

[[rf.transmitters]]
name = "TX1"
position = [0.278, 0.3, 0.45]
freq_ghz = 60.0
power_dbm = 0.0
antenna = "isotropic"
polarization = "vertical"

[rf.grid]
height_m = 0.1
cell_m = 0.02
'''
    write(os.path.join(d, 'scene.toml'), toml)
    pts = [('camera', (0.278, 0.005, 0.273)), ('S1', (0.45, 0.45, 0.25)), ('R1', (0.12, 0.12, 0.2)),
           ('TX1', (0.278, 0.3, 0.45))]
    return os.path.join(d, 'cornell_box.obj'), pts, {'air_m3': air}


# ----------------------------------------------------------------------------- 2. shoebox

def shoebox():
    d = os.path.join(ROOMS, 'shoebox')
    os.makedirs(d, exist_ok=True)
    p = Part('shoebox', '10 x 8 x 3 m box, x in [0,10], y in [0,8], z in [0,3]. Normals point out of the room.')
    for z in (0.0, 3.0):
        for (x, y) in ((0.0, 0.0), (10.0, 0.0), (10.0, 8.0), (0.0, 8.0)):
            p.v((x, y, z))
    tris = {
        'floor': [(0, 2, 1), (0, 3, 2)],
        'ceiling': [(4, 5, 6), (4, 6, 7)],
        'walls': [(0, 1, 5), (0, 5, 4), (1, 2, 6), (1, 6, 5), (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7)],
    }
    for m in ('floor', 'walls', 'ceiling'):
        for t in tris[m]:
            p.face(m, t)
    vol = p.orient(outward=True)
    write_obj(os.path.join(d, 'shoebox.obj'),
              ['Shoebox room for propsim: 10 x 8 x 3 m, 12 triangles. Units: metres, +z up.'],
              'shoebox.mtl', [p])
    write_mtl(os.path.join(d, 'shoebox.mtl'), ['Shoebox display colours (linear RGB).'],
              [('floor', (0.35, 0.3, 0.25), []), ('walls', (0.7, 0.7, 0.7), []), ('ceiling', (0.8, 0.8, 0.8), [])])
    S = 2 * (10 * 8 + 10 * 3 + 8 * 3)
    c = 343.0
    k = 24 * math.log(10) / c
    sab = k * vol / (S * 0.1)
    eyr = k * vol / (-S * math.log(1 - 0.1))
    toml = f'''# Shoebox - propsim acoustics test case.
# 10 x 8 x 3 m (V = {vol:.1f} m^3, S = {S:.1f} m^2), every surface absorption 0.1 in all bands,
# scattering 0.5. Reference decay times without air absorption, c = 343 m/s:
#   Sabine T = 24 ln(10) V / (c S a)          = {sab:.3f} s
#   Eyring T = 24 ln(10) V / (-c S ln(1 - a)) = {eyr:.3f} s
# (compare the simulated T with air absorption switched off, or correct for 4 m V).
obj = "shoebox.obj"

[surfaces]
floor = "shoebox_absorber"
walls = "shoebox_absorber"
ceiling = "shoebox_absorber"

[materials.shoebox_absorber]
description = "Uniform test absorber: absorption 0.1 and scattering 0.5 in every octave band"
source = "Synthetic test material for the shoebox reverberation test (Sabine/Eyring comparison)"
absorption = [0.1, 0.1, 0.1, 0.1, 0.1, 0.1]
scattering = [0.5, 0.5, 0.5, 0.5, 0.5, 0.5]
itu = "concrete"
color = [0.7, 0.7, 0.7]
kind = "diffuse"

[camera]
eye = [0.6, 0.6, 1.7]
target = [7.0, 5.0, 1.2]
up = [0.0, 0.0, 1.0]
fov_deg = 70.0

[render]
width = 640
height = 480
spp = 64
max_depth = 8
background = [0.0, 0.0, 0.0]

[[lights]]
position = [5.0, 4.0, 2.8]
intensity = [30.0, 30.0, 30.0]

[acoustic]
temperature_c = 20.0
relative_humidity_percent = 50.0
pressure_kpa = 101.325
rays = 100000
max_time_s = 2.0

[[acoustic.sources]]
name = "S1"
position = [2.0, 3.0, 1.5]

[[acoustic.receivers]]
name = "R1"
position = [7.0, 5.0, 1.2]
radius_m = 0.1

[rf]
freq_ghz = 3.5
max_depth = 3
rays = 1000000

[[rf.transmitters]]
name = "TX1"
position = [1.0, 1.0, 2.5]
freq_ghz = 3.5
power_dbm = 20.0
antenna = "isotropic"
polarization = "vertical"

[rf.grid]
height_m = 1.5
cell_m = 0.25

[[rf.receivers]]
name = "P1"
position = [7.0, 5.0, 1.2]
'''
    write(os.path.join(d, 'scene.toml'), toml)
    pts = [('camera', (0.6, 0.6, 1.7)), ('S1', (2, 3, 1.5)), ('R1', (7, 5, 1.2)), ('TX1', (1, 1, 2.5)),
           ('light', (5, 4, 2.8))]
    return os.path.join(d, 'shoebox.obj'), pts, {'sabine_s': sab, 'eyring_s': eyr}


# ----------------------------------------------------------------------------- 3. L-shaped room

def l_room():
    d = os.path.join(ROOMS, 'l_room')
    os.makedirs(d, exist_ok=True)
    foot = [(0.0, 0.0), (8.0, 0.0), (8.0, 4.0), (4.0, 4.0), (4.0, 8.0), (0.0, 8.0)]
    H = 3.0
    p = Part('l_room', 'L-shaped room, 3 m high. Footprint polygon (counter-clockwise seen from above):\n'
             '(0,0) (8,0) (8,4) (4,4) (4,8) (0,8); (4,4) is the inner (reflex) corner.\n'
             'Vertices 1-6 floor corners, 7-12 ceiling corners; floor, ceiling and walls share them,\n'
             'so there is no T-junction. Normals point out of the room.')
    for z in (0.0, H):
        for (x, y) in foot:
            p.v((x, y, z), f'{"floor" if z == 0 else "ceiling"} corner ({x:g}, {y:g})')
    # floor/ceiling triangulation of the L (all triangles inside the polygon)
    ftris = [(0, 1, 2), (0, 2, 3), (0, 3, 5), (5, 3, 4)]
    for t in ftris:
        p.face('floorboard', (t[0], t[2], t[1]))  # floor: clockwise from above -> normal -z
    for i in range(6):
        j = (i + 1) % 6
        p.face('plasterboard', (i, j, j + 6, i + 6))
    for t in ftris:
        p.face('ceiling_board', (t[0] + 6, t[1] + 6, t[2] + 6))
    vol = p.orient(outward=True)
    write_obj(os.path.join(d, 'l_room.obj'),
              ['L-shaped room for propsim: an 8 x 4 m leg along x and a 4 x 8 m leg along y, 3 m high.',
               'Units: metres, +z up. 20 triangles (floor 4, ceiling 4, walls 6 quads).'],
              'l_room.mtl', [p])
    write_mtl(os.path.join(d, 'l_room.mtl'), ['L room display colours (linear RGB).'],
              [('floorboard', (0.45, 0.3, 0.18), []), ('plasterboard', (0.75, 0.75, 0.72), []),
               ('ceiling_board', (0.8, 0.8, 0.8), [])])
    toml = f'''# L-shaped room - propsim example scene for occlusion / diffraction-free shadow zones.
# Footprint (0,0) (8,0) (8,4) (4,4) (4,8) (0,8), 3 m high: floor 48 m^2, V = {vol:.1f} m^3.
# S1 is in the x-leg; R1 sees it directly, R2 in the y-leg is around the corner: the segment
# S1-R2 passes x = y = 4.5, behind the inner corner (4, 4), so there is no line of sight.
# Walls plasterboard, floor floorboard, ceiling ceiling_board (built-in materials).
obj = "l_room.obj"

[camera]
# From the far end of the x-leg looking down it towards the corner.
eye = [7.7, 0.4, 1.7]
target = [1.0, 3.0, 1.2]
up = [0.0, 0.0, 1.0]
fov_deg = 70.0

[render]
width = 640
height = 480
spp = 64
max_depth = 8
background = [0.0, 0.0, 0.0]

[[lights]]
position = [6.0, 2.0, 2.8]
intensity = [15.0, 15.0, 15.0]

[[lights]]
position = [2.0, 6.0, 2.8]
intensity = [15.0, 15.0, 15.0]

[acoustic]
temperature_c = 20.0
relative_humidity_percent = 50.0
pressure_kpa = 101.325
rays = 100000
max_time_s = 3.0

[[acoustic.sources]]
name = "S1"
position = [7.0, 2.0, 1.5]

[[acoustic.receivers]]
name = "R1_line_of_sight"
position = [2.0, 2.0, 1.2]
radius_m = 0.1

[[acoustic.receivers]]
name = "R2_around_corner"
position = [2.0, 7.0, 1.2]
radius_m = 0.1

[rf]
freq_ghz = 3.5
max_depth = 3
rays = 1000000

[[rf.transmitters]]
name = "TX1"
position = [7.0, 2.0, 2.5]
freq_ghz = 3.5
power_dbm = 20.0
antenna = "dipole"
polarization = "vertical"

[rf.grid]
height_m = 1.5
cell_m = 0.25

[[rf.receivers]]
name = "P_los"
position = [2.0, 2.0, 1.2]

[[rf.receivers]]
name = "P_nlos"
position = [2.0, 7.0, 1.2]
'''
    write(os.path.join(d, 'scene.toml'), toml)
    pts = [('camera', (7.7, 0.4, 1.7)), ('S1', (7, 2, 1.5)), ('R1', (2, 2, 1.2)), ('R2', (2, 7, 1.2)),
           ('TX1', (7, 2, 2.5)), ('light1', (6, 2, 2.8)), ('light2', (2, 6, 2.8))]
    return os.path.join(d, 'l_room.obj'), pts, {}


# ----------------------------------------------------------------------------- 4. street canyon

BUILDINGS = [
    # name, (x0, y0), (x1, y1), height, facades in glass
    ('B01_NE', (10.0, 10.0), (40.0, 34.0), 25.0, ['south', 'west']),
    ('B02_NE', (45.0, 10.0), (82.0, 30.0), 15.0, []),
    ('B03_NE', (12.0, 40.0), (55.0, 56.0), 35.0, []),
    ('B04_NW', (-38.0, 10.0), (-10.0, 32.0), 30.0, ['south']),
    ('B05_NW', (-82.0, 10.0), (-43.0, 28.0), 12.0, []),
    ('B06_NW', (-62.0, 38.0), (-20.0, 56.0), 20.0, []),
    ('B07_SE', (10.0, -30.0), (35.0, -10.0), 40.0, ['north', 'west']),
    ('B08_SE', (40.0, -34.0), (76.0, -10.0), 18.0, []),
    ('B09_SE', (20.0, -56.0), (62.0, -40.0), 10.0, []),
    ('B10_SW', (-35.0, -28.0), (-10.0, -10.0), 22.0, ['north']),
    ('B11_SW', (-80.0, -32.0), (-40.0, -10.0), 28.0, []),
    ('B12_SW', (-52.0, -55.0), (-15.0, -36.0), 14.0, []),
]


def street_canyon():
    d = os.path.join(ROOMS, 'street_canyon')
    os.makedirs(d, exist_ok=True)
    g = Part('ground', 'Ground plane, x in [-90, 90], y in [-60, 60], z = 0 (open quad, normal +z, up into the air).')
    for (x, y) in ((-90.0, -60.0), (90.0, -60.0), (90.0, 60.0), (-90.0, 60.0)):
        g.v((x, y, 0.0))
    g.face('medium_dry_ground', (0, 1, 2, 3))
    parts = [g]
    vols = {}
    for name, (x0, y0), (x1, y1), h, glass in BUILDINGS:
        mt = {k: ('glass' if k in glass else 'concrete') for k in ('bottom', 'top', 'south', 'east', 'north', 'west')}
        desc = (f'Building {name}: x [{x0:g}, {x1:g}], y [{y0:g}, {y1:g}], height {h:g} m; closed box '
                f'(bottom face on the ground),\nnormals out of the building. Glass facades: '
                f'{", ".join(glass) if glass else "none"}.')
        b = box_part(name, (x0, y0, 0.0), (x1, y1, h), mt, desc)
        vols[name] = b.orient(outward=BUILDING_NORMALS_OUT)
        parts.append(b)
    write_obj(os.path.join(d, 'street_canyon.obj'),
              ['Street canyon for propsim radio coverage: 180 x 120 m ground, 12 box buildings 10-40 m high.',
               'Units: metres, +z up. Main street along x: |y| < 10 m (20 m wide between facades);',
               'cross street along y: |x| < 10 m (20 m wide). facades facing the streets partly glass.'],
              'street_canyon.mtl', parts)
    write_mtl(os.path.join(d, 'street_canyon.mtl'), ['Street canyon display colours (linear RGB).'],
              [('medium_dry_ground', (0.25, 0.22, 0.17), []), ('concrete', (0.5, 0.5, 0.48), []),
               ('glass', (0.3, 0.45, 0.55), [])])
    total = sum(vols.values())
    toml = f'''# Street canyon - propsim outdoor radio coverage example.
# 180 x 120 m ground (medium_dry_ground) with 12 closed box buildings, 10-40 m high (concrete; the
# facades of B01, B04, B07 and B10 facing the streets are glass). Main street along x, |y| < 10 m;
# cross street along y, |x| < 10 m; the transmitter stands on the crossing. Building volume
# {total:.0f} m^3. Buildings are wound with normals out of the building (into the air) and the
# ground faces up: unlike the rooms, this scene has no enclosed air volume.
obj = "street_canyon.obj"

[camera]
eye = [-110.0, -150.0, 130.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
fov_deg = 45.0

[render]
width = 960
height = 640
spp = 32
max_depth = 4
background = [0.55, 0.65, 0.8]

[[lights]]
position = [120.0, -200.0, 300.0]
intensity = [200000.0, 190000.0, 170000.0]

[rf]
freq_ghz = 3.5
max_depth = 3
rays = 10000000

[[rf.transmitters]]
name = "TX1"
position = [0.0, 0.0, 10.0]
freq_ghz = 3.5
power_dbm = 30.0
antenna = "isotropic"
polarization = "vertical"

[rf.grid]
height_m = 1.5
cell_m = 1.0
min = [-90.0, -60.0]
max = [90.0, 60.0]

[[rf.receivers]]
name = "P_main_street"
position = [60.0, 0.0, 1.5]

[[rf.receivers]]
name = "P_cross_street"
position = [0.0, -50.0, 1.5]

[[rf.receivers]]
name = "P_behind_B01"
position = [25.0, 37.0, 1.5]
'''
    write(os.path.join(d, 'scene.toml'), toml)
    pts = [('TX1', (0, 0, 10)), ('P_main_street', (60, 0, 1.5)), ('P_cross_street', (0, -50, 1.5)),
           ('P_behind_B01', (25, 37, 1.5))]
    return os.path.join(d, 'street_canyon.obj'), pts, {'building_volumes_m3': vols, 'building_total_m3': total}


# ----------------------------------------------------------------------------- 5. BRAS CR2 / CR4

BRAS_STYLE = {
    # usemtl suffix -> (itu, display colour from the source file's MTL comment, description)
    'concrete': ('concrete', 'Concrete walls and structure'),
    'windows': ('glass', 'Windows (glazing)'),
    'ceiling': ('ceiling_board', 'Suspended ceiling'),
    'plaster': ('plasterboard', 'Plastered walls'),
    'floor': ('floorboard', 'Floor'),
    'linoleum': ('floorboard', 'Linoleum floor covering (seating rake)'),
    'woodPanels': ('wood', 'Wooden wall panels'),
    'parquet': ('floorboard', 'Parquet floor (stage)'),
    'seating': ('wood', 'Audience seating (upholstered seats, wooden shells)'),
    'whitePanels': ('plasterboard', 'White wall and ceiling panels'),
    'brickwall': ('brick', 'Brick wall'),
}

BRAS_SETUP = {
    'CR2': dict(eye=[0.2, -3.6, 1.6], target=[0.0, 3.0, 1.1], fov=70.0,
                lights=[([0.0, -1.5, 2.6], 10.0), ([0.0, 2.0, 2.6], 10.0)], max_time=3.0),
    'CR4': dict(eye=[14.0, 0.0, 3.0], target=[-2.0, 0.0, 2.0], fov=65.0,
                lights=[([3.0, 0.0, 8.0], 300.0), ([12.0, 0.0, 9.0], 300.0)], max_time=3.0),
}


def bras(shared, tag):
    low = tag.lower()
    src = os.path.join(shared, f'bras_{low}')
    d = os.path.join(ROOMS, f'bras_{low}')
    os.makedirs(d, exist_ok=True)
    for fn in (f'{tag}.obj', f'{tag}.mtl', 'ATTRIBUTION.md'):
        shutil.copyfile(os.path.join(src, fn), os.path.join(d, fn))
    # the JSON is the source of scene.toml; keep a copy next to it for reference
    shutil.copyfile(os.path.join(src, f'{tag}.json'), os.path.join(d, f'{tag}.json'))
    js = json.load(open(os.path.join(src, f'{tag}.json')))
    colours = {}
    cur = None
    for line in open(os.path.join(src, f'{tag}.mtl')):
        if line.startswith('newmtl'):
            cur = line.split()[1]
        elif 'display colour in source file' in line and cur:
            colours[cur] = srgb_to_linear(line.strip().split()[-1])
    setup = BRAS_SETUP[tag]
    air = js['air']
    out = [f'# {tag} (BRAS) - propsim scene written from {tag}.json (copied here unchanged from the shared',
           f'# BRAS conversion). Licence: CC BY-SA 4.0, see ATTRIBUTION.md. {js["description_in_source"]}',
           f'# Air volume {js["volume_m3"]:.2f} m^3 (shell minus {js["volume_analysis"]["obstacle_count"]} '
           f'closed obstacles), surface {js["surface_m2"]:.2f} m^2, {js["triangles"]} triangles.',
           '# Note: the room shell is wound outward (signed volume > 0); the BRAS obstacles keep the upstream',
           '# winding, normals out of the obstacle (into the air).']
    if tag == 'CR4':
        mc = js['mesh_checks']
        out.append(f'# Note: upstream mesh has {mc["edges_with_more_than_2_faces"]} edges shared by three '
                   'triangles (see CR4.json mesh_checks.non_manifold_edges).')
    out += [f'obj = "{tag}.obj"', '']
    variant = js.get('variant')
    if variant:
        out += [f'# BRAS variant in {tag}.json: "{variant["name"]}" '
                f'(active_in_source_file = {str(variant["active_in_source_file"]).lower()}):',
                '# overrides_group_to_material = ' + json.dumps(variant['overrides_group_to_material']),
                '# i.e. the white panels are covered with absorbers, modelled with the seating material.',
                '# Delete this [surfaces] entry to use the untreated mat_CR4_whitePanels material.',
                '[surfaces]']
        for grp, mat in variant['overrides_group_to_material'].items():
            out.append(f'{grp} = "{mat}"')
        out.append('')
    for name, m in js['materials'].items():
        suffix = name.split('_', 2)[2]
        itu, desc = BRAS_STYLE[suffix]
        out += [f'[materials.{name}]',
                f'description = "{tag} {desc} (BRAS fitted estimate, octave bands 125 Hz - 4 kHz)"',
                f'source = "BRAS, Brinkmann et al. 2021, Applied Acoustics 176, 107867, fitted_estimates '
                f'(octave = mean of three third-octave values); CC BY-SA 4.0"',
                'absorption = ' + vec(m['absorption']),
                'scattering = ' + vec(m['scattering']),
                f'itu = "{itu}"',
                'color = ' + vec(colours.get(name, [0.7, 0.7, 0.7])),
                '']
    out += ['[camera]', f'eye = {vec(setup["eye"])}', f'target = {vec(setup["target"])}',
            'up = [0.0, 0.0, 1.0]', f'fov_deg = {f(setup["fov"])}', '',
            '[render]', 'width = 640', 'height = 480', 'spp = 64', 'max_depth = 8',
            'background = [0.0, 0.0, 0.0]', '']
    for pos, inten in setup['lights']:
        out += ['[[lights]]', f'position = {vec(pos)}', f'intensity = {vec([inten] * 3)}', '']
    out += ['[acoustic]',
            f'# air from {tag}.json: {air["temperature_c"]} C, {air["relative_humidity_percent"]} %, '
            f'{air["pressure_pa"]} Pa ({air["air_absorption_model"]})',
            f'temperature_c = {f(air["temperature_c"])}',
            f'relative_humidity_percent = {f(air["relative_humidity_percent"])}',
            f'pressure_kpa = {f(air["pressure_pa"] / 1000.0)}',
            'rays = 100000', f'max_time_s = {f(setup["max_time"])}', '']
    out += toml_sources('acoustic.sources', [{'name': s['name'], 'position': s['position']} for s in js['sources']])
    out += toml_sources('acoustic.receivers', [{'name': r['name'], 'position': r['position'], 'radius_m': 0.1}
                                               for r in js['receivers']])
    write(os.path.join(d, 'scene.toml'), '\n'.join(out).rstrip() + '\n')
    attr = os.path.join(d, 'ATTRIBUTION.md')
    note = (f'\nscene.toml in this folder was written for propsim from {tag}.json with no geometry, material '
            'or position edits (materials, air, sources and receivers copied from the JSON'
            + ('; the [surfaces] override reproduces the JSON\'s active "variant"' if variant else '')
            + '; camera and point lights added for rendering only).\n')
    with open(attr, 'a') as fh:
        fh.write(note)
    pts = [('camera', tuple(setup['eye']))] + [('light', tuple(p)) for p, _ in setup['lights']]
    pts += [(s['name'], tuple(s['position'])) for s in js['sources'] + js['receivers']]
    return os.path.join(d, f'{tag}.obj'), pts, {'json_air_volume_m3': js['volume_m3']}


# ----------------------------------------------------------------------------- main

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--shared', default=os.path.join(ROOMS, '..', '..', 'shared', 'rooms'))
    ap.add_argument('--no-check', action='store_true')
    a = ap.parse_args()
    results = [cornell(), shoebox(), l_room(), street_canyon(), bras(a.shared, 'CR2'), bras(a.shared, 'CR4')]
    if a.no_check:
        return
    for path, pts, extra in results:
        r = objcheck.report(path, pts)
        print(f'== {os.path.relpath(path, ROOMS)}: {r["triangles"]} triangles, {r["vertices"]} vertices, '
              f'area {r["area_m2"]:.4f} m^2, edges {r["edges"]}, non-2-face edges '
              f'{r["edges_not_shared_by_exactly_2"]}, repeated directed edges {r["directed_edges_used_not_once"]}, '
              f'divergence sum {r["signed_volume_all_m3"]:.4f} m^3, degenerate {r["degenerate_triangles"]}')
        for c in r['components']:
            if len(r['components']) > 20 and c['triangles'] < 3000:
                continue
            print(f'   component {",".join(c["objects"])} [{",".join(c["usemtl"])}]: {c["triangles"]} tris, '
                  f'area {c["area_m2"]:.4f}, signed volume {c["signed_volume_m3"]:.5f}, '
                  f'closed {c["closed"]}, oriented {c["oriented"]}')
        if len(r['components']) > 20:
            vols = [c['signed_volume_m3'] for c in r['components']]
            print(f'   ({len(vols)} components; small ones: signed volumes all '
                  f'{"positive" if all(v > 0 for v in vols) else "MIXED"}, '
                  f'sum of small {sum(v for v in vols if abs(v) < 1000):.4f})')
        print('   winding numbers: ' + ', '.join(f'{k}={v:.3f}' for k, v in r['points'].items()))
        for k, v in extra.items():
            print(f'   {k}: {v if not isinstance(v, float) else round(v, 5)}')


if __name__ == '__main__':
    main()
