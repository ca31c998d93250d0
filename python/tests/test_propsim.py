"""The Python module against closed forms and the command line's behaviour, with small
settings (a few thousand rays, tiny images) so that the suite takes seconds."""

import json
import math

import numpy as np
import pytest

import propsim

C0 = 299_792_458.0


def tiny_render(**options):
    return propsim.render(width=24, height=16, spp=2, max_depth=2, **options)


def test_render_returns_a_linear_float32_image_of_the_asked_size():
    r = tiny_render()
    img = r["image"]
    assert img.shape == (16, 24, 3)
    assert img.dtype == np.float32
    assert np.isfinite(img).all() and (img >= 0).all()
    assert img.mean() > 0, "the Cornell box is lit"
    assert r["settings"]["width"] == 24 and r["settings"]["spp"] == 2
    assert r["settings"]["integrator"] == "path" and r["settings"]["seed"] == 0
    assert r["files"] == []


def test_render_same_seed_same_image_bit_for_bit_on_any_thread_count():
    a = tiny_render(seed=5)["image"]
    b = tiny_render(seed=5, threads=1)["image"]
    c = tiny_render(seed=6)["image"]
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_render_writes_what_the_cli_writes(tmp_path):
    r = tiny_render(out=tmp_path)
    assert (tmp_path / "render.png").is_file()
    npy = tmp_path / "render.npy"
    r2 = tiny_render(output=str(npy))
    assert np.array_equal(np.load(npy), r2["image"])
    assert np.array_equal(r["image"], r2["image"])


def shoebox(**options):
    # 10 x 8 x 3 m; source and receiver 5 m apart at the same height.
    settings = {"rays": 2000, "ism_order": 1, **options}
    return propsim.acoustic("builtin:shoebox", sources=[(2.0, 2.0, 1.5)], receivers=[(6.0, 5.0, 1.5)], **settings)


def test_acoustic_shapes_and_names():
    a = shoebox()
    pairs, bands = 1, len(a["bands_hz"])
    assert bands == 8
    h = a["histogram"]
    assert h.dtype == np.float64 and h.shape[:2] == (pairs, bands) and h.shape[2] > 100
    assert a["metrics"].shape == (pairs, bands, 15)
    assert len(a["metric_names"]) == 15 and a["metric_names"][2] == "t30_s"
    assert len(a["impulse_responses"]) == pairs
    ir = a["impulse_responses"][0]
    assert ir.dtype == np.float32 and a["sample_rate_hz"] == 48_000
    assert abs(len(ir) / 48_000 - h.shape[2] * a["bin_s"]) < 0.1
    assert [p["source"] for p in a["pairs"]] == ["S1"] and a["pairs"][0]["receiver"] == "R1"
    assert a["volume_m3"] == pytest.approx(240.0, rel=1e-3)
    assert len(a["sabine_s"]) == bands and len(a["eyring_s"]) == bands
    # The scene's reverberation estimate: 0.161 V / (S alpha) with alpha = 0.1 (no air).
    assert a["settings"]["rays"] == 2000 and a["settings"]["ism_order"] == 1


def test_acoustic_direct_sound_is_one_over_four_pi_d_squared():
    a = shoebox(no_air=True)
    d = 5.0
    pair = a["pairs"][0]
    assert pair["distance_m"] == pytest.approx(d, rel=1e-6)
    k = int(pair["direct_s"] / a["bin_s"])
    expected = 1.0 / (4.0 * math.pi * d * d)
    for b in range(len(a["bands_hz"])):
        assert a["histogram"][0, b, k] == pytest.approx(expected, rel=0.02), b
        assert a["histogram"][0, b, :k].sum() == 0.0


def test_acoustic_same_seed_same_histogram_bit_for_bit():
    a, b = shoebox(seed=7), shoebox(seed=7, threads=1)
    assert np.array_equal(a["histogram"], b["histogram"])
    assert np.array_equal(a["impulse_responses"][0], b["impulse_responses"][0])


def test_acoustic_writes_what_the_cli_writes(tmp_path):
    a = shoebox(out=tmp_path)
    assert np.array_equal(np.load(tmp_path / "histogram.npy"), a["histogram"])
    assert (tmp_path / "metrics.csv").is_file() and (tmp_path / "ir_S1_R1.wav").is_file()
    assert json.loads((tmp_path / "acoustic.json").read_text())["result"]["ism_order"] == 1


FREE_SPACE_OBJ = """\
# One small concrete triangle far from the transmitter: free space for the test.
mtllib free.mtl
v 900 900 900
v 901 900 900
v 900 901 900
usemtl concrete
f 1 2 3
"""

FREE_SPACE_TOML = """\
obj = "free.obj"

[rf]
freq_ghz = 3.5

[[rf.transmitters]]
name = "TX"
position = [0.0, 0.0, 10.0]

[rf.grid]
height_m = 0.0
cell_m = 2.0
min = [-20.0, -20.0]
max = [20.0, 20.0]

[[rf.receivers]]
name = "P"
position = [30.0, 0.0, 0.0]
"""


@pytest.fixture
def free_space(tmp_path):
    (tmp_path / "free.obj").write_text(FREE_SPACE_OBJ)
    (tmp_path / "free.mtl").write_text("newmtl concrete\nKd 0.5 0.5 0.5\n")
    scene = tmp_path / "scene.toml"
    scene.write_text(FREE_SPACE_TOML)
    return scene


def friis(d, f_hz=3.5e9):
    return (C0 / f_hz / (4.0 * math.pi * d)) ** 2


