#!/usr/bin/env python3
"""propsim acoustic against pyroomacoustics' ray tracer, side by side on one machine.

The shoebox of issue 19: 10 x 8 x 3 m, energy absorption 0.2 and scattering 0 on every
surface, source (2, 3, 1.5), receiver (7, 5, 1.6), 20 C and 50 % relative humidity, air
absorption on. Rounds alternate between the two tools; medians are reported.

    pip install pyroomacoustics
    cargo build --release
    python3 benches/peers/acoustic_vs_pyroomacoustics.py --rays 1000000 --rounds 3

pyroomacoustics is timed on `room.ray_tracing()` alone (its C++ ray tracer, one thread);
propsim on the whole `propsim acoustic` command (trace, image sources, impulse responses,
metrics and every output file). Both print T30 at 1 kHz; the exact image-source value of
this room is in docs/acoustics.md.
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOM = "[10, 8, 3]"
SCENE = """obj = "{obj}"
[surfaces]
floor = "spec"
walls = "spec"
ceiling = "spec"
[materials.spec]
absorption = [0.2, 0.2, 0.2, 0.2, 0.2, 0.2]
scattering = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
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


def run_pyroomacoustics(rays):
    import pyroomacoustics as pra

    material = pra.Material(energy_absorption=0.2, scattering=0.0)
    room = pra.ShoeBox([10, 8, 3], fs=16000, materials=material, max_order=2,
                       ray_tracing=True, air_absorption=True)
    room.set_ray_tracing(n_rays=rays)
    room.add_source([2, 3, 1.5])
    room.add_microphone([7, 5, 1.6])
    start = time.perf_counter()
    room.ray_tracing()
    seconds = time.perf_counter() - start
    room.compute_rir()
    t30 = float(room.measure_rt60(decay_db=30)[0][0])
    return seconds, t30


def run_propsim(binary, scene, rays, out):
    start = time.perf_counter()
    result = subprocess.run([binary, "acoustic", scene, "--rays", str(rays), "--out", out],
                            check=True, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    t30 = None
    for line in result.stdout.splitlines():
        if line.startswith("T30 s"):
            t30 = float(line.split()[6])  # the 1 kHz column (63 125 250 500 1000 ...)
    return seconds, t30


def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=1_000_000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--binary", default=os.path.join(root, "target", "release", "propsim"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "scene.toml")
        with open(scene, "w") as f:
            f.write(SCENE.format(obj=os.path.join(root, "rooms", "shoebox", "shoebox.obj")))
        pra_times, ours_times = [], []
        for k in range(args.rounds):
            p_s, p_t30 = run_pyroomacoustics(args.rays)
            o_s, o_t30 = run_propsim(args.binary, scene, args.rays, os.path.join(tmp, "out"))
            pra_times.append(p_s)
            ours_times.append(o_s)
            print(f"round {k + 1}: pyroomacoustics ray_tracing {p_s:.2f} s (T30 1 kHz {p_t30:.3f} s), "
                  f"propsim acoustic {o_s:.2f} s (T30 1 kHz {o_t30:.3f} s)", flush=True)
        p, o = statistics.median(pra_times), statistics.median(ours_times)
        print(f"medians: pyroomacoustics {p:.2f} s, propsim {o:.2f} s, ratio {p / o:.2f}x")


if __name__ == "__main__":
    sys.exit(main())
