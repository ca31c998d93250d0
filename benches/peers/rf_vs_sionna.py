#!/usr/bin/env python3
"""propsim rf against Sionna RT's radio-map solver on Sionna's own street canyon, side by side.

Not part of the test suite: Sionna RT is a peer, not a dependency. Needs
`pip install sionna-rt` and Debian's `libllvm19` (Dr.Jit's LLVM back end).

What it does, in one run on this machine:
  1. exports Sionna's `simple_street_canyon` (its PLY meshes and ITU materials, 0.1 m slabs) to
     an OBJ + materials file that `propsim rf` reads;
  2. alternates rounds: Sionna's `RadioMapSolver` (warm: one untimed call first, so the JIT
     compilation is not counted) and the whole `propsim rf` command (a new process each round,
     loading, tracing and writing its outputs included); prints the medians and their ratio;
  3. compares propsim's last map with a Sionna reference map of --reference-rays rays (10^8
     by default, cached in --work as a .npy) cell by cell: median and 90th percentile of the
     absolute difference in dB over the cells both reach.

Settings follow issue 20: 180 x 120 m of 1 m cells at z = 1.5 m, transmitter (0, 0, 20),
isotropic, vertical polarisation, 3.5 GHz, 10^7 rays, depth 3, reflection and transmission.

    python3 benches/peers/rf_vs_sionna.py --rounds 5
    python3 benches/peers/rf_vs_sionna.py --rounds 3 --propsim-args=--no-diffraction
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

FREQ_HZ = 3.5e9
TX = (0.0, 0.0, 20.0)
CENTER = (0.0, 0.0, 1.5)
SIZE = (180.0, 120.0)
CELL_M = 1.0


def export_scene(scene, work):
    """Writes Sionna's scene as canyon.obj plus canyon_materials.toml (ITU names, 0.1 m)."""
    import mitsuba as mi

    obj_path = os.path.join(work, "canyon.obj")
    mat_path = os.path.join(work, "canyon_materials.toml")
    lines = ["# Sionna RT simple_street_canyon, exported by benches/peers/rf_vs_sionna.py"]
    materials = {}
    base = 1
    for name, obj in scene.objects.items():
        shape = obj.mi_mesh
        verts = np.array(shape.vertex_positions_buffer()).reshape(-1, 3)
        faces = np.array(shape.faces_buffer()).reshape(-1, 3)
        rm = obj.radio_material
        mat = "sionna_" + rm.name
        materials[mat] = (rm.itu_type, float(rm.thickness[0]) if hasattr(rm.thickness, "__len__") else float(rm.thickness))
        lines.append(f"o {name}")
        lines.append(f"usemtl {mat}")
        for v in verts:
            lines.append(f"v {v[0]:.6f} {v[1]:.6f} {v[2]:.6f}")
        for f in faces:
            lines.append(f"f {f[0] + base} {f[1] + base} {f[2] + base}")
        base += len(verts)
    with open(obj_path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    with open(mat_path, "w") as fh:
        for mat, (itu, thick) in materials.items():
            fh.write(f'[materials.{mat}]\nitu = "{itu}"\nthickness_m = {thick}\n\n')
    return obj_path, mat_path


def sionna_map(scene, rays, depth, seed=1):
    """Path gain [linear] on the grid, shape (ny, nx), y rows from -60 up, x fastest."""
    from sionna.rt import RadioMapSolver
    import mitsuba as mi

    solver = RadioMapSolver()
    rm = solver(
        scene,
        center=mi.Point3f(*CENTER),
        orientation=mi.Point3f(0, 0, 0),
        size=mi.Point2f(*SIZE),
        cell_size=mi.Point2f(CELL_M, CELL_M),
        samples_per_tx=int(rays),
        max_depth=depth,
        refraction=True,
        diffraction=False,
        seed=seed,
    )
    return np.array(rm.path_gain.numpy()[0])


def run_propsim(binary, obj_path, mat_path, out, rays, depth, extra):
    cmd = [
        binary, "rf", obj_path, "--materials", mat_path,
        "--tx", ",".join(str(c) for c in TX), "--antenna", "isotropic",
        "--polarization", "vertical", "--freq-ghz", str(FREQ_HZ / 1e9),
        "--grid-min", f"{-SIZE[0] / 2},{-SIZE[1] / 2}", "--grid-max", f"{SIZE[0] / 2},{SIZE[1] / 2}",
        "--cell-m", str(CELL_M), "--grid-height", str(CENTER[2]),
        "--rays", str(int(rays)), "--max-depth", str(depth), "--out", out,
    ] + extra
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def propsim_map(out):
    """Path gain [linear] on the same grid, shape (ny, nx); NaN where no ray reached."""
    import csv

    nx, ny = int(SIZE[0] / CELL_M), int(SIZE[1] / CELL_M)
    grid = np.full((ny, nx), np.nan)
    with open(os.path.join(out, "coverage.csv")) as fh:
        for row in csv.DictReader(fh):
            if row["path_gain_db"] == "":
                continue
            ix = int((float(row["x_m"]) + SIZE[0] / 2) // CELL_M)
            iy = int((float(row["y_m"]) + SIZE[1] / 2) // CELL_M)
            grid[iy, ix] = 10 ** (float(row["path_gain_db"]) / 10)
    return grid


def compare(p, s):
    both = np.isfinite(p) & (p > 0) & (s > 0)
    d = np.abs(10 * np.log10(p[both]) - 10 * np.log10(s[both]))
    return {
        "cells_both": int(both.sum()),
        "cells_sionna": int((s > 0).sum()),
        "cells_propsim": int((np.isfinite(p) & (p > 0)).sum()),
        "median_abs_db": float(np.median(d)) if d.size else None,
        "p90_abs_db": float(np.percentile(d, 90)) if d.size else None,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--rays", type=float, default=1e7)
    ap.add_argument("--depth", type=int, default=3)
    ap.add_argument("--reference-rays", type=float, default=1e8)
    ap.add_argument("--work", default="target/peers/sionna")
    ap.add_argument("--propsim", default="target/release/propsim")
    ap.add_argument("--propsim-args", default="", help="extra flags for propsim rf, space separated")
    args = ap.parse_args()

    os.makedirs(args.work, exist_ok=True)
    from sionna.rt import load_scene, Transmitter, PlanarArray, scene as sscene

    scene = load_scene(sscene.simple_street_canyon)
    scene.frequency = FREQ_HZ
    scene.tx_array = PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V")
    scene.rx_array = scene.tx_array
    scene.add(Transmitter(name="tx", position=list(TX)))
    obj_path, mat_path = export_scene(scene, args.work)
    extra = args.propsim_args.split() if args.propsim_args else []
    out = os.path.join(args.work, "propsim_out")

    ref_path = os.path.join(args.work, f"sionna_ref_{int(args.reference_rays)}_d{args.depth}.npy")
    if os.path.exists(ref_path):
        ref = np.load(ref_path)
    else:
        print(f"sionna reference map, {args.reference_rays:.0e} rays ...", file=sys.stderr)
        ref = sionna_map(scene, args.reference_rays, args.depth, seed=7)
        np.save(ref_path, ref)

    sionna_map(scene, args.rays, args.depth)  # warm-up: JIT compilation, not timed
    t_s, t_p = [], []
    for r in range(args.rounds):
        t0 = time.perf_counter()
        smap = sionna_map(scene, args.rays, args.depth, seed=r + 1)
        t_s.append(time.perf_counter() - t0)
        t_p.append(run_propsim(args.propsim, obj_path, mat_path, out, args.rays, args.depth, extra))
        print(f"round {r + 1}: sionna {t_s[-1]:.2f} s, propsim {t_p[-1]:.2f} s", file=sys.stderr)
    pmap = propsim_map(out)
    result = {
        "rays": args.rays, "depth": args.depth, "rounds": args.rounds,
        "propsim_args": extra,
        "sionna_warm_s_median": statistics.median(t_s),
        "propsim_command_s_median": statistics.median(t_p),
        "ratio_propsim_over_sionna": statistics.median(t_p) / statistics.median(t_s),
        "propsim_vs_sionna_reference": compare(pmap, ref),
        "sionna_same_rays_vs_reference": compare(np.where(smap > 0, smap, np.nan), ref),
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
