#!/usr/bin/env python3
"""Writes rooms/smoke/smoke.txt: a 24^3 density grid of a smoke plume (a soft blob shaped
by three octaves of value noise, densities 0 to 1), in propsim's text grid format
(docs/render.md, "Density grid files"): a header `nx ny nz`, then the densities, x fastest,
then y, then z. Deterministic (an integer hash, no random module), standard library only.

    python3 rooms/tools/smoke_grid.py rooms/smoke/smoke.txt
"""
import math
import sys

N = 24


def hash01(i, j, k, octave):
    """A value in [0, 1) for a lattice point (a 32-bit integer hash)."""
    h = (i * 73856093) ^ (j * 19349663) ^ (k * 83492791) ^ (octave * 2654435761)
    h &= 0xFFFFFFFF
    h ^= h >> 13
    h = (h * 0x5BD1E995) & 0xFFFFFFFF
    h ^= h >> 15
    return h / 2**32


def value_noise(x, y, z, octave):
    """Trilinear value noise with a smoothstep fade."""
    i, j, k = math.floor(x), math.floor(y), math.floor(z)
    fx, fy, fz = x - i, y - j, z - k
    fade = lambda t: t * t * (3 - 2 * t)
    ux, uy, uz = fade(fx), fade(fy), fade(fz)
    total = 0.0
    for di in (0, 1):
        for dj in (0, 1):
            for dk in (0, 1):
                w = (ux if di else 1 - ux) * (uy if dj else 1 - uy) * (uz if dk else 1 - uz)
                total += w * hash01(i + di, j + dj, k + dk, octave)
    return total


def density(x, y, z):
    """x, y, z in [0, 1]: a plume rising along z, wider at the top, broken up by noise."""
    r_max = 0.1 + 0.25 * z
    r = math.hypot(x - 0.5, y - 0.5)
    envelope = max(0.0, 1.0 - (r / r_max) ** 2) * max(0.0, min(1.0, 6 * z)) * max(0.0, min(1.0, 6 * (1 - z)))
    noise = sum(value_noise(4 * 2**o * x, 4 * 2**o * y, 4 * 2**o * z, o) / 2**o for o in range(3)) / 1.75
    return max(0.0, envelope * (1.6 * noise - 0.35))


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "rooms/smoke/smoke.txt"
    with open(out, "w") as f:
        f.write("# rooms/smoke density grid, written by rooms/tools/smoke_grid.py\n")
        f.write(f"{N} {N} {N}\n")
        for k in range(N):
            for j in range(N):
                row = [density((i + 0.5) / N, (j + 0.5) / N, (k + 0.5) / N) for i in range(N)]
                f.write(" ".join(f"{v:.3g}" for v in row) + "\n")


if __name__ == "__main__":
    main()
