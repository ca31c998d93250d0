#!/usr/bin/env python3
"""Equal-time RMSE of the light-transport integrators on rooms/caustics (issue 25, point 3).

Renders a path-traced reference as several independent seeds (so its own noise can be
estimated and taken out of each RMSE), then times each integrator in alternating rounds and
reports, per integrator, the median wall time, the RMSE against the reference (with the
reference's variance subtracted; mean squared error over the rounds, each round a new seed),
and the ratio of `path`'s RMSE scaled to the same time
(`RMSE_path * sqrt(t_path / t)`) over the integrator's. The RMSE is also split between the
pixels that see a diffuse surface first and those that see the glass ball or the mirror
(computed from the scene's geometry), where the light arrives mostly by specular-diffuse-specular
paths that no bidirectional join makes. Per-pixel squared errors are kept in --workdir
(sqerr_NAME.npy) for closer looks; --eye/--target/--scene measure other views.

    cargo build --release
    python3 benches/caustics_equal_time.py --rounds 3

Needs numpy. The reference (8 x 32,768 spp at 32x32) takes about 2 minutes on 2 cores and is
kept in --workdir for later runs.
"""

import argparse
import hashlib
import os
import statistics
import subprocess
import sys
import time
import tomllib

import numpy as np

SCENE = "rooms/caustics/scene.toml"
SIZE = 32
# The scene's specular geometry (rooms/caustics/scene.toml and caustics.obj); the camera is read
# from the scene file unless --eye/--target are given.
BALL_CENTRE, BALL_RADIUS = (0.62, 0.62, 0.2), 0.2
MIRROR_X, MIRROR_Y, MIRROR_Z = 1.19, (0.25, 0.95), (0.02, 0.7)
ROOM = (1.2, 1.2, 1.0)

CONFIGS = {
    "path": ["--spp", "2048"],
    "bdpt": ["--spp", "256", "--integrator", "bdpt"],
    # ... and at about path's time, without the time scaling.
    "bdpt_512": ["--spp", "512", "--integrator", "bdpt"],
    # sppm at its default radius, at about path's time (256 x 16,000 photons) and at about half
    # of it (256 x 8,000), and the earlier 1,024 x 3,000 at 5 cm (docs/render.md says why
    # fewer, larger iterations win here).
    "sppm": ["--integrator", "sppm", "--iterations", "256", "--photons", "16000"],
    "sppm_8k": ["--integrator", "sppm", "--iterations", "256", "--photons", "8000"],
    "sppm_3k": ["--integrator", "sppm", "--iterations", "1024", "--photons", "3000", "--sppm-radius", "0.05"],
    "pssmlt": ["--spp", "1024", "--integrator", "pssmlt"],
    "vcm": ["--spp", "256", "--integrator", "vcm"],
}


def scene_camera(path):
    with open(path, "rb") as f:
        cam = tomllib.load(f)["camera"]
    return tuple(cam["eye"]), tuple(cam["target"]), float(cam["fov_deg"])


