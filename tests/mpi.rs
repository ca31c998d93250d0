//! Distributed runs for real: installs Open MPI when it is missing, builds propsim with
//! `--features mpi`, and checks that `mpirun -n 2` and `mpirun -n 3` (an uneven split of
//! rays, tiles and cells) write byte-identical outputs to a single-process run with the same
//! seed, for every simulator and for `propsim run`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

const MANIFEST_DIR: &str = env!("CARGO_MANIFEST_DIR");

/// Debian's packages for building and running against Open MPI (bindgen needs libclang).
const PACKAGES: [&str; 3] = ["libopenmpi-dev", "openmpi-bin", "libclang-dev"];

fn on_path(program: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {program}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

fn has_libclang() -> bool {
    let found = Command::new("sh")
        .args(["-c", "ls /usr/lib/llvm-*/lib/libclang*.so* /usr/lib/*/libclang*.so* 2>/dev/null | head -1"])
        .output()
        .map(|o| !o.stdout.is_empty());
    found.unwrap_or(false)
}

/// Installs Open MPI and libclang with apt-get unless they are there already.
fn ensure_open_mpi() {
    if on_path("mpirun") && on_path("mpicc") && has_libclang() {
        return;
    }
    assert!(on_path("apt-get"), "Open MPI is missing and apt-get is not available: install {PACKAGES:?}");
    let sudo = if on_path("id")
        && Command::new("id")
            .arg("-u")
            .output()
            .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() != "0")
    {
        "sudo "
    } else {
        ""
    };
    let script = format!(
        "{sudo}apt-get update -qq && DEBIAN_FRONTEND=noninteractive {sudo}apt-get install -y -qq --no-install-recommends {}",
        PACKAGES.join(" ")
    );
    let out = Command::new("sh").args(["-c", &script]).output().expect("sh runs");
    assert!(
        out.status.success(),
        "installing {PACKAGES:?} failed: {}",
        String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
    );
    assert!(on_path("mpirun"), "mpirun is still missing after installing {PACKAGES:?}");
}

/// The propsim binary built with `--features mpi` (in its own target directory, so it does
/// not wait on the build lock of the `cargo test` that runs this).
fn mpi_binary() -> &'static Path {
    static BINARY: OnceLock<PathBuf> = OnceLock::new();
    BINARY.get_or_init(|| {
        ensure_open_mpi();
        let target = Path::new(env!("CARGO_TARGET_TMPDIR")).join("../mpi");
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let out = Command::new(cargo)
            .current_dir(MANIFEST_DIR)
            .env("CARGO_TARGET_DIR", &target)
            .args(["build", "--profile", "ci", "--features", "mpi", "--bin", "propsim"])
            .output()
            .expect("cargo runs");
        assert!(
            out.status.success(),
            "cargo build --features mpi failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        target.join("ci/propsim")
    })
}

