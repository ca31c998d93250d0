#!/usr/bin/env python3
"""Mesh checks for propsim room OBJs (pure Python, no dependencies).

Usage: python3 objcheck.py FILE.obj [--points x,y,z ...]

Faces are triangulated as fans (a b c d -> a b c, a c d), as propsim's OBJ loader does.
Reports: triangles, area (per usemtl group), edge manifoldness (every undirected edge used by
exactly two triangles), orientation (every directed edge used once), and per connected
component (triangles sharing vertex indices) the signed volume by the divergence theorem,
V = sum over triangles of a . (b x c) / 6. Positive = normals point out of the enclosed region.
"""
import math
import sys
from collections import defaultdict


def load_obj(path):
    verts, tris, mats, objs = [], [], [], []
    mat, obj = None, None
    with open(path) as fh:
        for line in fh:
            s = line.split('#', 1)[0].split()
            if not s:
                continue
            if s[0] == 'v':
                verts.append(tuple(float(x) for x in s[1:4]))
            elif s[0] == 'usemtl':
                mat = s[1]
            elif s[0] == 'o':
                obj = s[1]
            elif s[0] == 'f':
                idx = []
                for tok in s[1:]:
                    i = int(tok.split('/')[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                for k in range(1, len(idx) - 1):
                    tris.append((idx[0], idx[k], idx[k + 1]))
                    mats.append(mat)
                    objs.append(obj)
    return verts, tris, mats, objs


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def norm(a):
    return math.sqrt(dot(a, a))


def tri_area(v, t):
    return 0.5 * norm(cross(sub(v[t[1]], v[t[0]]), sub(v[t[2]], v[t[0]])))


def tri_vol(v, t):
    return dot(v[t[0]], cross(v[t[1]], v[t[2]])) / 6.0


def components(tris):
    parent = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b, c in tris:
        ra, rb, rc = find(a), find(b), find(c)
        parent[rb] = ra
        parent[find(rc)] = ra
    comp = defaultdict(list)
    for i, t in enumerate(tris):
        comp[find(t[0])].append(i)
    return list(comp.values())


def edge_stats(tris, subset=None):
    und, dire = defaultdict(int), defaultdict(int)
    for i in (subset if subset is not None else range(len(tris))):
        t = tris[i]
        for k in range(3):
            a, b = t[k], t[(k + 1) % 3]
            und[(min(a, b), max(a, b))] += 1
            dire[(a, b)] += 1
    bad_und = sum(1 for n in und.values() if n != 2)
    bad_dir = sum(1 for n in dire.values() if n != 1)
    return len(und), bad_und, bad_dir


def winding_number(v, tris, p, subset=None):
    """Generalised winding number of point p (solid angle sum / 4 pi)."""
    total = 0.0
    for i in (subset if subset is not None else range(len(tris))):
        a, b, c = (sub(v[j], p) for j in tris[i])
        la, lb, lc = norm(a), norm(b), norm(c)
        num = dot(a, cross(b, c))
        den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
        total += 2.0 * math.atan2(num, den)
    return total / (4.0 * math.pi)


def report(path, points=()):
    v, tris, mats, objs = load_obj(path)
    area = sum(tri_area(v, t) for t in tris)
    by_mat = defaultdict(float)
    for t, m in zip(tris, mats):
        by_mat[m] += tri_area(v, t)
    nedges, bad_und, bad_dir = edge_stats(tris)
    out = {
        'file': path, 'vertices': len(v), 'triangles': len(tris), 'area_m2': area,
        'area_by_usemtl_m2': dict(by_mat), 'edges': nedges,
        'edges_not_shared_by_exactly_2': bad_und, 'directed_edges_used_not_once': bad_dir,
        'signed_volume_all_m3': sum(tri_vol(v, t) for t in tris),
        'degenerate_triangles': sum(1 for t in tris if tri_area(v, t) < 1e-10),
        'components': [],
    }
    for c in components(tris):
        ne, bu, bd = edge_stats(tris, c)
        out['components'].append({
            'objects': sorted({objs[i] for i in c if objs[i]}),
            'usemtl': sorted({mats[i] for i in c if mats[i]}),
            'triangles': len(c), 'area_m2': sum(tri_area(v, tris[i]) for i in c),
            'signed_volume_m3': sum(tri_vol(v, tris[i]) for i in c),
            'closed': bu == 0, 'oriented': bd == 0,
        })
    # winding numbers over the closed components only (open sheets such as a light quad or a
    # ground plane have no inside)
    closed = [i for c in components(tris) if edge_stats(tris, c)[1] == 0 for i in c]
    out['points'] = {name: winding_number(v, tris, p, closed) for name, p in points}
    return out


if __name__ == '__main__':
    args = sys.argv[1:]
    pts = []
    if '--points' in args:
        k = args.index('--points')
        pts = [(s, tuple(float(x) for x in s.split(','))) for s in args[k + 1:]]
        args = args[:k]
    import json
    for p in args:
        print(json.dumps(report(p, pts), indent=1))