def render(propsim, scene, view, out, args, seed):
    """Renders `scene` at SIZE x SIZE with seed `seed`, `view` (--eye/--target flags) and
    `args`, into `out`; returns the wall time."""
    cmd = [propsim, "render", scene, "--width", str(SIZE), "--height", str(SIZE), "--seed", str(seed), *view, *args, "-o", out]
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def specular_mask(eye, target, fov_deg):
    """Pixels whose camera ray meets the ball or the mirror before a wall (dilated by one)."""
    eye = np.array(eye)
    f = np.array(target) - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    th = np.tan(np.radians(fov_deg) / 2)
    c = np.array(BALL_CENTRE)
    m = np.zeros((SIZE, SIZE), bool)
    for y in range(SIZE):
        for x in range(SIZE):
            d = f + (2 * (x + 0.5) / SIZE - 1) * th * r + (1 - 2 * (y + 0.5) / SIZE) * th * u
            d /= np.linalg.norm(d)
            hits = []
            oc = eye - c
            b, cc = oc @ d, oc @ oc - BALL_RADIUS**2
            if b * b - cc > 0 and -b - np.sqrt(b * b - cc) > 0:
                hits.append(-b - np.sqrt(b * b - cc))
            if d[0] > 0:
                t = (MIRROR_X - eye[0]) / d[0]
                p = eye + t * d
                if MIRROR_Y[0] <= p[1] <= MIRROR_Y[1] and MIRROR_Z[0] <= p[2] <= MIRROR_Z[1]:
                    hits.append(t)
            wall = min(
                t
                for t in ((-eye[i] / d[i]) if d[i] < 0 else ((ROOM[i] - eye[i]) / d[i]) for i in range(3) if d[i] != 0)
                if t > 0
            )
            m[y, x] = bool(hits) and min(hits) < wall
    dil = m.copy()
    dil[1:] |= m[:-1]
    dil[:-1] |= m[1:]
    dil[:, 1:] |= m[:, :-1]
    dil[:, :-1] |= m[:, 1:]
    return dil


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--propsim", default="target/release/propsim")
    ap.add_argument("--workdir", default="out/caustics_equal_time")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--ref-seeds", type=int, default=8)
    ap.add_argument("--ref-spp", type=int, default=32768, help="samples per pixel of each reference seed")
    ap.add_argument("--only", default="", help="comma-separated integrators to run besides path (default: all)")
    ap.add_argument("--eye", default="", help="camera position X,Y,Z (default: the scene's)")
    ap.add_argument("--target", default="", help="camera target X,Y,Z (default: the scene's)")
    ap.add_argument("--scene", default=SCENE, help="scene file (its camera is the default view)")
    a = ap.parse_args()
    eye, target, fov_deg = scene_camera(a.scene)
    view = []
    if a.eye:
        eye = tuple(float(v) for v in a.eye.split(","))
        view += ["--eye", a.eye]
    if a.target:
        target = tuple(float(v) for v in a.target.split(","))
        view += ["--target", a.target]
    os.makedirs(a.workdir, exist_ok=True)
    # The references are kept per scene text and view, so an edited scene renders new ones.
    with open(a.scene, "rb") as f:
        view_key = hashlib.sha256(f.read() + repr(view).encode()).hexdigest()[:10]
    refs = []
    for k in range(a.ref_seeds):
        out = os.path.join(a.workdir, f"ref_{view_key}_{a.ref_spp}_{101 + k}.npy")
        if not os.path.exists(out):
            print(f"reference seed {101 + k} ({a.ref_spp} spp)...", file=sys.stderr)
            render(a.propsim, a.scene, view, out, ["--spp", str(a.ref_spp)], 101 + k)
        refs.append(np.load(out))
    refs = np.array(refs)
    ref = refs.mean(0)
    ref_var = refs.var(0, ddof=1).mean(2) / len(refs)  # per pixel, of the reference's mean
    mask = specular_mask(eye, target, fov_deg)
    configs = {n: c for n, c in CONFIGS.items() if n == "path" or not a.only or n in a.only.split(",")}
    times = {n: [] for n in configs}
    err = {n: np.zeros_like(ref_var) for n in configs}
    # Round k renders seed k + 1 with every integrator in turn: the times alternate, and the
    # squared errors are averaged over the rounds' seeds (one seed's error swings with the
    # few rare bright paths it happens to find).
    for k in range(a.rounds):
        for n, args in configs.items():
            out = os.path.join(a.workdir, f"{n}.npy")
            times[n].append(render(a.propsim, a.scene, view, out, args, k + 1))
            err[n] += (((np.load(out) - ref) ** 2).mean(2) - ref_var) / a.rounds
    for n, e2 in err.items():
        np.save(os.path.join(a.workdir, f"sqerr_{n}.npy"), e2)  # per pixel, for closer looks
    t_path = statistics.median(times["path"])
    share = err["path"][mask].sum() / err["path"].sum()
    print(f"reference: {len(refs)} x {a.ref_spp} spp, its own RMSE {np.sqrt(ref_var.mean()):.4f}; "
          f"{mask.sum()} of {mask.size} pixels see the ball or the mirror first and hold {100 * share:.0f} % of "
          f"path's squared error (an integrator whose ratio there is x cannot beat x / {np.sqrt(share):.2f} "
          "over the whole image)")
    print("| integrator | median time | RMSE | ratio at equal time | diffuse-seen ratio | specular-seen ratio |")
    print("|---|---|---|---|---|---|")
    for n, e2 in err.items():
        t = statistics.median(times[n])

        def ratio(sel):
            return np.sqrt(err["path"][sel].mean() * t_path / (max(e2[sel].mean(), 1e-12) * t))

        everything = np.ones_like(mask)
        print(f"| `{n}` | {t:.2f} s | {np.sqrt(max(e2.mean(), 0)):.4f} | {ratio(everything):.2f} | "
              f"{ratio(~mask):.2f} | {ratio(mask):.2f} |")


if __name__ == "__main__":
    main()
