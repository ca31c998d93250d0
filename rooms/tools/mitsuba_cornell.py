"""Mitsuba 3 on propsim's classic Cornell box: speed and error, for `propsim bench render`.

Usage (pip install mitsuba numpy; Dr.Jit's LLVM backend needs libLLVM >= 16, e.g.
apt-get install libllvm19 and DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1):

    propsim render -o ours_ref.exr --spp 512 --seed 99
    propsim render -o ours64.exr --spp 64 --seed 5
    python3 rooms/tools/mitsuba_cornell.py rooms/cornell_box_classic ours_ref.exr ours64.exr

Same geometry (the OBJ split per usemtl), same colours and emitter, two-sided diffuse (propsim's
Lambert is two-sided; the shell's normals point out of the box), box pixel filter, and
max_depth 9 = propsim's 8 bounces (Mitsuba counts the camera segment).
"""
import os, sys, tempfile, time
import numpy as np
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
room, ours_ref, ours64 = sys.argv[1:4]
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
s = mi.load_dict(scene)
render = lambda spp, seed: np.array(mi.render(s, spp=spp, seed=seed))[..., :3]
render(4, 0)  # JIT warm-up
times = []
for k in range(5):
    t = time.time()
    m64 = render(64, 7 + k)
    times.append(time.time() - t)
t = sorted(times)[2]
ref = sum(render(64, 1000 + k) for k in range(8)) / 8
theirs_ref = np.array(mi.Bitmap(ours_ref))[..., :3]
o64 = np.array(mi.Bitmap(ours64))[..., :3]
comb = (ref + theirs_ref) / 2
rmse = lambda a, b: float(np.sqrt(((a - b) ** 2).sum(-1).mean()))
print("reference means: mitsuba", ref.mean((0, 1)), "propsim", theirs_ref.mean((0, 1)))
print(f"mitsuba 64 spp: {t:.3f} s median, {256 * 256 * 64 / t / 1e6:.2f} M samples/s, RMSE {rmse(m64, comb):.5f}")
print(f"propsim 64 spp: RMSE {rmse(o64, comb):.5f}")
