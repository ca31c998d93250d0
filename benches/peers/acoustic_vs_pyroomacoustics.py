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
metrics and every output file). Both print T30 and EDT at 1 kHz (pyroomacoustics' impulse
response filtered to the 1 kHz octave, Schroeder-integrated); the exact image-source values
of this room, T30 1.014 s and EDT 0.767 s, come from tests/acoustic_physics.rs
(`specular_shoebox_t30_matches_the_exact_image_source_decay_in_every_band`).

With --equal-error, propsim then runs at growing ray counts (three seeds each) and prints
the worst T30 and EDT error of each, to find the ray count whose worst error is at most
pyroomacoustics' median error at --rays (over its rounds).
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
    rir = room.rir[0][0]
    t30, edt = octave_decay_times(rir, room.fs, 1000.0)
    return seconds, t30, edt


EXACT_T30_S = 1.014
EXACT_EDT_S = 0.767


def octave_decay_times(rir, fs, centre_hz):
    """T30 (-5 to -35 dB) and EDT (0 to -10 dB) of the octave band at centre_hz, from the
    Schroeder integral (ISO 3382-1), fitted by least squares."""
    import numpy as np
    from scipy.signal import butter, sosfiltfilt

    sos = butter(4, [centre_hz / np.sqrt(2), centre_hz * np.sqrt(2)], btype="band", fs=fs, output="sos")
    energy = sosfiltfilt(sos, rir) ** 2
    start = int(np.argmax(energy))
    tail = np.cumsum(energy[start:][::-1])[::-1]
    db = 10 * np.log10(tail / tail[0] + 1e-300)
    t = np.arange(len(db)) / fs

    def fit(hi, lo):
        sel = (db <= hi) & (db >= lo)
        slope = np.polyfit(t[sel], db[sel], 1)[0]
        return -60.0 / slope

    return float(fit(-5, -35)), float(fit(0, -10))


def run_propsim(binary, scene, rays, out, seed=1):
    start = time.perf_counter()
    result = subprocess.run([binary, "acoustic", scene, "--rays", str(rays), "--out", out,
                             "--seed", str(seed)], check=True, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    t30 = edt = None
    for line in result.stdout.splitlines():
        # the 1 kHz column (63 125 250 500 1000 ...)
        if line.startswith("T30 s"):
            t30 = float(line.split()[6])
        if line.startswith("EDT s"):
            edt = float(line.split()[6])
    return seconds, t30, edt


def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=1_000_000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--binary", default=os.path.join(root, "target", "release", "propsim"))
    parser.add_argument("--equal-error", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "scene.toml")
        with open(scene, "w") as f:
            f.write(SCENE.format(obj=os.path.join(root, "rooms", "shoebox", "shoebox.obj")))
        pra_times, ours_times = [], []
        pra_errors = []
        for k in range(args.rounds):
            p_s, p_t30, p_edt = run_pyroomacoustics(args.rays)
            o_s, o_t30, o_edt = run_propsim(args.binary, scene, args.rays, os.path.join(tmp, "out"))
            pra_times.append(p_s)
            ours_times.append(o_s)
            pra_errors.append((abs(p_t30 / EXACT_T30_S - 1), abs(p_edt / EXACT_EDT_S - 1)))
            print(f"round {k + 1}: pyroomacoustics ray_tracing {p_s:.2f} s (1 kHz T30 {p_t30:.3f} s, "
                  f"EDT {p_edt:.3f} s), propsim acoustic {o_s:.2f} s (T30 {o_t30:.3f} s, "
                  f"EDT {o_edt:.3f} s); exact T30 {EXACT_T30_S} s, EDT {EXACT_EDT_S} s", flush=True)
        p, o = statistics.median(pra_times), statistics.median(ours_times)
        print(f"medians: pyroomacoustics {p:.2f} s, propsim {o:.2f} s, ratio {p / o:.2f}x")
        if not args.equal_error:
            return
        pra_t30_err = statistics.median(e[0] for e in pra_errors)
        pra_edt_err = statistics.median(e[1] for e in pra_errors)
        print(f"pyroomacoustics at {args.rays} rays: median T30 error {100 * pra_t30_err:.1f} %, "
              f"median EDT error {100 * pra_edt_err:.1f} % (best {100 * min(e[0] for e in pra_errors):.1f} %, "
              f"{100 * min(e[1] for e in pra_errors):.1f} %)")
        for rays in [1000, 3000, 10_000, 30_000, 100_000]:
            runs = [run_propsim(args.binary, scene, rays, os.path.join(tmp, "out"), seed) for seed in (1, 2, 3)]
            t30_err = max(abs(r[1] / EXACT_T30_S - 1) for r in runs)
            edt_err = max(abs(r[2] / EXACT_EDT_S - 1) for r in runs)
            seconds = statistics.median(r[0] for r in runs)
            ok = t30_err <= pra_t30_err and edt_err <= pra_edt_err
            print(f"propsim {rays} rays: worst of 3 seeds T30 error {100 * t30_err:.1f} %, EDT error "
                  f"{100 * edt_err:.1f} %, {seconds:.2f} s (ratio {p / seconds:.1f}x)"
                  f"{'  <- at most the peer error' if ok else ''}", flush=True)


if __name__ == "__main__":
    sys.exit(main())
