//! `propsim render` from the command line: defaults, formats, automatic camera, progress
//! quiet when piped, and a clean one-line error for every bad input.

mod common;

use std::path::Path;

fn propsim_in(dir: &Path, args: &[&str]) -> (bool, String, String) {
    common::propsim_in(Some(dir), args)
}

fn assert_clean_error(args: &[&str], needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let (ok, _, err) = propsim_in(dir.path(), args);
    common::check_one_line_error(args, ok, &err, needles);
    assert!(!dir.path().join("out").exists(), "{args:?}: nothing written on error");
}

/// A room open at the front (y = 0), with a ceiling lamp facing down.
const ROOM_OBJ: &str = "\
v 0 0 0
v 4 0 0
v 4 3 0
v 0 3 0
v 0 0 2.5
v 4 0 2.5
v 4 3 2.5
v 0 3 2.5
usemtl floor_red
f 1 2 3 4
usemtl wall
f 2 3 7 6
f 4 1 5 8
usemtl lamp
f 8 7 6 5
";

const ROOM_MTL: &str = "\
newmtl floor_red
Kd 0.8 0.1 0.1
newmtl wall
Kd 0.7 0.7 0.7
newmtl lamp
Kd 0 0 0
Ke 4 4 4
";

#[test]
fn no_arguments_renders_the_classic_cornell_box_to_out_render_png() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, out, err) = propsim_in(dir.path(), &["render"]);
    assert!(ok, "{err}");
    assert!(err.is_empty(), "quiet when piped: {err}");
    assert!(out.contains("out/render.png") && out.contains("256x256"), "{out}");
    let img = image::open(dir.path().join("out/render.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (256, 256));
    // Red wall on the left, green on the right, a bright light at the top centre.
    let left = img.get_pixel(20, 128).0;
    let right = img.get_pixel(236, 128).0;
    assert!(left[0] > 2 * left[1] && right[1] > right[0], "{left:?} {right:?}");
    assert!(img.get_pixel(128, 32).0.iter().all(|&c| c > 200));
}

#[test]
fn bare_obj_gets_an_automatic_camera_and_exr_output_is_linear_float() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("room.obj"), format!("mtllib room.mtl\n{ROOM_OBJ}")).unwrap();
    std::fs::write(dir.path().join("room.mtl"), ROOM_MTL).unwrap();
    let (ok, out, err) = propsim_in(
        dir.path(),
        &[
            "render",
            "room.obj",
            "-o",
            "img/room.exr",
            "--width",
            "40",
            "--height",
            "30",
            "--spp",
            "8",
            "--threads",
            "2",
        ],
    );
    assert!(ok, "{err}");
    assert!(out.contains("40x30"), "{out}");
    let img = exr::prelude::read_first_rgba_layer_from_file(
        dir.path().join("img/room.exr"),
        |r, _| vec![(0.0f32, 0.0f32, 0.0f32); r.width() * r.height()],
        |v: &mut Vec<(f32, f32, f32)>, p, (r, g, b, _a): (f32, f32, f32, f32)| {
            v[p.y() * 40 + p.x()] = (r, g, b)
        },
    )
    .unwrap();
    let px = &img.layer_data.channel_data.pixels;
    assert_eq!(px.len(), 40 * 30);
    // The automatic view sees the room: plenty of lit pixels, some red floor.
    assert!(px.iter().filter(|p| p.0 + p.1 + p.2 > 0.0).count() > 120);
    assert!(px.iter().any(|p| p.0 > 3.0 * p.1 && p.0 > 0.01));
    // The flags override the automatic camera; every integrator runs.
    for integrator in ["raycast", "whitted", "distributed", "path", "light", "bdpt", "sppm", "ppm"] {
        let (ok, _, err) = propsim_in(
            dir.path(),
            &[
                "render",
                "room.obj",
                "-o",
                "r.png",
                "--width",
                "16",
                "--height",
                "16",
                "--spp",
                "1",
                "--integrator",
                integrator,
                "--eye",
                "2,1.5,1.2",
                "--target",
                "2,3,1",
                "--up",
                "0,0,1",
                "--fov-deg",
                "60",
                "--seed",
                "7",
                "--max-depth",
                "3",
            ],
        );
        assert!(ok, "{integrator}: {err}");
    }
}