/// Runs `propsim ARGS` under `mpirun -n ranks` (or alone for `ranks == 0`) in `dir`.
fn run(dir: &Path, ranks: u32, args: &[&str]) {
    let binary = mpi_binary();
    let mut cmd = if ranks == 0 {
        Command::new(binary)
    } else {
        let mut c = Command::new("mpirun");
        c.args(["-n", &ranks.to_string(), "--oversubscribe"]).arg(binary);
        c
    };
    let out = cmd
        .current_dir(dir)
        .args(args)
        // CI runs as root in a container: allow it, and use shared memory without ptrace.
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .output()
        .expect("mpirun runs");
    assert!(
        out.status.success(),
        "{ranks} ranks, propsim {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Keys of the JSON summaries that legitimately differ between runs: timings, the process
/// count and the output paths.
const VOLATILE_KEYS: [&str; 12] = [
    "seconds",
    "segments_per_second",
    "diffraction_seconds",
    "rays_per_second",
    "wall_time_s",
    "trace_time_s",
    "reduce",
    "trace_seconds",
    "timings_s",
    "processes",
    "threads",
    "outputs",
];

fn strip_volatile(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(map) => {
            for k in VOLATILE_KEYS {
                map.remove(k);
            }
            map.values_mut().for_each(strip_volatile);
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(strip_volatile),
        _ => {}
    }
}

/// Every file in `dir`: bytes, or for JSON files the parsed value without volatile keys.
fn outputs(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    for entry in std::fs::read_dir(dir).expect("output directory exists") {
        let path = entry.expect("entry").path();
        let name = path.file_name().expect("name").to_string_lossy().to_string();
        let bytes = std::fs::read(&path).expect("readable");
        let bytes = if name.ends_with(".json") {
            let mut v: serde_json::Value = serde_json::from_slice(&bytes).expect("valid JSON");
            strip_volatile(&mut v);
            serde_json::to_vec(&v).expect("serialises")
        } else {
            bytes
        };
        files.insert(name, bytes);
    }
    files
}

/// Runs `args` (which write into the directory `out`) alone and under 2 and 3 ranks, and
/// asserts byte-identical outputs.
fn same_outputs_for_any_rank_count(name: &str, args: &[&str]) {
    let base = tempfile::tempdir().expect("temp dir");
    let mut reference: Option<BTreeMap<String, Vec<u8>>> = None;
    for ranks in [0u32, 2, 3] {
        let dir = base.path().join(format!("{name}-{ranks}"));
        std::fs::create_dir_all(dir.join("out")).expect("mkdir");
        run(&dir, ranks, args);
        let got = outputs(&dir.join("out"));
        assert!(!got.is_empty(), "{name}: no outputs");
        match &reference {
            None => reference = Some(got),
            Some(r) => {
                assert_eq!(r.keys().collect::<Vec<_>>(), got.keys().collect::<Vec<_>>(), "{name}: file sets");
                for (file, bytes) in r {
                    assert!(
                        got[file] == *bytes,
                        "{name}: out/{file} differs between 1 process and {ranks} ranks"
                    );
                }
            }
        }
    }
}

#[test]
fn mpi_render_is_byte_identical_for_1_2_and_3_ranks() {
    // 100 x 60 pixels: 7 x 4 = 28 tiles of 16, which 3 ranks cannot split evenly.
    same_outputs_for_any_rank_count(
        "render",
        &[
            "render",
            "builtin:cornell_box",
            "-o",
            "out/render.png",
            "--width",
            "100",
            "--height",
            "60",
            "--spp",
            "8",
        ],
    );
}

#[test]
fn mpi_light_transport_integrators_are_byte_identical_for_1_2_and_3_ranks() {
    // The integrators that splat light paths anywhere on the film (a rank's light paths land
    // on tiles other ranks render) or share one normalisation (pssmlt's bootstrap), as linear
    // EXR so that every bit of every pixel is compared. 100 x 60 pixels, 28 tiles; sppm's
    // 20,000 photons an iteration are 5 blocks of 4,096, and 37 chains and 3,000 bootstrap
    // samples a depth split over no rank count evenly; vcm's 7,000 light subpaths (every rank
    // traces them all) are more than the 6,000 pixels that each join one.
    let small =
        ["builtin:cornell_box", "-o", "out/render.exr", "--width", "100", "--height", "60", "--spp", "8"];
    for (integrator, extra) in [
        ("light", &[][..]),
        ("bdpt", &[][..]),
        ("sppm", &["--photons", "20000"][..]),
        ("pssmlt", &["--mlt-bootstrap", "3000", "--mlt-chains", "37"][..]),
        ("vcm", &["--photons", "7000"][..]),
    ] {
        let mut args = vec!["render", "--integrator", integrator];
        args.extend(small);
        args.extend(extra);
        same_outputs_for_any_rank_count(&format!("render-{integrator}"), &args);
    }
}

#[test]
fn mpi_radiosity_fields_fog_prism_and_bent_rays_are_byte_identical_for_1_2_and_3_ranks() {
    // Radiosity (every rank solves the same system), signed distance fields (path traced),
    // the fog (volpath), the prism (spectral), the smoke's density grid and ink cube (volpath,
    // raymarch), and the acoustic rays bent at the showcase's corner edge.
    for (name, scene, integrator, extra) in [
        (
            "radiosity",
            "rooms/cornell_radiosity/scene.toml",
            "radiosity",
            &["--radiosity-patch-area", "0.01"][..],
        ),
        ("sdf", "rooms/sdf/scene.toml", "path", &[][..]),
        ("volpath", "rooms/fog/scene.toml", "volpath", &[][..]),
        ("spectral", "rooms/prism/scene.toml", "spectral", &[][..]),
        ("smoke-volpath", "rooms/smoke/scene.toml", "volpath", &[][..]),
        ("smoke-raymarch", "rooms/smoke/scene.toml", "raymarch", &[][..]),
        ("caustics-vcm", "rooms/caustics/scene.toml", "vcm", &[][..]),
        // bdpt's split pixels (the ball and the mirror) with their walks for paths no join makes.
        ("caustics-bdpt", "rooms/caustics/scene.toml", "bdpt", &[][..]),
    ] {
        let scene = format!("{MANIFEST_DIR}/{scene}");
        let mut args = vec!["render", &scene, "--integrator", integrator, "-o", "out/render.exr"];
        args.extend(["--width", "60", "--height", "40", "--spp", "4"]);
        args.extend(extra);
        same_outputs_for_any_rank_count(&format!("render-{name}"), &args);
    }
    same_outputs_for_any_rank_count(
        "acoustic-bent",
        &["acoustic", "builtin:showcase", "--rays", "20000", "--out", "out"],
    );
}

#[test]
fn mpi_acoustic_is_byte_identical_for_1_2_and_3_ranks() {
    // 20,000 rays: 20 blocks of 1024, the last one short; with the directional outputs
    // (their direction histograms are summed across ranks like the energy histograms).
    same_outputs_for_any_rank_count(
        "acoustic",
        &[
            "acoustic",
            "builtin:shoebox",
            "--rays",
            "20000",
            "--directivity",
            "cardioid",
            "--ambisonic-order",
            "3",
            "--binaural",
            "--out",
            "out",
        ],
    );
}

#[test]
fn mpi_rf_is_byte_identical_for_1_2_and_3_ranks() {
    let scene = format!("{MANIFEST_DIR}/rooms/street_canyon/scene.toml");
    same_outputs_for_any_rank_count("rf", &["rf", &scene, "--rays", "300000", "--out", "out"]);
    // Diffuse reflection draws its directions from each ray's own stream as well.
    same_outputs_for_any_rank_count(
        "rf-diffuse",
        &[
            "rf",
            &scene,
            "--rays",
            "100000",
            "--scattering-coefficient",
            "0.6",
            "--no-receivers",
            "--out",
            "out",
        ],
    );
}

#[test]
fn mpi_run_is_byte_identical_for_1_2_and_3_ranks() {
    same_outputs_for_any_rank_count("run", &["run", "--out", "out"]);
}
