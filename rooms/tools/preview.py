#!/usr/bin/env python3
"""Quick camera check: ray-casts a scene.toml's OBJ from its [camera] (vertical fov) and writes a
small flat-shaded PNG (MTL Kd x |cos|, emissive Ke shown bright). Pure Python, slow; for sanity
checks of camera placement only.   python3 preview.py SCENE.toml OUT.png [width]"""
import math
import os
import struct
import sys
import tomllib
import zlib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from objcheck import cross, dot, load_obj, norm, sub  # noqa: E402


def load_mtl(path):
    kd, cur = {}, None
    if not os.path.exists(path):
        return kd
    for line in open(path):
        s = line.split()
        if not s:
            continue
        if s[0] == 'newmtl':
            cur = s[1]
        elif s[0] == 'Kd' and cur:
            kd[cur] = tuple(float(x) for x in s[1:4])
        elif s[0] == 'Ke' and cur:
            kd[cur] = (1.0, 1.0, 1.0)
    return kd


def build_bvh(v, tris, idx, depth=0):
    lo = [min(v[j][k] for i in idx for j in tris[i]) for k in range(3)]
    hi = [max(v[j][k] for i in idx for j in tris[i]) for k in range(3)]
    if len(idx) <= 8 or depth > 30:
        return (lo, hi, idx, None, None)
    ax = max(range(3), key=lambda k: hi[k] - lo[k])
    idx = sorted(idx, key=lambda i: sum(v[j][ax] for j in tris[i]))
    m = len(idx) // 2
    return (lo, hi, None, build_bvh(v, tris, idx[:m], depth + 1), build_bvh(v, tris, idx[m:], depth + 1))


def hit_box(lo, hi, o, inv, tmax):
    t0, t1 = 0.0, tmax
    for k in range(3):
        a, b = (lo[k] - o[k]) * inv[k], (hi[k] - o[k]) * inv[k]
        if a > b:
            a, b = b, a
        t0, t1 = max(t0, a), min(t1, b)
        if t0 > t1:
            return False
    return True


def trace(node, v, tris, o, d, inv, best):
    lo, hi, leaf, l, r = node
    if not hit_box(lo, hi, o, inv, best[0]):
        return
    if leaf is None:
        trace(l, v, tris, o, d, inv, best)
        trace(r, v, tris, o, d, inv, best)
        return
    for i in leaf:
        a, b, c = (v[j] for j in tris[i])
        e1, e2 = sub(b, a), sub(c, a)
        p = cross(d, e2)
        det = dot(e1, p)
        if abs(det) < 1e-12:
            continue
        s = sub(o, a)
        u = dot(s, p) / det
        if u < 0 or u > 1:
            continue
        q = cross(s, e1)
        w = dot(d, q) / det
        if w < 0 or u + w > 1:
            continue
        t = dot(e2, q) / det
        if 1e-6 < t < best[0]:
            best[0], best[1] = t, i


def png(path, w, h, rows):
    raw = b''.join(b'\x00' + bytes(r) for r in rows)
    chunk = lambda t, data: struct.pack('>I', len(data)) + t + data + struct.pack('>I', zlib.crc32(t + data))
    with open(path, 'wb') as fh:
        fh.write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, 8, 2, 0, 0, 0))
                 + chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b''))


def main(scene, out, width=96):
    sc = tomllib.load(open(scene, 'rb'))
    base = os.path.dirname(scene)
    objp = os.path.join(base, sc['obj'])
    v, tris, mats, _ = load_obj(objp)
    mtllib = [l.split()[1] for l in open(objp) if l.startswith('mtllib')]
    kd = load_mtl(os.path.join(base, mtllib[0])) if mtllib else {}
    cam = sc['camera']
    rend = sc.get('render', {})
    aspect = rend.get('width', 1) / rend.get('height', 1)
    w, h = width, max(1, round(width / aspect))
    eye, tgt, up = cam['eye'], cam['target'], cam.get('up', [0, 0, 1])
    fwd = sub(tgt, eye)
    fwd = tuple(x / norm(fwd) for x in fwd)
    right = cross(fwd, up)
    right = tuple(x / norm(right) for x in right)
    upv = cross(right, fwd)
    th = math.tan(math.radians(cam['fov_deg']) / 2)
    bvh = build_bvh(v, tris, list(range(len(tris))))
    rows = []
    for j in range(h):
        row = []
        for i in range(w):
            sx = (2 * (i + 0.5) / w - 1) * th * aspect
            sy = (1 - 2 * (j + 0.5) / h) * th
            d = tuple(fwd[k] + sx * right[k] + sy * upv[k] for k in range(3))
            d = tuple(x / norm(d) for x in d)
            inv = tuple(1 / x if abs(x) > 1e-12 else 1e12 for x in d)
            best = [1e30, None]
            trace(bvh, v, tris, eye, d, inv, best)
            if best[1] is None:
                row += [40, 0, 40]
                continue
            a, b, c = (v[k] for k in tris[best[1]])
            n = cross(sub(b, a), sub(c, a))
            cosv = abs(dot(n, d)) / norm(n)
            col = kd.get(mats[best[1]], (0.7, 0.7, 0.7))
            sh = 0.3 + 0.7 * cosv
            row += [min(255, int(255 * (c_ * sh) ** (1 / 2.2))) for c_ in col]
        rows.append(row)
    png(out, w, h, rows)


if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 96)