#[test]
fn bad_inputs_give_one_line_errors() {
    // Small defaults, unless the case sets the flag itself.
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut v = vec!["render"];
        for (flag, value) in [("--width", "8"), ("--height", "8"), ("--spp", "1")] {
            if !extra.contains(&flag) {
                v.extend([flag, value]);
            }
        }
        v.extend(extra);
        v
    };
    assert_clean_error(&with(&["--spp", "0"]), &["spp 0"]);
    assert_clean_error(&with(&["--width", "0"]), &["width 0"]);
    assert_clean_error(&with(&["--height", "20000"]), &["height 20000", "16384"]);
    assert_clean_error(&with(&["--integrator", "photon"]), &["photon", "path"]);
    assert_clean_error(&with(&["--eye", "nan,0,0"]), &["--eye", "finite"]);
    assert_clean_error(&with(&["--eye", "1,2"]), &["--eye", "X,Y,Z"]);
    assert_clean_error(&with(&["--eye", "1,1,1", "--target", "1,1,1"]), &["eye and target"]);
    assert_clean_error(&with(&["--up", "0,1,0"]), &["up"]);
    assert_clean_error(&with(&["--fov-deg", "0"]), &["field of view"]);
    assert_clean_error(&with(&["--fov-deg", "NaN"]), &["field of view"]);
    assert_clean_error(&with(&["--max-depth", "5000"]), &["max depth"]);
    assert_clean_error(
        &with(&["--integrator", "sppm", "--sppm-radius", "0"]),
        &["--sppm-radius 0", "positive"],
    );
    assert_clean_error(&with(&["--integrator", "sppm", "--sppm-radius", "-1"]), &["--sppm-radius -1"]);
    assert_clean_error(
        &with(&["--integrator", "vcm", "--sppm-radius", "1e30"]),
        &["--sppm-radius", "at most"],
    );
    assert_clean_error(&with(&["--integrator", "ppm", "--photons", "0"]), &["--photons 0"]);
    assert_clean_error(&with(&["--integrator", "sppm", "--iterations", "0"]), &["--iterations 0"]);
    assert_clean_error(&with(&["--photons", "100"]), &["--photons", "sppm"]);
    // The fog: its flags belong to volpath and raymarch; bad coefficients and asymmetries are
    // named.
    assert_clean_error(
        &with(&["--fog-g", "0.5"]),
        &["--fog-g applies to --integrator volpath or raymarch, not path"],
    );
    assert_clean_error(&with(&["--integrator", "raymarch", "--fog-g", "-1"]), &["asymmetry g -1"]);
    assert_clean_error(&with(&["--integrator", "volpath", "--fog-g", "1"]), &["asymmetry g 1"]);
    assert_clean_error(
        &with(&["--integrator", "volpath", "--fog-sigma-s", "-1,0,0"]),
        &["fog scattering -1,0,0"],
    );
    assert_clean_error(&with(&["--integrator", "volpath", "--fog-sigma-a", "0,1e9,0"]), &["fog absorption"]);
    assert_clean_error(&with(&["--integrator", "volpath", "--fog-sigma-a", "nan,0,0"]), &["--fog-sigma-a"]);
    // A flag of one integrator given with another is refused by name, even at its default
    // value: it would do nothing, and a silent no-op hides a wrong --integrator.
    assert_clean_error(
        &with(&["--mlt-chains", "10"]),
        &["--mlt-chains applies to --integrator pssmlt, not path"],
    );
    for flag in [
        "--mlt-chains",
        "--mlt-mutations-per-pixel",
        "--mlt-large-step-probability",
        "--mlt-sigma",
        "--mlt-bootstrap",
    ] {
        assert_clean_error(&with(&["--integrator", "bdpt", flag, "1"]), &[flag, "pssmlt, not bdpt"]);
    }
    assert_clean_error(
        &with(&["--integrator", "path", "--mlt-chains", "1000"]),
        &["--mlt-chains", "not path"],
    );
    // The clamp is the path tracer's: the integrators that ignore it refuse it.
    for integrator in ["bdpt", "spectral", "volpath"] {
        let not = format!("not {integrator}");
        assert_clean_error(
            &with(&["--integrator", integrator, "--clamp-indirect", "10"]),
            &["--clamp-indirect", "path or distributed", &not],
        );
    }
    for (flag, integrator) in
        [("--iterations", "light"), ("--photons", "pssmlt"), ("--sppm-radius", "radiosity")]
    {
        assert_clean_error(
            &with(&["--integrator", integrator, flag, "2"]),
            &[&format!("{flag} applies to --integrator sppm, ppm or vcm, not {integrator}")],
        );
    }
    for (flag, value) in [
        ("--radiosity-method", "matrix"),
        ("--radiosity-patches", "64"),
        ("--radiosity-patch-area", "0.1"),
        ("--radiosity-max-patches", "1000"),
        ("--radiosity-refine", "0.01"),
        ("--radiosity-tolerance", "0.001"),
        ("--radiosity-samples", "4"),
    ] {
        assert_clean_error(
            &with(&["--integrator", "sppm", flag, value]),
            &[&format!("{flag} applies to --integrator radiosity, not sppm")],
        );
    }
    // The integrator may come from the scene file's [render] table as well.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("room.obj"), format!("mtllib room.mtl\n{ROOM_OBJ}")).unwrap();
    std::fs::write(dir.path().join("room.mtl"), ROOM_MTL).unwrap();
    std::fs::write(
        dir.path().join("scene.toml"),
        "obj = \"room.obj\"\n[render]\nintegrator = \"bdpt\"\nwidth = 8\nheight = 8\nspp = 1\n",
    )
    .unwrap();
    let (ok, _, err) = propsim_in(dir.path(), &["render", "scene.toml", "--mlt-sigma", "0.1"]);
    common::check_one_line_error(&["render", "scene.toml"], ok, &err, &["--mlt-sigma", "pssmlt, not bdpt"]);
    assert_clean_error(&with(&["-o", "picture.jpg"]), &["picture.jpg", ".png"]);
    assert_clean_error(&with(&["-o", "picture"]), &["picture", "extension"]);
    assert_clean_error(&["render", "missing.toml"], &["missing.toml"]);
    assert_clean_error(&["render", "builtin:nope"], &["nope"]);
}

