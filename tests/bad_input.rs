//! The bad-input catalogue (issue 21, point 3): one test per case, across every command and
//! file kind. Each asserts exactly one `error:` line on stderr naming the problem (and the
//! file, where there is one), a non-zero exit that is neither a panic (101) nor a signal,
//! nothing written, and an end within a second, in an address space of 2 GB (so that an
//! absurd size cannot allocate gigabytes on the way).

mod common;

use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::BOX_OBJ;

const SHOEBOX: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/shoebox/scene.toml");

/// The box with an MTL library `box.mtl` (whose text each case gives) for surface `paint`.
const PAINTED_OBJ: &str = "mtllib box.mtl\nv 0 0 0\nv 4 0 0\nv 0 3 0\nusemtl paint\nf 1 2 3\n";

/// A scene of the box with one source and one receiver; cases replace the positions.
const BOX_SCENE: &str = "obj = \"box.obj\"
[acoustic]
[[acoustic.sources]]
name = \"S1\"
position = [1.0, 1.0, 1.2]
[[acoustic.receivers]]
name = \"R1\"
position = [3.0, 2.0, 1.2]
";

/// Bytes that are not text.
const BINARY: &[u8] = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe\x00\x01\xc3\x28";

/// A file the case creates in its directory.
enum File {
    Text(&'static str, &'static str),
    Bytes(&'static str, &'static [u8]),
    Dir(&'static str),
}

struct Case {
    /// Arguments; `{dir}` is the case's directory, `{out}` the output path in it, `{shoebox}`
    /// the shipped shoebox scene.
    args: &'static [&'static str],
    files: &'static [File],
    /// Words the error line must hold (with the placeholders above).
    needles: &'static [&'static str],
    env: &'static [(&'static str, &'static str)],
}

const fn case(args: &'static [&'static str], needles: &'static [&'static str]) -> Case {
    Case { args, files: &[], needles, env: &[] }
}

const fn with_files(
    args: &'static [&'static str],
    files: &'static [File],
    needles: &'static [&'static str],
) -> Case {
    Case { args, files, needles, env: &[] }
}

/// Longest a case may take: absurd sizes are refused before any work.
const LIMIT: Duration = Duration::from_secs(1);
/// Address space the child may use, bytes.
const ADDRESS_SPACE: u64 = 2 << 30;

fn files_under(dir: &Path) -> Vec<String> {
    let mut all = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        all.push(p.display().to_string());
        if p.is_dir() && !p.is_symlink() {
            all.extend(files_under(&p));
        }
    }
    all.sort();
    all
}

fn check(name: &str, c: Case) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display().to_string();
    let fill =
        |s: &str| s.replace("{dir}", &d).replace("{out}", &format!("{d}/out")).replace("{shoebox}", SHOEBOX);
    for f in c.files {
        match f {
            File::Text(n, t) => std::fs::write(dir.path().join(n), t).unwrap(),
            File::Bytes(n, b) => std::fs::write(dir.path().join(n), b).unwrap(),
            File::Dir(n) => std::fs::create_dir_all(dir.path().join(n)).unwrap(),
        }
    }
    let before = files_under(dir.path());
    let args: Vec<String> = c.args.iter().map(|a| fill(a)).collect();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_propsim"));
    cmd.args(&args)
        .current_dir(dir.path())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for (k, v) in c.env {
        cmd.env(k, v);
    }
    // SAFETY: setrlimit is async-signal-safe and touches only the child.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit { rlim_cur: ADDRESS_SPACE, rlim_max: ADDRESS_SPACE };
            if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let started = Instant::now();
    let out = cmd.output().expect("the binary runs");
    let took = started.elapsed();
    let err = String::from_utf8_lossy(&out.stderr);
    let shown = format!("{name}: propsim {}", args.join(" "));
    let code = out.status.code();
    assert!(code.is_some(), "{shown}: died by a signal ({:?}): {err}", out.status);
    assert!(code != Some(0), "{shown}: should fail; stderr: {err}");
    assert!(code != Some(101) && !err.contains("panicked"), "{shown}: panicked: {err}");
    // A command-line mistake keeps clap's tip and usage lines after its one error line.
    let clap_help = |l: &str| {
        let t = l.trim_start();
        t.starts_with("tip:") || t.starts_with("Usage:") || t.starts_with("For more information, try")
    };
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty() && !clap_help(l)).collect();
    assert_eq!(lines.len(), 1, "{shown}: one line expected on stderr, got: {err}");
    assert!(lines[0].starts_with("error: "), "{shown}: {}", lines[0]);
    for n in c.needles {
        let n = fill(n);
        assert!(lines[0].contains(&n), "{shown}: the error should mention \"{n}\": {}", lines[0]);
    }
    assert_eq!(files_under(dir.path()), before, "{shown}: nothing may be written");
    assert!(took < LIMIT, "{shown}: took {took:?}");
    if std::env::var("PROPSIM_SHOW_ERRORS").is_ok() {
        eprintln!("{name} ({:.0} ms): {}", took.as_secs_f64() * 1e3, lines[0]);
    }
}

