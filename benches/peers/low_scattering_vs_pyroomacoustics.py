#!/usr/bin/env python3
"""Low scattering: propsim and pyroomacoustics against exact and diffuse-field references.

Two 10 x 8 x 3 m shoeboxes, source (2, 3, 1.5), receiver (7, 5, 1.6), no air absorption
(so every octave band is the same and the references are exact):

  U  every surface absorption 0.2 (the shoebox of issue 19);
  N  non-uniform: floor 0.1, ceiling 0.5 (an absorbing ceiling), walls 0.05.

with the same scattering s on every surface, s = 0, 0.05, 0.1, 0.5, 1. For each case it
prints T20 and T30 (ISO 3382-1 least-squares fits on the Schroeder curve, all computed here
by the same code) of

  ism    the exact image-source decay of the specular room (s = 0 only: the truth there);
  spec   the exact specular part of the decay for s > 0 (image sources with every reflection
         weighted by (1 - a)(1 - s)): a lower bound of the total energy at every time;
  diff   the exact diffuse limit (s = 1): the slowest decay mode of Kuttruff's integral
         equation for Lambert walls, solved on a grid of wall patches (radiosity);
  Eyring, and Kuttruff's correction of Eyring for the spread of free path lengths;
  propsim (`propsim acoustic`) and pyroomacoustics 0.10.1 (hybrid ISM order 2 + rays),
         rounds alternating between the tools, medians over the rounds.

    pip install pyroomacoustics
    cargo build --release
    python3 benches/peers/low_scattering_vs_pyroomacoustics.py --rounds 3
"""
import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile

import numpy as np

SIZE = np.array([10.0, 8.0, 3.0])
SRC = np.array([2.0, 3.0, 1.5])
RCV = np.array([7.0, 5.0, 1.6])
C = 343.2 * np.sqrt(293.15 / 293.15)  # 20 C, as propsim's default air
BIN = 1e-3
# absorption per axis: (face at 0, face at L) for x, y, z
ROOMS = {
    "U": ((0.2, 0.2), (0.2, 0.2), (0.2, 0.2)),
    "N": ((0.05, 0.05), (0.05, 0.05), (0.1, 0.5)),
}
SCATTERING = [0.0, 0.05, 0.1, 0.5, 1.0]


# ---------------------------------------------------------------- references
def ism_histogram(absorption, s, t_max, bin_s=BIN):
    """Exact image-source energy histogram of the box (Allen and Berkley 1979): the image
    2nL + (1 - 2u) x_s lies behind |n - u| reflections on the face at 0 and |n| on the face at
    L; each reflection keeps (1 - a)(1 - s) of the energy (the specular part)."""
    path = C * t_max
    hist = np.zeros(int(np.ceil(t_max / bin_s)))
    axes = []
    for k in range(3):
        lo, hi = [(1 - a) * (1 - s) for a in absorption[k]]
        reach = int(np.ceil(path / (2 * SIZE[k]))) + 1
        n = np.arange(-reach, reach + 1)
        pos, w = [], []
        for u in (0, 1):
            pos.append(2 * n * SIZE[k] + (1 - 2 * u) * SRC[k] - RCV[k])
            w.append(lo ** np.abs(n - u) * hi ** np.abs(n))
        axes.append((np.concatenate(pos), np.concatenate(w)))
    (dx, wx), (dy, wy), (dz, wz) = axes
    for i in range(len(dx)):
        dxy2 = dx[i] ** 2 + dy ** 2
        keep = dxy2 <= path * path
        if not keep.any():
            continue
        d2 = dxy2[keep][:, None] + dz[None, :] ** 2
        w = (wx[i] * wy[keep])[:, None] * wz[None, :]
        d = np.sqrt(d2).ravel()
        b = (d / C / bin_s).astype(int)
        ok = b < len(hist)
        np.add.at(hist, b[ok], (w.ravel() / (4 * np.pi * d2.ravel()))[ok])
    return hist


def schroeder_db(energy):
    tail = np.cumsum(energy[::-1])[::-1]
    with np.errstate(divide="ignore"):
        return 10 * np.log10(tail / tail[0])


