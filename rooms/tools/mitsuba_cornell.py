"""Mitsuba 3 on propsim's classic Cornell box: speed and error, for `propsim bench render`.

Usage (pip install mitsuba numpy; Dr.Jit's LLVM backend needs libLLVM >= 16, e.g.
apt-get install libllvm19 and DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1):

    propsim render -o ours_ref.exr --spp 4096 --seed 99
    for s in 5 6 7; do propsim render -o ours64_$s.exr --spp 64 --seed $s; done
    python3 rooms/tools/mitsuba_cornell.py rooms/cornell_box_classic ours_ref.exr ours64_5.exr ours64_6.exr ours64_7.exr

or, for speed alone, alternating with `propsim bench render` so that both see the same machine:

    python3 rooms/tools/mitsuba_cornell.py rooms/cornell_box_classic --alternate ROUNDS target/release/propsim

It times Mitsuba's 64-spp render (median of 5, for each sampler) and prints, for each of
Mitsuba's samplers and for propsim, the RMSE at 64 spp (pooled over the seeds) against the mean of the two
references (propsim's and a 1024-spp Mitsuba render).

Same geometry (the OBJ split per usemtl), same colours and emitter, two-sided diffuse (propsim's
Lambert is two-sided; the shell's normals point out of the box), box pixel filter, and
max_depth 9 = propsim's 8 bounces (Mitsuba counts the camera segment).
"""
import os, sys, tempfile, time
import numpy as np
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
room, ours_ref = sys.argv[1:3]
tmp = tempfile.mkdtemp()
verts, faces, cur = [], {}, None
for line in open(os.path.join(room, "cornell_box_classic.obj")):
    line = line.split("#")[0].strip()
    if line.startswith("v "):
        verts.append(line)
    elif line.startswith("usemtl"):
        cur = line.split()[1]
    elif line.startswith("f "):
        faces.setdefault(cur, []).append(line)
for m, fs in faces.items():
    open(os.path.join(tmp, m + ".obj"), "w").write("\n".join(verts + fs) + "\n")
colours = {"cornell_white": [0.73] * 3, "cornell_red": [0.65, 0.05, 0.05],
           "cornell_green": [0.12, 0.45, 0.15], "cornell_light": [0.78] * 3}
scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 9},
         "sensor": {"type": "perspective", "fov": 39.3, "fov_axis": "y",
                    "to_world": mi.ScalarTransform4f().look_at(origin=[0.278, -0.8, 0.273],
                                                               target=[0.278, 0.5592, 0.273], up=[0, 0, 1]),
                    "film": {"type": "hdrfilm", "width": 256, "height": 256, "rfilter": {"type": "box"}},
                    "sampler": {"type": "independent"}}}
for m, c in colours.items():
    shape = {"type": "obj", "filename": os.path.join(tmp, m + ".obj"), "face_normals": True,
             "bsdf": {"type": "twosided", "b": {"type": "diffuse", "reflectance": {"type": "rgb", "value": c}}}}
    if m == "cornell_light":
        shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": [17, 12, 4]}}
    scene[m] = shape
def load(sampler):
    scene["sensor"]["sampler"] = {"type": sampler}
    return mi.load_dict(scene)

if sys.argv[2] == "--alternate":
    import re, statistics, subprocess
    rounds, propsim = int(sys.argv[3]), sys.argv[4]
    samplers = {name: load(name) for name in ["multijitter", "ldsampler"]}
    def mitsuba_speed(sc):
        """Median of 3 timed 64-spp renders, in M samples/s."""
        mi.render(sc, spp=4, seed=0)  # JIT warm-up
        times = []
        for k in range(3):
            t = time.time()
            mi.render(sc, spp=64, seed=7 + k)
            times.append(time.time() - t)
        return 256 * 256 * 64 / sorted(times)[1] / 1e6
    def propsim_speed():
        # Dr.Jit's worker threads spin for a while after a render; let them go idle first.
        time.sleep(3)
        out = subprocess.run([propsim, "bench", "render", "--repeat", "3"], capture_output=True, text=True).stdout
        return float(re.search(r"samples/s\s+([0-9.]+)", out).group(1))
    ratios = {name: [] for name in samplers}
    for r in range(rounds):
        before = propsim_speed()
        theirs = {name: mitsuba_speed(sc) for name, sc in samplers.items()}
        after = propsim_speed()
        ours = (before + after) / 2
        print(f"round {r}: propsim {before:.2f} / {after:.2f}, mitsuba "
              + ", ".join(f"{n} {v:.2f}" for n, v in theirs.items()), "M samples/s", flush=True)
        for name, v in theirs.items():
            ratios[name].append(ours / v)
    for name, v in ratios.items():
        print(f"speed propsim / mitsuba {name}: median {statistics.median(v):.3f}, range {min(v):.3f}-{max(v):.3f}")
    sys.exit(0)

s = load("independent")
render = lambda spp, seed, sc=None: np.array(mi.render(sc or s, spp=spp, seed=seed))[..., :3]
render(4, 0)  # JIT warm-up
times = []
for k in range(5):
    t = time.time()
    m64 = render(64, 7 + k)
    times.append(time.time() - t)
t = sorted(times)[2]
ld = load("ldsampler")
ref = sum(render(128, 1000 + k, ld) for k in range(8)) / 8
theirs_ref = np.array(mi.Bitmap(ours_ref))[..., :3]
comb = (ref + theirs_ref) / 2
rmse = lambda a, b: float(np.sqrt(((a - b) ** 2).sum(-1).mean()))
pooled = lambda imgs: float(np.sqrt(np.mean([rmse(a, comb) ** 2 for a in imgs])))
print("reference means: mitsuba", ref.mean((0, 1)), "propsim", theirs_ref.mean((0, 1)),
      "RMSE between them", rmse(ref, theirs_ref))
print(f"mitsuba 64 spp: {t:.3f} s median, {256 * 256 * 64 / t / 1e6:.2f} M samples/s")
def speed(sc):
    """Median of 5 timed 64-spp renders of scene `sc`, in M samples/s."""
    render(4, 0, sc)  # JIT warm-up
    times = []
    for k in range(5):
        t = time.time()
        render(64, 7 + k, sc)
        times.append(time.time() - t)
    return 256 * 256 * 64 / sorted(times)[2] / 1e6
for name in ["independent", "stratified", "multijitter", "ldsampler"]:
    sc = load(name)
    print(f"mitsuba {name:12s} 64 spp RMSE {pooled([render(64, 7 + k, sc) for k in range(3)]):.5f}, "
          f"{speed(sc):.2f} M samples/s")
ours = [np.array(mi.Bitmap(f))[..., :3] for f in sys.argv[3:]]
print(f"propsim              64 spp RMSE {pooled(ours):.5f}")