macro_rules! catalogue {
    ($($name:ident: $case:expr;)*) => {
        $(
            #[test]
            fn $name() {
                check(stringify!($name), $case);
            }
        )*
        /// Every case's name.
        const CASES: &[&str] = &[$(stringify!($name)),*];
    };
}

#[test]
fn the_catalogue_has_at_least_40_cases() {
    assert!(CASES.len() >= 40, "{} cases", CASES.len());
}

catalogue! {
    // Numeric flags: zero, negative, NaN, infinite, absurd.
    acoustic_rays_zero: case(&["acoustic", "{shoebox}", "--rays", "0", "--out", "{out}"], &["rays", "between 1"]);
    acoustic_rays_absurd: case(&["acoustic", "{shoebox}", "--rays", "100000000000000", "--out", "{out}"], &["rays", "10^9"]);
    acoustic_max_time_negative: case(&["acoustic", "{shoebox}", "--max-time-s", "-1", "--out", "{out}"], &["maximum time -1"]);
    acoustic_max_time_absurd: case(&["acoustic", "{shoebox}", "--max-time-s", "1e9", "--out", "{out}"], &["maximum time"]);
    acoustic_temperature_nan: case(&["acoustic", "{shoebox}", "--temperature-c", "nan", "--out", "{out}"], &["temperature NaN"]);
    acoustic_humidity_negative: case(&["acoustic", "{shoebox}", "--humidity-percent", "-5", "--out", "{out}"], &["humidity -5"]);
    acoustic_receiver_radius_zero: case(&["acoustic", "{shoebox}", "--receiver-radius-m", "0", "--out", "{out}"], &["radius 0"]);
    acoustic_ism_order_absurd: case(&["acoustic", "{shoebox}", "--ism-order", "1000", "--out", "{out}"], &["--ism-order 1000"]);
    render_spp_zero: case(&["render", "{shoebox}", "--spp", "0", "-o", "{out}/r.png"], &["spp 0"]);
    render_width_absurd: case(&["render", "{shoebox}", "--width", "100000000", "-o", "{out}/r.png"], &["width 100000000"]);
    render_height_zero: case(&["render", "{shoebox}", "--height", "0", "-o", "{out}/r.png"], &["height 0"]);
    render_max_depth_absurd: case(&["render", "{shoebox}", "--max-depth", "1000000", "-o", "{out}/r.png"], &["max depth 1000000"]);
    render_fov_zero: case(&["render", "{shoebox}", "--fov-deg", "0", "-o", "{out}/r.png"], &["field of view"]);
    render_fov_nan: case(&["render", "{shoebox}", "--fov-deg", "nan", "-o", "{out}/r.png"], &["field of view"]);
    render_eye_infinite: case(&["render", "{shoebox}", "--eye", "inf,0,1", "-o", "{out}/r.png"], &["--eye", "not finite"]);
    render_too_big_for_the_memory: Case {
        args: &["render", "{shoebox}", "--width", "16384", "--height", "16384", "-o", "{out}/r.png"],
        files: &[],
        needles: &["16384x16384", "memory", "PROPSIM_MAX_MEMORY_MB"],
        env: &[("PROPSIM_MAX_MEMORY_MB", "1000")],
    };
    render_unknown_integrator: case(&["render", "{shoebox}", "--integrator", "magic", "-o", "{out}/r.png"], &["--integrator", "magic"]);
    rf_cell_zero: case(&["rf", "{shoebox}", "--cell-m", "0", "--out", "{out}"], &["cell size"]);
    rf_cell_nan: case(&["rf", "{shoebox}", "--cell-m", "nan", "--out", "{out}"], &["cell size"]);
    rf_cell_too_small_for_the_grid: case(&["rf", "{shoebox}", "--cell-m", "1e-6", "--out", "{out}"], &["too many"]);
    rf_freq_negative: case(&["rf", "{shoebox}", "--freq-ghz", "-1", "--out", "{out}"], &["--freq-ghz", "-1", "positive"]);
    rf_freq_infinite: case(&["rf", "{shoebox}", "--freq-ghz", "inf", "--out", "{out}"], &["--freq-ghz", "inf", "positive"]);
    rf_grid_height_absurd: case(&["rf", "{shoebox}", "--grid-height", "1e9", "--out", "{out}"], &["grid height 1000000000"]);
    rf_png_width_zero: case(&["rf", "{shoebox}", "--png-width", "0", "--out", "{out}"], &["--png-width 0"]);
    rf_png_width_absurd: case(&["rf", "{shoebox}", "--png-width", "1000000000", "--out", "{out}"], &["--png-width 1000000000"]);
    rf_rays_zero: case(&["rf", "{shoebox}", "--rays", "0", "--out", "{out}"], &["--rays 0"]);
    rf_max_depth_absurd: case(&["rf", "{shoebox}", "--max-depth", "1000", "--out", "{out}"], &["--max-depth 1000"]);
    rf_wall_thickness_negative: case(&["rf", "{shoebox}", "--wall-thickness-m", "-0.1", "--out", "{out}"], &["--wall-thickness-m"]);
    rf_tx_power_absurd: case(&["rf", "{shoebox}", "--tx-power-dbm", "1e300", "--out", "{out}"], &["--tx-power-dbm", "dBm"]);
    rf_cfr_points_zero: case(&["rf", "{shoebox}", "--cfr-bandwidth-mhz", "10", "--cfr-points", "0", "--out", "{out}"], &["--cfr-points 0"]);
    bench_trace_repeat_zero: case(&["bench", "trace", "--repeat", "0"], &["--repeat 0"]);
    bench_trace_ray_count_zero: case(&["bench", "trace", "--ray-count", "0"], &["--ray-count 0"]);
    bench_trace_beyond_the_memory: Case {
        args: &["bench", "trace", "--triangles", "100000000"],
        files: &[],
        needles: &["100000000 triangles", "memory", "PROPSIM_MAX_MEMORY_MB"],
        env: &[("PROPSIM_MAX_MEMORY_MB", "1000")],
    };
    bench_render_repeat_zero: case(&["bench", "render", "--repeat", "0"], &["--repeat 0"]);
    bench_rf_repeat_zero: case(&["bench", "rf", "{shoebox}", "--repeat", "0"], &["--repeat 0"]);
    bench_acoustic_rays_zero: case(&["bench", "acoustic", "{shoebox}", "--rays", "0"], &["--rays 0"]);
    threads_zero: case(&["--threads", "0", "info", "{shoebox}"], &["--threads 0"]);
    threads_absurd: case(&["--threads", "100000", "info", "{shoebox}"], &["--threads 100000"]);

    // MTL values: short, non-finite, out of range; a binary MTL.
    mtl_colour_with_one_value: with_files(&["info", "{dir}/box.obj"],
        &[File::Text("box.obj", PAINTED_OBJ), File::Text("box.mtl", "newmtl paint\nKd 0.5\n")],
        &["box.mtl", "line 2", "three numbers"]);
    mtl_colour_nan: with_files(&["render", "{dir}/box.obj", "-o", "{out}/r.png"],
        &[File::Text("box.obj", PAINTED_OBJ), File::Text("box.mtl", "newmtl paint\nKd nan -5 1e40\n")],
        &["box.mtl", "line 2", "\"nan\"", "finite"]);
    mtl_colour_negative: with_files(&["info", "{dir}/box.obj"],
        &[File::Text("box.obj", PAINTED_OBJ), File::Text("box.mtl", "newmtl paint\nKd 0.5 -5 0.5\n")],
        &["box.mtl", "line 2", "[0, 1]"]);
    mtl_emission_negative: with_files(&["info", "{dir}/box.obj"],
        &[File::Text("box.obj", PAINTED_OBJ), File::Text("box.mtl", "newmtl paint\nKd 0.5 0.5 0.5\nKe -1 0 0\n")],
        &["box.mtl", "line 3", "negative"]);
    mtl_dissolve_above_one: with_files(&["info", "{dir}/box.obj"],
        &[File::Text("box.obj", PAINTED_OBJ), File::Text("box.mtl", "newmtl paint\nKd 0.5 0.5 0.5\nd 2\n")],
        &["box.mtl", "line 3", "[0, 1]"]);
    mtl_binary: with_files(&["info", "{dir}/box.obj"],
        &[File::Text("box.obj", PAINTED_OBJ), File::Bytes("box.mtl", BINARY)],
        &["box.mtl", "cannot be opened"]);

    // Materials files: out of range, non-finite, wrong lengths, wrong kinds of file.
    materials_absorption_above_one: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.concrete]\nabsorption = 1.5\n")],
        &["m.toml", "concrete", "outside [0, 1]"]);
    materials_absorption_negative: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.concrete]\nabsorption = [0.1, 0.1, -0.1, 0.1, 0.1, 0.1]\n")],
        &["m.toml", "concrete", "outside [0, 1]"]);
    materials_absorption_wrong_length: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.concrete]\nabsorption = [0.1, 0.2, 0.3]\n")],
        &["m.toml", "concrete", "got 3"]);
    materials_scattering_nan: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.concrete]\nabsorption = 0.1\nscattering = nan\n")],
        &["m.toml", "concrete", "scattering"]);
    materials_colour_wrong_length: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.concrete]\ncolor = [0.5, 0.5]\n")],
        &["m.toml", "line 2"]);
    materials_permittivity_below_one: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.concrete]\nrelative_permittivity = 0.5\n")],
        &["m.toml", "concrete", "relative_permittivity"]);
    materials_sellmeier_c_negative: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.flint]\nkind = \"dielectric\"\nsellmeier_b = [1.0, 0.2, 1.0]\nsellmeier_c = [-0.006, 0.02, 100.0]\n")],
        &["m.toml", "flint", "sellmeier_c", ">= 0"]);
    materials_sellmeier_b_nan: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.flint]\nkind = \"dielectric\"\nsellmeier_b = [nan, 0.2, 1.0]\nsellmeier_c = [0.006, 0.02, 100.0]\n")],
        &["m.toml", "flint", "sellmeier_b", "finite"]);
    materials_sellmeier_c_nan: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.flint]\nkind = \"dielectric\"\nsellmeier_b = [1.0, 0.2, 1.0]\nsellmeier_c = [0.006, nan, 100.0]\n")],
        &["m.toml", "flint", "sellmeier_c"]);
    materials_abbe_number_zero: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.crown]\nkind = \"dielectric\"\nior = 1.52\nabbe_number = 0\n")],
        &["m.toml", "crown", "abbe_number", "> 0"]);
    materials_abbe_number_negative: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.crown]\nkind = \"dielectric\"\nior = 1.52\nabbe_number = -40\n")],
        &["m.toml", "crown", "abbe_number", "> 0"]);
    materials_dispersion_on_a_diffuse_material: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.paint]\ncolor = [0.5, 0.5, 0.5]\nabbe_number = 40\n")],
        &["m.toml", "paint", "abbe_number", "dielectric"]);
    materials_sellmeier_without_c: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("m.toml", "[materials.flint]\nkind = \"dielectric\"\nsellmeier_b = [1.0, 0.2, 1.0]\n")],
        &["m.toml", "flint", "sellmeier_b needs sellmeier_c"]);
    render_spectral_with_another_integrator: case(&["render", "{shoebox}", "--spectral", "--integrator", "bdpt", "-o", "{out}/r.png"],
        &["--spectral", "bdpt"]);
    materials_binary: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Bytes("m.toml", BINARY)],
        &["m.toml", "cannot read"]);
    materials_is_a_directory: with_files(&["info", "{dir}/box.obj", "--materials", "{dir}/m.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Dir("m.toml")],
        &["m.toml", "cannot read"]);

    // Scene files and OBJs: empty, binary, directories.
    scene_empty: with_files(&["info", "{dir}/s.toml"], &[File::Text("s.toml", "")], &["s.toml", "no geometry"]);
    scene_binary: with_files(&["acoustic", "{dir}/s.toml", "--out", "{out}"], &[File::Bytes("s.toml", BINARY)], &["s.toml", "cannot read"]);
    scene_is_a_directory: with_files(&["info", "{dir}/s.toml"], &[File::Dir("s.toml")], &["s.toml", "cannot read"]);
    scene_names_a_directory_as_obj: with_files(&["info", "{dir}/s.toml"],
        &[File::Text("s.toml", "obj = \"sub\"\n"), File::Dir("sub")],
        &["sub", "cannot read"]);
    obj_empty: with_files(&["render", "{dir}/box.obj", "-o", "{out}/r.png"], &[File::Text("box.obj", "")], &["box.obj", "empty"]);
    obj_binary: with_files(&["rf", "{dir}/box.obj", "--out", "{out}"], &[File::Bytes("box.obj", BINARY)], &["box.obj", "cannot read"]);
    obj_is_a_directory: with_files(&["info", "{dir}/box.obj"], &[File::Dir("box.obj")], &["box.obj", "cannot read"]);
    obj_missing: case(&["info", "{dir}/nowhere.obj"], &["nowhere.obj", "not found"]);

    // Positions: on a surface, outside the room, not finite.
    scene_source_on_the_floor: with_files(&["acoustic", "{dir}/s.toml", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[acoustic]\n[[acoustic.sources]]\nname = \"S1\"\nposition = [1.0, 1.0, 0.0]\n[[acoustic.receivers]]\nname = \"R1\"\nposition = [3.0, 2.0, 1.2]\n")],
        &["s.toml", "source \"S1\"", "0.01 m"]);
    scene_receiver_outside_the_room: with_files(&["acoustic", "{dir}/s.toml", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[acoustic]\n[[acoustic.sources]]\nname = \"S1\"\nposition = [1.0, 1.0, 1.2]\n[[acoustic.receivers]]\nname = \"R1\"\nposition = [9.0, 2.0, 1.2]\n")],
        &["s.toml", "\"R1\"", "outside the room"]);
    scene_source_not_finite: with_files(&["acoustic", "{dir}/s.toml", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[acoustic]\n[[acoustic.sources]]\nname = \"S1\"\nposition = [1.0, nan, 1.2]\n")],
        &["s.toml", "S1", "non-finite"]);
    cli_receiver_on_a_wall: with_files(&["acoustic", "{dir}/s.toml", "--receiver", "3.995,1,1", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", BOX_SCENE)],
        &["s.toml", "receiver \"R1\"", "0.01 m"]);
    cli_source_outside_the_room: with_files(&["acoustic", "{dir}/s.toml", "--source", "-1,1,1", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", BOX_SCENE)],
        &["s.toml", "source \"S1\"", "outside the room"]);
    cli_transmitter_on_a_wall: with_files(&["rf", "{dir}/s.toml", "--tx", "0,1,1", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", BOX_SCENE)],
        &["s.toml", "transmitter", "0.01 m"]);
    scene_sphere_radius_zero: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[spheres]]\ncenter = [1, 1, 1]\nradius_m = 0\nmaterial = \"concrete\"\n")],
        &["s.toml", "radius 0"]);
    scene_light_intensity_negative: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[lights]]\nposition = [1, 1, 1]\nintensity = [-30, 1e38, 30]\n")],
        &["s.toml", "light 1", "intensity"]);
    scene_render_width_zero: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[render]\nwidth = 0\n")],
        &["s.toml", "width 0"]);
    scene_rf_grid_cell_zero: with_files(&["rf", "{dir}/s.toml", "--tx", "1,1,1", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[rf.grid]\ncell_m = 0.0\n")],
        &["s.toml", "cell size"]);

    // Ray files of `bench trace`.
    ray_file_empty: with_files(&["bench", "trace", "{dir}/box.obj", "--rays", "{dir}/r.bin"],
        &[File::Text("box.obj", BOX_OBJ), File::Bytes("r.bin", b"")],
        &["r.bin", "24 bytes per ray"]);
    ray_file_not_finite: with_files(&["bench", "trace", "{dir}/box.obj", "--rays", "{dir}/r.bin"],
        &[File::Text("box.obj", BOX_OBJ), File::Bytes("r.bin", &[0, 0, 0xc0, 0x7f, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x80, 0x3f, 0, 0, 0, 0, 0, 0, 0, 0])],
        &["r.bin", "ray 0", "not finite"]);
    ray_file_is_a_directory: with_files(&["bench", "trace", "{dir}/box.obj", "--rays", "{dir}/r.bin"],
        &[File::Text("box.obj", BOX_OBJ), File::Dir("r.bin")],
        &["r.bin", "cannot read"]);

    // Outputs that cannot be written.
    render_output_is_a_directory: with_files(&["render", "{shoebox}", "--width", "8", "--height", "8", "-o", "{dir}/r.png"],
        &[File::Dir("r.png")], &["r.png", "directory"]);
    render_output_under_a_file: with_files(&["render", "{shoebox}", "--width", "8", "--height", "8", "-o", "{dir}/f/r.png"],
        &[File::Text("f", "")], &["f/r.png"]);
    render_output_unknown_format: case(&["render", "{shoebox}", "-o", "{out}/r.bmp"], &["r.bmp"]);
    acoustic_out_is_a_file: with_files(&["acoustic", "{shoebox}", "--rays", "100", "--out", "{dir}/f"],
        &[File::Text("f", "")], &["{dir}/f"]);
    rf_out_under_a_file: with_files(&["rf", "{shoebox}", "--rays", "100", "--out", "{dir}/f/rf"],
        &[File::Text("f", "")], &["f/rf"]);
    run_out_under_a_device: case(&["run", "{shoebox}", "--out", "/dev/null/out"], &["/dev/null/out"]);
    // Instances (issue 24): singular and non-finite transforms, an unknown mesh, nesting.
    instance_singular_scale: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[instances]]\nname = \"flat\"\nmesh = \"box.obj\"\nscale = [1, 1, 0]\n")],
        &["{dir}/s.toml", "instance \"flat\"", "singular"]);
    instance_matrix_not_finite: with_files(&["acoustic", "{dir}/s.toml", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[instances]]\nmesh = \"box.obj\"\nmatrix = [[1, 0, 0, nan], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n")],
        &["{dir}/s.toml", "instance #1", "non-finite"]);
    instance_unknown_mesh: with_files(&["rf", "{dir}/s.toml", "--out", "{out}"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[instances]]\nname = \"car\"\nmesh = \"sedan\"\n")],
        &["{dir}/s.toml", "instance \"car\"", "unknown mesh \"sedan\""]);
    instance_nested_scene: with_files(&["info", "{dir}/s.toml"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[instances]]\nname = \"me\"\nmesh = \"s.toml\"\n")],
        &["{dir}/s.toml", "instance \"me\"", "do not nest"]);
    // Participating media (issue 26): density grids and [[media]] entries.
    media_grid_missing: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\ngrid = \"g.txt\"\nbounds_min = [0, 0, 0]\nbounds_max = [4, 3, 2.5]\n")],
        &["g.txt", "not found", "smoke"]);
    media_grid_wrong_count: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\ngrid = \"g.txt\"\nbounds_min = [0, 0, 0]\nbounds_max = [4, 3, 2.5]\n"), File::Text("g.txt", "2 2 2\n1 1 1\n")],
        &["g.txt", "3 densities", "expected 8"]);
    media_grid_empty: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\ngrid = \"g.txt\"\nbounds_min = [0, 0, 0]\nbounds_max = [4, 3, 2.5]\n"), File::Text("g.txt", "0 4 4\n")],
        &["g.txt", "empty density grid"]);
    media_grid_negative: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\ngrid = \"g.txt\"\nbounds_min = [0, 0, 0]\nbounds_max = [4, 3, 2.5]\n"), File::Text("g.txt", "1 1 2\n0.5 -1\n")],
        &["g.txt", "number 2 is -1", "0 or more"]);
    media_grid_nan: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\ngrid = \"g.txt\"\nbounds_min = [0, 0, 0]\nbounds_max = [4, 3, 2.5]\n"), File::Text("g.txt", "1 1 1\nnan\n")],
        &["g.txt", "NaN", "finite"]);
    media_grid_huge: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\ngrid = \"g.txt\"\nbounds_min = [0, 0, 0]\nbounds_max = [4, 3, 2.5]\n"), File::Text("g.txt", "100000 100000 100000\n")],
        &["g.txt", "more than"]);
    media_grid_raw_wrong_size: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\ngrid = \"g.raw\"\ngrid_dims = [2, 2, 2]\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n"), File::Bytes("g.raw", &[0, 0, 0, 0, 0])],
        &["g.raw", "5 bytes", "expected 32"]);
    media_bounds_inverted: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\ngrid = \"g.txt\"\nbounds_min = [0, 0, 3]\nbounds_max = [4, 3, 2.5]\n"), File::Text("g.txt", "1 1 1\n1\n")],
        &["g.txt", "bounds_min", "below bounds_max"]);
    media_negative_coefficient: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_a = [0.1, -1, 0]\n")],
        &["{dir}/s.toml", "medium \"smoke\"", "sigma_a"]);
    media_unknown_boundary: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\nboundary = \"glass_box\"\n")],
        &["{dir}/s.toml", "medium \"smoke\"", "\"glass_box\" is no usemtl"]);
    raymarch_step_zero: case(&["render", "{shoebox}", "-o", "{out}/r.png", "--integrator", "raymarch", "--raymarch-step", "0"],
        &["raymarch step 0", "above 0"]);
    raymarch_step_with_path: case(&["render", "{shoebox}", "-o", "{out}/r.png", "--raymarch-step", "0.01"],
        &["--raymarch-step", "raymarch", "not path"]);
    media_and_fog_both_fill_the_scene: with_files(&["render", "{dir}/s.toml", "-o", "{out}/r.png", "--integrator", "volpath", "--fog-sigma-s", "1,1,1"],
        &[File::Text("box.obj", BOX_OBJ), File::Text("s.toml", "obj = \"box.obj\"\n[[media]]\nname = \"smoke\"\nsigma_s = [1, 1, 1]\n")],
        &["{dir}/s.toml", "\"smoke\"", "both fill the scene"]);
}