@pytest.mark.filterwarnings("ignore::propsim.PropsimWarning")
def test_rf_free_space_is_friis(free_space):
    r = propsim.rf(free_space, rays=200_000, cfr_bandwidth_mhz=20, cfr_points=8)
    g = r["path_gain"]
    assert g.shape == (1, r["grid"]["ny"], r["grid"]["nx"]) == (1, 20, 20)
    assert r["x_m"].shape == (20,) and r["y_m"].shape == (20,)
    # The cell below the transmitter, centre (1, 1, 0): 10.1 m away.
    i, j = int(np.argmin(abs(r["x_m"] - 1.0))), int(np.argmin(abs(r["y_m"] - 1.0)))
    err_db = 10 * math.log10(g[0, j, i] / friis(math.sqrt(2 + 100)))
    assert abs(err_db) < 1.0, err_db
    # The point receiver 31.6 m away: one path, Friis exactly.
    assert r["paths"].shape == (1, len(r["paths_columns"]))
    d = math.hypot(30.0, 10.0)
    assert r["paths"][0, r["paths_columns"].index("delay_s")] == pytest.approx(d / C0, rel=1e-6)
    gain_db = r["paths"][0, r["paths_columns"].index("gain_db")]
    assert gain_db == pytest.approx(10 * math.log10(friis(d)), abs=0.05)
    # One path: |H(f)|^2 is its gain at every frequency.
    assert r["cfr"].shape == (1, 1, 8) and r["cfr"].dtype == np.complex128
    assert np.allclose(abs(r["cfr"]) ** 2, friis(d), rtol=0.02)


@pytest.mark.filterwarnings("ignore::propsim.PropsimWarning")
def test_rf_same_seed_same_map_bit_for_bit(free_space):
    a = propsim.rf(free_space, rays=20_000, seed=3, no_receivers=True)
    b = propsim.rf(free_space, rays=20_000, seed=3, no_receivers=True, threads=1)
    assert np.array_equal(a["path_gain"], b["path_gain"])
    assert "paths" not in a


def test_run_writes_the_manifest(tmp_path):
    m = propsim.run(out=tmp_path, quick=True, only=["render", "rf"], width=32, height=24, spp=1, rf_rays=5000)
    assert m["parts"]["render"]["status"] == "ran"
    assert m["parts"]["acoustic"]["status"] == "not selected"
    assert (tmp_path / "manifest.json").is_file() and (tmp_path / "render.png").is_file()
    assert {o["path"] for o in m["outputs"]} >= {"render.png", "summary.png", "coverage.npy"}


def test_a_missing_scene_names_the_file(tmp_path):
    missing = tmp_path / "no_such_scene.toml"
    for call in (propsim.render, propsim.acoustic, propsim.rf):
        with pytest.raises(propsim.PropsimError, match="no_such_scene.toml"):
            call(missing)


def test_unknown_options_and_bad_values_are_the_cli_errors():
    with pytest.raises(propsim.PropsimError, match="unknown option 'rayz'") as e:
        propsim.acoustic(rayz=10)
    assert "\n" not in str(e.value)
    assert "did you mean 'rays'?" in str(e.value)
    with pytest.raises(propsim.PropsimError, match="invalid value 'many' for '--rays"):
        propsim.acoustic(rays="many")
    with pytest.raises(propsim.PropsimError, match="--ism-order 7: at most 6"):
        shoebox(ism_order=7)
    with pytest.raises(propsim.PropsimError, match="--threads 0"):
        tiny_render(threads=0)
    with pytest.raises(propsim.PropsimError, match="not both"):
        tiny_render(out="x", output="y.png")
    with pytest.raises(propsim.PropsimError, match="--mlt-chains applies to --integrator pssmlt, not bdpt"):
        tiny_render(integrator="bdpt", mlt_chains=10)
    with pytest.raises(propsim.PropsimError, match="--radiosity-patches applies to --integrator radiosity"):
        tiny_render(radiosity_patches=64)
    assert issubclass(propsim.PropsimError, ValueError)


def test_defaults_are_the_cli_defaults():
    # The render's seed is 0, the acoustic seed 1 and its image-source order 2.
    a = propsim.acoustic("builtin:shoebox", rays=500, sources=[(2, 2, 1.5)], receivers=[(6, 5, 1.5)])
    assert a["settings"]["seed"] == 1 and a["settings"]["ism_order"] == 2
    assert a["settings"]["air_absorption"] is True


def test_points_as_numpy_arrays_and_empty_lists():
    points = np.array([[2.0, 2.0, 1.5], [6.0, 5.0, 1.5], [6.0, 2.0, 1.5]])
    a = propsim.acoustic("builtin:shoebox", sources=points[:1], receivers=points[1:], rays=500, ism_order=0)
    assert [p["receiver"] for p in a["pairs"]] == ["R1", "R2"]
    assert [p["distance_m"] for p in a["pairs"]] == pytest.approx([5.0, 4.0], rel=1e-6)
    # An empty list is no flag: the scene's sources and receivers.
    scene = propsim.acoustic("builtin:shoebox", rays=500, ism_order=0)
    b = propsim.acoustic("builtin:shoebox", sources=[], receivers=(), rays=500, ism_order=0)
    assert b["sources"] == scene["sources"] and b["receivers"] == scene["receivers"]


def test_the_cli_warnings_are_python_warnings():
    with pytest.warns(propsim.PropsimWarning, match="S1 -> R1: receiver within 1 m of the source"):
        a = propsim.acoustic("builtin:shoebox", sources=[(2, 2, 1.5)], receivers=[(2, 2.5, 1.5)], rays=500)
    assert any("within 1 m" in w for w in a["warnings"])