#[test]
fn each_integrators_own_flags_are_accepted_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let small = ["--width", "8", "--height", "8", "--spp", "1", "--max-depth", "2", "-o", "r.png"];
    for extra in [
        &["--integrator", "pssmlt", "--mlt-chains", "4", "--mlt-bootstrap", "100", "--mlt-sigma", "0.05"][..],
        &["--integrator", "ppm", "--iterations", "2", "--photons", "100", "--sppm-radius", "0.05"][..],
        &["--integrator", "radiosity", "--radiosity-patches", "64", "--radiosity-samples", "1"][..],
    ] {
        let args: Vec<&str> = ["render"].iter().chain(&small).chain(extra).copied().collect();
        let (ok, _, err) = propsim_in(dir.path(), &args);
        assert!(ok, "{args:?}: {err}");
    }
}

#[test]
fn a_scene_without_light_gets_one_warning_line_except_under_the_headlight() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("dark.obj"), format!("mtllib dark.mtl\n{ROOM_OBJ}")).unwrap();
    // The same room with its lamp switched off: nothing emits and the background is black.
    std::fs::write(dir.path().join("dark.mtl"), ROOM_MTL.replace("Ke 4 4 4", "Ke 0 0 0")).unwrap();
    let (ok, _, err) =
        propsim_in(dir.path(), &["render", "dark.obj", "--width", "32", "--height", "24", "--spp", "1"]);
    assert!(ok, "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(lines[0].starts_with("warning: dark.obj: no light"), "{err}");
    let (ok, _, err) = propsim_in(
        dir.path(),
        &[
            "render",
            "dark.obj",
            "--width",
            "32",
            "--height",
            "24",
            "--integrator",
            "raycast",
            "--output",
            "r.png",
        ],
    );
    assert!(ok && err.is_empty(), "{err}");
    // The lit room: no warning.
    std::fs::write(dir.path().join("dark.mtl"), ROOM_MTL).unwrap();
    let (ok, _, err) =
        propsim_in(dir.path(), &["render", "dark.obj", "--width", "32", "--height", "24", "--spp", "1"]);
    assert!(ok && err.is_empty(), "{err}");
}

/// `--spectral` is `--integrator spectral`, bit for bit; and through the prism of
/// rooms/prism the spectral integrator spreads the white slit into a band many times wider
/// than the RGB path tracer's single slit image. SF11's deviation at minimum deviation runs
/// from 74.7 degrees at 400 nm to 64.7 at 700 nm (Sellmeier), against the slit's 0.34 degrees
/// (6 mm at 1 m): without dispersion the band would be as narrow as the slit.
#[test]
fn spectral_flag_is_the_spectral_integrator_and_the_prism_spreads_the_slit() {
    let dir = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/prism/scene.toml");
    let small = ["--width", "160", "--height", "64", "--spp", "32"];
    let run = |extra: &[&str], out: &str| {
        let args: Vec<&str> =
            ["render", scene].iter().chain(&small).chain(extra).chain(&["-o", out]).copied().collect();
        let (ok, _, err) = propsim_in(dir.path(), &args);
        assert!(ok, "{args:?}: {err}");
        let (descr, shape, data) = common::read_npy(&dir.path().join(out));
        assert_eq!((descr.as_str(), shape.as_slice()), ("<f4", &[64usize, 160, 3][..]));
        data.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect::<Vec<f32>>()
    };
    let flag = run(&["--spectral"], "flag.npy");
    let named = run(&["--integrator", "spectral"], "named.npy");
    assert_eq!(
        flag.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        named.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    let rgb = run(&["--integrator", "path"], "path.npy");
    // Columns of the middle row whose summed RGB is over a tenth of the brightest column's.
    let lit_columns = |img: &[f32]| {
        let row = 32 * 160 * 3;
        let col: Vec<f32> =
            (0..160).map(|x| img[row + 3 * x..row + 3 * x + 3].iter().map(|v| v.max(0.0)).sum()).collect();
        let top = col.iter().copied().fold(0.0f32, f32::max);
        assert!(top > 0.0, "the slit is not seen");
        col.iter().filter(|&&c| c > 0.1 * top).count()
    };
    let (spectral_width, rgb_width) = (lit_columns(&flag), lit_columns(&rgb));
    eprintln!("prism: lit columns spectral {spectral_width}, path {rgb_width}");
    assert!(spectral_width >= 5 * rgb_width, "spectral {spectral_width} columns, path {rgb_width}");
}