def decay_time(energy, start_db, end_db, bin_s=BIN):
    """ISO 3382-1: least-squares line through the Schroeder curve from its first crossing of
    start_db to its first crossing of end_db, extrapolated to 60 dB."""
    level = schroeder_db(energy)
    t = (np.arange(len(level)) + 0.5) * bin_s
    i0 = np.argmax(level <= start_db)
    if not (level <= end_db).any():
        return float("nan")
    i1 = np.argmax(level <= end_db)
    slope = np.polyfit(t[i0:i1 + 1], level[i0:i1 + 1], 1)[0]
    return -60.0 / slope


def t20_t30(energy):
    return decay_time(energy, -5, -25), decay_time(energy, -5, -35)


def faces(absorption):
    """The six faces as (origin, edge u, edge v, inward normal, absorption)."""
    x, y, z = SIZE
    e = np.eye(3)
    out = []
    for k, (lo, hi) in enumerate(absorption):
        i, j = [m for m in range(3) if m != k]
        u, v = e[i] * SIZE[i], e[j] * SIZE[j]
        out.append((np.zeros(3), u, v, e[k], lo))
        out.append((e[k] * SIZE[k], u, v, -e[k], hi))
    return out


def diffuse_limit_s(absorption, patch_m=1.0, quad=6):
    """Slowest decay of the room when every wall reflects by Lambert's law: Kuttruff's integral
    equation B(r, t) = rho(r) int B(r', t - R/c) cos cos' / (pi R^2) dS' (Room Acoustics,
    sec. 5.6) on a grid of patches. For every patch pair, Gauss-Legendre quadrature
    (quad x quad points a patch) gives the form factor F_ij and the mean and variance of the
    distance R; each row of F is normalised to 1 (a closed room). The decay rate delta makes
    the spectral radius of diag(rho) [F_ij <exp(delta R / c)>] one, with
    <exp(delta R / c)> = exp(delta <R> / c + delta^2 var R / 2 c^2) (delta R / c < 0.5 here).
    Returns T = 6 ln 10 / delta."""
    g, gw = np.polynomial.legendre.leggauss(quad)
    g, gw = (g + 1) / 2, gw / 2
    centres, nrm, rho, pts, wts = [], [], [], [], []
    for o, u, v, n, a in faces(absorption):
        nu = max(1, int(round(np.linalg.norm(u) / patch_m)))
        nv = max(1, int(round(np.linalg.norm(v) / patch_m)))
        area = np.linalg.norm(u) * np.linalg.norm(v) / (nu * nv)
        for p in range(nu):
            for q in range(nv):
                pts.append([o + (p + gi) / nu * u + (q + gj) / nv * v for gi in g for gj in g])
                wts.append([wi * wj * area for wi in gw for wj in gw])
                nrm.append(n)
                rho.append(1 - a)
    pts, wts, nrm, rho = (np.array(x) for x in (pts, wts, nrm, rho))
    m, q2 = len(pts), quad * quad
    flat, wflat = pts.reshape(-1, 3), wts.ravel()
    nflat = np.repeat(nrm, q2, axis=0)
    f = np.zeros((m, m))
    mean_r = np.zeros((m, m))
    var_r = np.zeros((m, m))
    for i in range(m):
        d = flat[None, :, :] - pts[i][:, None, :]  # (q2, m q2, 3)
        r2 = (d * d).sum(-1)
        cos_i = d @ nrm[i]
        cos_j = -(d * nflat[None, :, :]).sum(-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = np.where((cos_i > 1e-12) & (cos_j > 1e-12), cos_i * cos_j / (np.pi * r2 * r2), 0.0)
        k = k * wts[i][:, None] * wflat[None, :] / wts[i].sum()
        r = np.sqrt(r2)
        kk = k.reshape(q2, m, q2).sum(axis=(0, 2))
        kr = (k * r).reshape(q2, m, q2).sum(axis=(0, 2))
        krr = (k * r2).reshape(q2, m, q2).sum(axis=(0, 2))
        f[i] = kk
        with np.errstate(divide="ignore", invalid="ignore"):
            mean_r[i] = np.where(kk > 0, kr / kk, 0.0)
            var_r[i] = np.where(kk > 0, krr / kk - mean_r[i] ** 2, 0.0)
    f /= f.sum(axis=1, keepdims=True)

    def radius(delta):
        x = delta / C
        mat = rho[:, None] * f * np.exp(x * mean_r + 0.5 * x * x * var_r)
        return np.max(np.abs(np.linalg.eigvals(mat)))

    lo, hi = 0.0, 200.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if radius(mid) < 1 else (lo, mid)
    return 6 * np.log(10) / (0.5 * (lo + hi))


def eyring_s(absorption):
    areas, a = area_absorption(absorption)
    v, s = np.prod(SIZE), areas.sum()
    mean = (areas * a).sum() / s
    return 24 * np.log(10) * v / (C * -s * np.log(1 - mean))


def kuttruff_s(absorption, samples=400_000, seed=1):
    """Eyring corrected for the spread of free path lengths between Lambert reflections
    (Kuttruff, Room Acoustics, sec. 5.5): decay rate times (1 + gamma^2 / 2 ln(1 - a_mean)),
    gamma^2 the relative variance of the chords of the box, by Monte Carlo here."""
    rng = np.random.default_rng(seed)
    areas, _ = area_absorption(absorption)
    face = rng.choice(6, size=samples, p=areas / areas.sum())
    k = face // 2
    start = rng.random((samples, 3)) * SIZE
    start[np.arange(samples), k] = np.where(face % 2 == 0, 0.0, SIZE[k])
    u1, u2 = rng.random(samples), rng.random(samples)
    local = np.stack([np.sqrt(u1) * np.cos(2 * np.pi * u2), np.sqrt(u1) * np.sin(2 * np.pi * u2),
                      np.sqrt(1 - u1)], axis=1)  # cosine-weighted, z along the inward normal
    direction = np.zeros((samples, 3))
    for axis in range(3):
        others = [m for m in range(3) if m != axis]
        sel = k == axis
        sign = np.where(face[sel] % 2 == 0, 1.0, -1.0)
        direction[np.ix_(sel, [axis])] = (local[sel, 2] * sign)[:, None]
        direction[np.ix_(sel, others)] = local[sel, :2]
    with np.errstate(divide="ignore"):
        t = np.where(direction > 0, (SIZE - start) / direction, np.where(direction < 0, -start / direction, np.inf))
    chord = t.min(axis=1)
    gamma2 = chord.var() / chord.mean() ** 2
    areas, a = area_absorption(absorption)
    mean = (areas * a).sum() / areas.sum()
    return eyring_s(absorption) / (1 + 0.5 * gamma2 * np.log(1 - mean))


def area_absorption(absorption):
    x, y, z = SIZE
    face_area = [y * z, x * z, x * y]
    areas = np.array([face_area[k] for k in range(3) for _ in range(2)])
    a = np.array([v for pair in absorption for v in pair])
    return areas, a


# ---------------------------------------------------------------- the two tools
SCENE = """obj = "{obj}"
[surfaces]
floor = "floor"
walls = "walls"
ceiling = "ceiling"
[materials.floor]
absorption = {floor}
scattering = {s}
[materials.walls]
absorption = {walls}
scattering = {s}
[materials.ceiling]
absorption = {ceiling}
scattering = {s}
[acoustic]
temperature_c = 20.0
relative_humidity_percent = 50.0
[[acoustic.sources]]
name = "S1"
position = [2.0, 3.0, 1.5]
[[acoustic.receivers]]
name = "R1"
position = [7.0, 5.0, 1.6]
"""


def run_propsim(binary, root, tmp, absorption, s, rays, seed):
    scene = os.path.join(tmp, "scene.toml")
    with open(scene, "w") as f:
        f.write(SCENE.format(obj=os.path.join(root, "rooms", "shoebox", "shoebox.obj"),
                             floor=absorption[2][0], ceiling=absorption[2][1], walls=absorption[0][0], s=s))
    out = os.path.join(tmp, "out")
    subprocess.run([binary, "acoustic", scene, "--rays", str(rays), "--seed", str(seed), "--no-air",
                    "--out", out], check=True, capture_output=True, text=True)
    with open(os.path.join(out, "histogram.csv")) as f:
        rows = list(csv.DictReader(f))
    return np.array([float(r["energy_1000hz_j_per_m2"]) for r in rows])


def run_pyroomacoustics(absorption, s, rays, seed):
    import pyroomacoustics as pra

    np.random.seed(seed)
    pra.libroom.set_rng_seed(seed) if hasattr(pra.libroom, "set_rng_seed") else None
    (west, east), (south, north), (floor, ceiling) = absorption
    mats = {name: pra.Material(energy_absorption=a, scattering=s)
            for name, a in [("west", west), ("east", east), ("south", south), ("north", north),
                            ("floor", floor), ("ceiling", ceiling)]}
    room = pra.ShoeBox(SIZE.tolist(), fs=16000, materials=mats, max_order=2, ray_tracing=True,
                       air_absorption=False)
    room.set_ray_tracing(n_rays=rays)
    room.add_source(SRC.tolist())
    room.add_microphone(RCV.tolist())
    room.compute_rir()
    rir = np.asarray(room.rir[0][0], dtype=float)
    # energy per 1 ms bin from the squared impulse response
    per = 16
    n = len(rir) // per
    return (rir[: n * per] ** 2).reshape(n, per).sum(axis=1)


def pyroomacoustics_direct():
    """The energy of the direct sound alone in pyroomacoustics' impulse response (its own scale)."""
    import pyroomacoustics as pra

    room = pra.ShoeBox(SIZE.tolist(), fs=16000, materials=pra.Material(energy_absorption=0.5), max_order=0,
                       air_absorption=False)
    room.add_source(SRC.tolist())
    room.add_microphone(RCV.tolist())
    room.compute_rir()
    return float((np.asarray(room.rir[0][0], dtype=float) ** 2).sum())


def from_direct(energy):
    """The decay from the direct sound's bin on (the tools delay the response differently)."""
    start = int(np.argmax(energy > 0.05 * energy.max()))
    return energy[start:]


def relative_tail(energy, direct):
    """Schroeder integral of `energy` per unit of direct-sound energy, from the direct sound."""
    return np.cumsum(energy[::-1])[::-1] / direct


def below_bound_db(tool, exact):
    """How far the tool's late energy (Schroeder integral per unit direct sound) falls below
    the exact specular part at worst, dB, from 20 ms after the direct sound down to 40 dB."""
    n = min(len(tool), len(exact))
    t, e = tool[:n], exact[:n]
    stop = int(np.argmax(e <= e[0] * 1e-4)) or n
    return float(np.max(10 * np.log10(e[20:stop] / t[20:stop])))


def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=200_000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--rooms", default="U,N")
    parser.add_argument("--scattering", default=",".join(map(str, SCATTERING)))
    parser.add_argument("--binary", default=os.path.join(root, "target", "release", "propsim"))
    args = parser.parse_args()
    d = np.linalg.norm(RCV - SRC)
    print("room  s     | exact ism/spec T20 T30 | propsim T20 T30 (bound dB) | pyroomac. T20 T30 (bound dB) "
          "| Eyring Kuttruff diffuse(s=1)")
    for name in args.rooms.split(","):
        absorption = ROOMS[name]
        ey, ku = eyring_s(absorption), kuttruff_s(absorption)
        diffuse = diffuse_limit_s(absorption)
        for s in map(float, args.scattering.split(",")):
            exact = ism_histogram(absorption, s, 8.0 if s == 0 else 4.0)
            # Per unit of direct sound: E / (4 pi d^2) in propsim's histogram and the exact one.
            direct, direct_pra = 1 / (4 * np.pi * d * d), pyroomacoustics_direct()
            exact_tail = relative_tail(from_direct(exact), direct)
            ours, peer = [], []
            with tempfile.TemporaryDirectory() as tmp:
                for k in range(args.rounds):
                    e = from_direct(run_propsim(args.binary, root, tmp, absorption, s, args.rays, k + 1))
                    ours.append((*t20_t30(e), below_bound_db(relative_tail(e, direct), exact_tail)))
                    e = from_direct(run_pyroomacoustics(absorption, s, args.rays, k + 1))
                    peer.append((*t20_t30(e), below_bound_db(relative_tail(e, direct_pra), exact_tail)))
            med = lambda rows: [statistics.median(r[i] for r in rows) for i in range(3)]
            (o20, o30, ob), (p20, p30, pb) = med(ours), med(peer)
            x20, x30 = t20_t30(exact)
            print(f"{name:4}  {s:<5} | {x20:6.3f} {x30:6.3f}         | {o20:6.3f} {o30:6.3f} ({ob:+5.1f})"
                  f"       | {p20:6.3f} {p30:6.3f} ({pb:+5.1f})         | {ey:6.3f} {ku:6.3f} {diffuse:6.3f}",
                  flush=True)


if __name__ == "__main__":
    sys.exit(main())
