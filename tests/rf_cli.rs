//! `propsim rf` end to end: outputs, determinism across thread counts, and every bad input
//! as a clean one-line error.

mod common;

use common::{assert_clean_error, propsim};

/// A command-line syntax error (from clap): non-zero exit, first line `error:` with the needles.
fn assert_usage_error(args: &[&str], needles: &[&str]) {
    let (ok, _, err) = propsim(args);
    assert!(!ok && !err.contains("panicked"), "{args:?}: {err}");
    let first = err.lines().next().unwrap_or_default();
    assert!(first.starts_with("error:"), "{err}");
    for n in needles {
        assert!(first.contains(n), "error should mention \"{n}\": {first}");
    }
}

const CANYON: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/street_canyon/scene.toml");
const L_ROOM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/l_room/scene.toml");

#[test]
fn coverage_csv_is_byte_identical_for_one_and_two_threads_and_well_formed() {
    let dir = tempfile::tempdir().unwrap();
    let run = |threads: &str| {
        let out = dir.path().join(format!("t{threads}"));
        let (ok, _, err) = propsim(&[
            "--threads",
            threads,
            "rf",
            CANYON,
            "--rays",
            "300000",
            "--cell-m",
            "2",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(ok, "{err}");
        out
    };
    let (a, b) = (run("1"), run("2"));
    let csv = std::fs::read(a.join("coverage.csv")).unwrap();
    assert_eq!(csv, std::fs::read(b.join("coverage.csv")).unwrap(), "CSV differs between 1 and 2 threads");
    let text = String::from_utf8(csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x_m,y_m,z_m,path_gain_db,rx_power_dbm,paths"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 90 * 60);
    assert!(!text.contains("inf") && !text.contains("NaN"));
    let (mut empty, mut reached, mut diffracted_only) = (0, 0, 0);
    for r in &rows {
        assert_eq!(r.len(), 6);
        assert_eq!(r[2], "1.500");
        if r[3].is_empty() {
            assert!(r[4].is_empty() && r[5] == "0");
            empty += 1;
        } else {
            let g: f64 = r[3].parse().unwrap();
            let p: f64 = r[4].parse().unwrap();
            assert!((p - (g + 30.0)).abs() < 0.002, "rx power = 30 dBm + gain");
            // No ray crossing: the cell's power is diffracted only (a shadowed cell).
            diffracted_only += usize::from(r[5] == "0");
            reached += 1;
        }
    }
    // Cells inside buildings are never reached; the streets are.
    assert!(empty > 1000 && reached > 1000, "{empty} {reached}");
    // Diffraction (on by default) reaches cells no ray path reaches.
    assert!(diffracted_only > 100, "{diffracted_only} cells reached by diffraction alone");
    let png = std::fs::read(a.join("coverage.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("coverage.json")).unwrap()).unwrap();
    assert_eq!(json["config"]["rays"], 300000);
    assert_eq!(json["config"]["transmitters"][0]["freq_ghz"], 3.5);
    assert!(json["estimator"].as_str().unwrap().contains("power (incoherent) sum"));
    assert_eq!(json["receivers"].as_array().unwrap().len(), 3);
}

#[test]
fn materials_outside_their_itu_range_need_extrapolate() {
    // The L-shaped room has floorboard, which ITU-R P.2040-3 gives for 50-100 GHz only.
    assert_clean_error(&["rf", L_ROOM, "--rays", "1000"], &["floorboard", "50-100 GHz", "--extrapolate"]);
    assert_clean_error(
        &["rf", CANYON, "--rays", "1000", "--freq-ghz", "20"],
        &["medium_dry_ground", "--extrapolate"],
    );
    let dir = tempfile::tempdir().unwrap();
    let (ok, out, err) = propsim(&[
        "rf",
        L_ROOM,
        "--rays",
        "20000",
        "--extrapolate",
        "--transmission",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("P_nlos"), "{out}");
}

#[test]
fn bad_inputs_are_one_line_errors() {
    assert_clean_error(&["rf", CANYON, "--cell-m", "0"], &["cell size", "positive"]);
    assert_clean_error(&["rf", CANYON, "--rays", "0"], &["--rays 0"]);
    assert_clean_error(&["rf", CANYON, "--rays", "100000000000"], &["--rays 100000000000", "between 1 and"]);
    assert_clean_error(&["rf", CANYON, "--cell-m", "0.001"], &["too many", "larger cell"]);
    assert_clean_error(&["rf", CANYON, "--freq-ghz", "-1"], &["TX1", "positive"]);
    assert_usage_error(&["rf", CANYON, "--tx", "1,2"], &["--tx", "X,Y,Z"]);
    assert_usage_error(&["rf", CANYON, "--rays", "many"], &["--rays"]);
    assert_clean_error(
        &["rf", CANYON, "--tx", "0,0,10", "--antenna", "yagi"],
        &["yagi", "isotropic or dipole"],
    );
    assert_clean_error(
        &["rf", CANYON, "--polarization", "diagonal"],
        &["diagonal", "vertical or horizontal"],
    );
    assert_clean_error(&["rf", CANYON, "--max-depth", "1000"], &["--max-depth"]);
    assert_clean_error(
        &["rf", CANYON, "--antenna", "dipole", "--orientation", "0,0,0"],
        &["TX1", "not a direction"],
    );
    assert_clean_error(&["rf", CANYON, "--grid-min", "10,10", "--grid-max", "0,0"], &["max must exceed min"]);
    assert_clean_error(&["rf", "builtin:bras_cr2"], &["no transmitter", "--tx"]);
    // A surface known only from the MTL has no radio data.
    let bare = tempfile::tempdir().unwrap();
    std::fs::write(bare.path().join("m.mtl"), "newmtl paint\nKd 0.5 0.5 0.5\n").unwrap();
    let obj = bare.path().join("mtl_only.obj");
    std::fs::write(
        &obj,
        "mtllib m.mtl\nv -50 -50 0\nv 50 -50 0\nv 50 50 0\nv -50 50 0\nusemtl paint\nf 1 2 3 4\n",
    )
    .unwrap();
    assert_clean_error(&["rf", obj.to_str().unwrap(), "--tx", "0,0,10"], &["paint", "no radio properties"]);
    assert_clean_error(&["rf", "no/such/scene.toml"], &["no/such/scene.toml"]);
    for bad in ["0", "-0.1", "nan", "inf"] {
        assert_clean_error(&["rf", CANYON, "--wall-thickness-m", bad], &["--wall-thickness-m", "positive"]);
    }
    // A material's thickness is checked when the file is read, whether walls transmit or not.
    let dir = tempfile::tempdir().unwrap();
    let materials = dir.path().join("thin.toml");
    std::fs::write(&materials, "[materials.concrete]\nitu = \"concrete\"\nthickness_m = 0\n").unwrap();
    let m = materials.to_str().unwrap();
    for extra in [&[][..], &["--no-transmission"][..]] {
        let mut args = vec!["rf", CANYON, "--materials", m];
        args.extend(extra);
        assert_clean_error(&args, &["thin.toml", "concrete", "thickness_m", "positive"]);
    }
    // The radio scattering keys are checked when the file is read: one line naming the file,
    // the material and the key.
    for (bad, key) in [
        ("scattering_coefficient = 1.5", "scattering_coefficient 1.5"),
        ("scattering_coefficient = nan", "scattering_coefficient NaN"),
        ("scattering_coefficient = -0.2", "scattering_coefficient -0.2"),
        ("xpd_coefficient = 1.01", "xpd_coefficient 1.01"),
        ("scattering_coefficient = 0.3\nscattering_pattern = \"directive\"\nalpha_r = 0", "alpha_r 0"),
        ("scattering_coefficient = 0.3\nscattering_pattern = \"glossy\"", "scattering_pattern"),
    ] {
        let file = dir.path().join("rough.toml");
        std::fs::write(&file, format!("[materials.glass]\nitu = \"glass\"\n{bad}\n")).unwrap();
        assert_clean_error(
            &["rf", CANYON, "--materials", file.to_str().unwrap()],
            &["rough.toml", "glass", key],
        );
    }
    for bad in ["1.5", "-0.1", "nan"] {
        assert_clean_error(
            &["rf", CANYON, "--scattering-coefficient", bad],
            &["--scattering-coefficient", "[0, 1]"],
        );
    }
    // Transmitter names name coverage.csv's columns: they must differ.
    let scene = two_transmitters_in_free_space(dir.path());
    let text = std::fs::read_to_string(&scene).unwrap().replace("TXB", "TXA");
    std::fs::write(&scene, text).unwrap();
    assert_clean_error(&["rf", scene.to_str().unwrap()], &["TXA", "used twice", "unique"]);
    for (flags, needles) in [
        (&["--vmin-db", "nan"][..], &["--vmin-db NaN", "finite"][..]),
        (&["--vmax-db", "inf"], &["--vmax-db inf", "finite"]),
        (&["--vmin-db", "-50", "--vmax-db", "-60"], &["--vmin-db -50", "below --vmax-db -60"]),
        (&["--vmin-db", "-50", "--vmax-db", "-50"], &["--vmin-db -50", "below --vmax-db -50"]),
        (&["--bandwidth-mhz", "0"], &["--bandwidth-mhz", "positive"]),
        (&["--noise-figure-db", "-1"], &["--noise-figure-db -1", "0 or more"]),
    ] {
        let mut args = vec!["rf", CANYON];
        args.extend(flags);
        assert_clean_error(&args, needles);
    }
    assert_clean_error(&["rf", CANYON, "--cfr-points", "64"], &["--cfr-points", "--cfr-bandwidth-mhz"]);
    assert_clean_error(&["rf", CANYON, "--cfr-bandwidth-mhz", "0"], &["--cfr-bandwidth-mhz", "positive"]);
    assert_clean_error(
        &["rf", CANYON, "--cfr-bandwidth-mhz", "20", "--cfr-points", "0"],
        &["--cfr-points 0", "between 1 and"],
    );
}

#[test]
fn transmission_is_on_by_default_and_the_flags_switch_it() {
    // The default, `--transmission` (kept, changes nothing) and `--wall-thickness-m 0.1` (the
    // default thickness) give the same bytes; `--no-transmission` leaves the cells inside the
    // buildings empty, which transmission reaches.
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "rf",
            CANYON,
            "--rays",
            "100000",
            "--cell-m",
            "3",
            "--no-receivers",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        let (ok, _, err) = propsim(&args);
        assert!(ok, "{err}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("coverage.json")).unwrap()).unwrap();
        (std::fs::read(out.join("coverage.csv")).unwrap(), json)
    };
    let (default, json) = run("default", &[]);
    assert_eq!(json["config"]["transmission"], true);
    // The summary says how walls were treated, and that diffraction is on: the canyon's 12
    // buildings have 96 free wedges (their bottom edges stand on the ground), and the
    // ground's 4 rims.
    assert_eq!(json["physics"]["transmission"], "on (0.1 m slabs, default)");
    assert_eq!(json["physics"]["diffraction"], "on (first order, UTD, 100 wedges)");
    assert_eq!(json["surfaces"][0]["surfaces"][0]["thickness_m"], 0.1);
    assert_eq!(run("flag", &["--transmission"]).0, default);
    assert_eq!(run("thick", &["--wall-thickness-m", "0.1"]).0, default);
    assert_eq!(run("last", &["--no-transmission", "--transmission"]).0, default);
    let (opaque, json) = run("opaque", &["--no-transmission"]);
    assert_eq!(json["config"]["transmission"], false);
    assert_eq!(json["physics"]["transmission"], "off (opaque walls)");
    let reached =
        |csv: &[u8]| String::from_utf8_lossy(csv).lines().skip(1).filter(|l| !l.contains(",,")).count();
    assert!(reached(&default) > reached(&opaque) + 100, "{} {}", reached(&default), reached(&opaque));
    let (thick, json) = run("thick2", &["--wall-thickness-m", "0.3"]);
    assert_ne!(thick, default);
    assert_eq!(json["surfaces"][0]["surfaces"][0]["thickness_m"], 0.3);
    assert_eq!(json["physics"]["transmission"], "on (0.3 m slabs, --wall-thickness-m)");
    // --no-diffraction: the rays' map alone (every reached cell has ray crossings), fewer
    // cells reached, and the summary says so.
    let (rays_only, json) = run("no_diffraction", &["--no-diffraction"]);
    assert_eq!(json["config"]["diffraction"], false);
    assert_eq!(json["physics"]["diffraction"], "off (--no-diffraction)");
    assert!(json["transmitter_maps"][0].get("diffracted_cells").is_none());
    let text = String::from_utf8_lossy(&rays_only);
    for line in text.lines().skip(1) {
        assert_eq!(line.contains(",,"), line.ends_with(",0"), "{line}");
    }
    assert!(reached(&default) > reached(&rays_only) + 100, "{} {}", reached(&default), reached(&rays_only));
    let on = &serde_json::from_str::<serde_json::Value>(
        &std::fs::read_to_string(dir.path().join("default/coverage.json")).unwrap(),
    )
    .unwrap()["transmitter_maps"][0];
    assert!(
        on["diffracted_cells"].as_u64().unwrap() > 1000 && on["lit_wedges"].as_u64().unwrap() > 10,
        "{on}"
    );
}

#[test]
fn diffuse_reflection_is_off_unless_a_scattering_coefficient_is_given() {
    // S = 0 in a materials file, or `--scattering-coefficient 0`, gives the default's bytes;
    // S > 0 changes the map, and the summary and the title say where it comes from.
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args =
            vec!["rf", CANYON, "--rays", "100000", "--cell-m", "3", "--out", out.to_str().unwrap()];
        args.extend(extra);
        let (ok, _, err) = propsim(&args);
        assert!(ok, "{err}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("coverage.json")).unwrap()).unwrap();
        (
            std::fs::read(out.join("coverage.csv")).unwrap(),
            std::fs::read(out.join("paths.csv")).unwrap(),
            json,
        )
    };
    let (default, default_paths, json) = run("default", &[]);
    assert_eq!(json["physics"]["diffuse_reflection"], "off (S = 0)");
    let zero = dir.path().join("zero.toml");
    std::fs::write(&zero, "[materials.concrete]\nitu = \"concrete\"\nscattering_coefficient = 0\n").unwrap();
    assert_eq!(run("zero", &["--materials", zero.to_str().unwrap()]).0, default);
    assert_eq!(run("flag0", &["--scattering-coefficient", "0"]).0, default);
    let rough = dir.path().join("rough.toml");
    std::fs::write(
        &rough,
        "[materials.concrete]\nitu = \"concrete\"\nscattering_coefficient = 0.5\nxpd_coefficient = 0.2\n",
    )
    .unwrap();
    let (map, paths, json) = run("rough", &["--materials", rough.to_str().unwrap()]);
    assert_ne!(map, default);
    // The point receivers keep the specular paths, each facade reflection at sqrt(1 - S^2).
    assert_ne!(paths, default_paths);
    assert_eq!(
        json["physics"]["diffuse_reflection"],
        "on (S = 0-0.5, lambertian, materials' scattering_coefficient)"
    );
    let concrete = json["surfaces"][0]["surfaces"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["material"] == "concrete")
        .unwrap()
        .clone();
    assert_eq!(concrete["scattering"]["scattering_coefficient"], 0.5);
    assert_eq!(concrete["scattering"]["xpd_coefficient"], 0.2);
    assert_eq!(concrete["scattering"]["pattern"], "lambertian");
    let (_, _, json) = run("flag", &["--scattering-coefficient", "0.7"]);
    assert_eq!(json["physics"]["diffuse_reflection"], "on (S = 0.7, lambertian, --scattering-coefficient)");
    // The diffuse draws come from each ray's own stream: the same bytes on 1 and 2 threads.
    let threads = |n: &str| {
        let out = dir.path().join(format!("threads{n}"));
        let args = ["--threads", n, "rf", CANYON, "--rays", "100000", "--cell-m", "3", "--no-receivers"];
        let (ok, _, err) = propsim(
            &[&args[..], &["--scattering-coefficient", "0.7", "--out", out.to_str().unwrap()]].concat(),
        );
        assert!(ok, "{err}");
        std::fs::read(out.join("coverage.csv")).unwrap()
    };
    assert_eq!(threads("1"), threads("2"));
}

#[test]
fn street_canyon_map_agrees_with_the_exact_paths_at_the_receivers() {
    // The stochastic map's cell value against the exact image-method power sum at the two
    // line-of-sight receivers (direct, ground, facades; up to 3 reflections).
    use propsim::rf::{RfConfig, RfOptions, simulate};
    use propsim::scene::{LoadOptions, World, load};
    let world = World::build(load(CANYON.as_ref(), &LoadOptions::default()).unwrap());
    // The image method finds the reflected paths only, so the map is made with opaque walls
    // (`--no-transmission`): under the defaults it would also hold the paths through the
    // buildings, which the exact sum leaves out.
    let o = RfOptions { rays: Some(2_000_000), no_transmission: true, ..RfOptions::default() };
    let config = RfConfig::from_scene(&world, &o).unwrap();
    let result = simulate(&world, &config, &|_| {}).unwrap();
    let tx = &result.transmitters[0];
    for (r, paths) in config.receivers.iter().zip(&tx.receivers).take(2) {
        let cell = config.grid.cell_of(r.position.x + 0.5, r.position.y + 0.5).unwrap();
        let grid_db = 10.0 * result.coverage.path_gain[cell].log10();
        let exact_db = 10.0 * paths.incoherent_gain.log10();
        eprintln!(
            "{}: grid {grid_db:.2} dB, exact power sum {exact_db:.2} dB, {} paths",
            r.name, paths.paths
        );
        assert!(paths.line_of_sight && paths.paths >= 4);
        assert!((grid_db - exact_db).abs() < 1.0, "{}: {grid_db} vs {exact_db}", r.name);
    }
}

#[test]
fn point_receivers_get_paths_power_delay_profiles_and_frequency_responses() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cir");
    let (ok, stdout, err) = propsim(&[
        "rf",
        CANYON,
        "--rays",
        "20000",
        "--cell-m",
        "4",
        "--cfr-bandwidth-mhz",
        "20",
        "--cfr-points",
        "64",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(stdout.contains("paths.csv"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("coverage.json")).unwrap()).unwrap();
    let receivers = json["receivers"].as_array().unwrap();
    assert_eq!(receivers.len(), 3);
    let text = std::fs::read_to_string(out.join("paths.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "transmitter,receiver,path,delay_s,amplitude_re,amplitude_im,gain_db,aod_azimuth_deg,\
             aod_zenith_deg,aoa_azimuth_deg,aoa_zenith_deg,interactions"
        )
    );
    let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(String::from).collect()).collect();
    let num = |s: &str| s.parse::<f64>().unwrap();
    for rx in receivers {
        let name = rx["name"].as_str().unwrap();
        let mine: Vec<&Vec<String>> = rows.iter().filter(|r| r[1] == name).collect();
        assert_eq!(mine.len() as u64, rx["paths"].as_u64().unwrap(), "{name}");
        // (The receiver behind B01 has no specular path: its rows are diffracted paths only.)
        assert!(!mine.is_empty(), "{name}");
        if name == "P_behind_B01" {
            assert!(mine.iter().all(|r| r[11].starts_with("D:")), "{name}");
        }
        let mut last = 0.0;
        for (k, r) in mine.iter().enumerate() {
            assert_eq!((r.len(), r[0].as_str(), r[2].parse::<usize>().unwrap()), (12, "TX1", k));
            let delay = num(&r[3]);
            assert!(delay >= last && delay > 0.0, "{name}: delays by increasing value");
            last = delay;
            let (re, im) = (num(&r[4]), num(&r[5]));
            assert!((num(&r[6]) - 10.0 * (re * re + im * im).log10()).abs() < 1e-5);
            assert!(num(&r[7]).abs() <= 180.0 && (0.0..=180.0).contains(&num(&r[8])));
            assert!(num(&r[9]).abs() <= 180.0 && (0.0..=180.0).contains(&num(&r[10])));
            let hops = r[11].split(';').count();
            assert!(
                r[11] == "LOS"
                    || r[11].split(';').all(|h| h.starts_with("R:")) && hops <= 3
                    || r[11].starts_with("D:") && hops == 1,
                "{}",
                r[11]
            );
        }
        // The line-of-sight receivers' first path is the direct one, at |rx - tx| / c.
        if rx["line_of_sight"] == true {
            let p =
                rx["position"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect::<Vec<_>>();
            let d = (p[0].powi(2) + p[1].powi(2) + (p[2] - 10.0).powi(2)).sqrt();
            assert_eq!(mine[0][11], "LOS");
            assert!((num(&mine[0][3]) - d / 299_792_458.0).abs() < 1e-6 * num(&mine[0][3]));
        }
        let png = std::fs::read(out.join(format!("pdp_{name}.png"))).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        // cfr.csv: 64 points over 3.49-3.51 GHz, each the sum of the paths' amplitudes turned
        // by exp(-j 2 pi (f - f_c) tau).
        let cfr = std::fs::read_to_string(out.join("cfr.csv")).unwrap();
        assert!(cfr.starts_with("transmitter,receiver,freq_hz,re,im,gain_db\n"));
        let points: Vec<Vec<f64>> = cfr
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<_>>())
            .filter(|f| f[1] == name)
            .map(|f| f[2..5].iter().map(|v| num(v)).collect())
            .collect();
        assert_eq!(points.len(), 64);
        let mean_f = points.iter().map(|p| p[0]).sum::<f64>() / 64.0;
        assert!((mean_f - 3.5e9).abs() < 1.0 && (points[1][0] - points[0][0] - 20e6 / 64.0).abs() < 1e-3);
        for p in &points {
            let (mut re, mut im) = (0.0, 0.0);
            for r in &mine {
                let phase = -std::f64::consts::TAU * (p[0] - 3.5e9) * num(&r[3]);
                let (s, c) = phase.sin_cos();
                re += num(&r[4]) * c - num(&r[5]) * s;
                im += num(&r[4]) * s + num(&r[5]) * c;
            }
            let scale = (re * re + im * im).sqrt();
            assert!(
                (p[1] - re).abs() <= 1e-9 * scale && (p[2] - im).abs() <= 1e-9 * scale,
                "{name} {}",
                p[0]
            );
        }
    }
    // Without receivers there is nothing to write.
    let bare = dir.path().join("bare");
    let (ok, _, err) = propsim(&[
        "rf",
        CANYON,
        "--rays",
        "20000",
        "--cell-m",
        "4",
        "--no-receivers",
        "--out",
        bare.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(!bare.join("paths.csv").exists() && bare.join("coverage.csv").exists());
}

/// A scene that is free space for the coverage grid: one tiny concrete triangle 1 km up, and
/// two isotropic transmitters `TXA` and `TXB` at (-25, 0, 21.5) and (25, 0, 21.5), -20 dBm
/// each at 3.5 GHz, over a 120 x 60 m grid of 2 m cells at 1.5 m.
fn two_transmitters_in_free_space(dir: &std::path::Path) -> std::path::PathBuf {
    std::fs::write(
        dir.join("speck.obj"),
        "v 0 0 1000\nv 0.01 0 1000\nv 0 0.01 1000\nusemtl concrete\nf 1 2 3\n",
    )
    .unwrap();
    let scene = dir.join("two_tx.toml");
    std::fs::write(
        &scene,
        r#"obj = "speck.obj"

[rf]
freq_ghz = 3.5

[[rf.transmitters]]
name = "TXA"
position = [-25.0, 0.0, 21.5]
power_dbm = -20.0

[[rf.transmitters]]
name = "TXB"
position = [25.0, 0.0, 21.5]
power_dbm = -20.0

[rf.grid]
height_m = 1.5
cell_m = 2.0
min = [-60.0, -30.0]
max = [60.0, 30.0]
"#,
    )
    .unwrap();
    scene
}

/// Friis `(lambda / 4 pi r)^2` at 3.5 GHz averaged over the 2 m cell centred on (cx, cy) at
/// 1.5 m (8 x 8 samples), from a transmitter at (tx, 0, 21.5).
fn friis_cell_average(cx: f64, cy: f64, tx: f64) -> f64 {
    let lambda = 299_792_458.0 / 3.5e9;
    let mut sum = 0.0;
    for a in 0..8 {
        for b in 0..8 {
            let x = cx + 2.0 * ((f64::from(a) + 0.5) / 8.0 - 0.5);
            let y = cy + 2.0 * ((f64::from(b) + 0.5) / 8.0 - 0.5);
            let r2 = (x - tx).powi(2) + y * y + 20.0f64.powi(2);
            sum += (lambda / (4.0 * std::f64::consts::PI)).powi(2) / r2;
        }
    }
    sum / 64.0
}

#[test]
fn two_transmitters_get_best_server_sinr_and_their_own_maps() {
    // Free space, two isotropic transmitters of equal power 50 m apart: each cell's best server
    // is the nearer one, each transmitter's power is Friis, the SINR is the closed form
    // P_near / (P_far + k T0 B F) from the two Friis powers, and the combined columns are the
    // sum. Powers are low (-20 dBm) so that the noise (-101.0 dBm with F = 3 dB, B = 10 MHz)
    // is comparable with the far transmitter's power over much of the grid.
    let dir = tempfile::tempdir().unwrap();
    let scene = two_transmitters_in_free_space(dir.path());
    let out = dir.path().join("out");
    let (ok, stdout, err) = propsim(&[
        "rf",
        scene.to_str().unwrap(),
        "--rays",
        "8000000",
        "--max-depth",
        "0",
        "--noise-figure-db",
        "3",
        "--bandwidth-mhz",
        "10",
        "--vmin-db",
        "-100",
        "--vmax-db",
        "-50",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(stdout.contains("best_server.png"), "{stdout}");
    let noise_dbm = 10.0 * (1.380_649e-23 * 290.0 * 10e6 * 1e3f64).log10() + 3.0;
    assert!((noise_dbm + 100.975).abs() < 0.001, "{noise_dbm}");
    let text = std::fs::read_to_string(out.join("coverage.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "x_m,y_m,z_m,path_gain_db,rx_power_dbm,paths,best_server,best_rx_power_dbm,sinr_db,\
             rx_power_dbm_TXA,rx_power_dbm_TXB"
        )
    );
    let lin = |db: f64| 10f64.powf(db / 10.0);
    let (mut worst_friis, mut worst_sinr, mut worst_sum) = (0.0f64, 0.0f64, 0.0f64);
    let (mut checked, mut near_bisector) = (0, 0);
    for line in lines {
        let r: Vec<&str> = line.split(',').collect();
        assert_eq!(r.len(), 11, "{line}");
        let num = |i: usize| r[i].parse::<f64>().unwrap_or_else(|_| panic!("{line}: column {i}"));
        let (x, y) = (num(0), num(1));
        let (pa, pb) = (num(9), num(10));
        // Each transmitter's own power: -20 dBm + Friis.
        let (fa, fb) = (friis_cell_average(x, y, -25.0), friis_cell_average(x, y, 25.0));
        let (want_a, want_b) = (-20.0 + 10.0 * fa.log10(), -20.0 + 10.0 * fb.log10());
        worst_friis = worst_friis.max((pa - want_a).abs()).max((pb - want_b).abs());
        // The combined columns are the sum of the two maps (3-decimal rounding).
        let sum_dbm = 10.0 * (lin(pa) + lin(pb)).log10();
        worst_sum = worst_sum.max((num(4) - sum_dbm).abs()).max((num(3) - (sum_dbm + 20.0)).abs());
        // The best server is the stronger of the two columns, with its power; the SINR is
        // computed from them exactly.
        let (best, best_p, other_p) = if pa >= pb { ("TXA", pa, pb) } else { ("TXB", pb, pa) };
        assert_eq!(r[6], best, "{line}");
        assert!((num(7) - best_p).abs() < 0.0015, "{line}");
        let sinr_cols = best_p - 10.0 * (lin(other_p) + lin(noise_dbm)).log10();
        assert!((num(8) - sinr_cols).abs() < 0.003, "{line}: {sinr_cols}");
        // Against the closed form: the nearer transmitter, away from the bisector x = 0 (where
        // the two Friis powers are within 1 dB).
        if (want_a - want_b).abs() < 1.0 {
            near_bisector += 1;
            continue;
        }
        checked += 1;
        let (near, p_near, p_far) =
            if want_a > want_b { ("TXA", want_a, want_b) } else { ("TXB", want_b, want_a) };
        assert_eq!(r[6], near, "{line}: the nearer transmitter serves");
        assert_eq!(near == "TXA", x < 0.0);
        let sinr = p_near - 10.0 * (lin(p_far) + lin(noise_dbm)).log10();
        worst_sinr = worst_sinr.max((num(8) - sinr).abs());
    }
    eprintln!(
        "two transmitters: {checked} cells off the bisector ({near_bisector} near it); worst \
         error: Friis {worst_friis:.3} dB, SINR {worst_sinr:.3} dB, sum {worst_sum:.4} dB"
    );
    assert_eq!(checked + near_bisector, 60 * 30);
    assert!(near_bisector < 100 && checked > 1700, "{near_bisector} {checked}");
    assert!(worst_friis < 0.5, "per-transmitter power {worst_friis:.3} dB from Friis");
    assert!(worst_sinr < 0.5, "SINR {worst_sinr:.3} dB from the closed form");
    assert!(worst_sum < 0.003, "combined columns {worst_sum} dB from the sum");
    for png in ["coverage.png", "coverage_TXA.png", "coverage_TXB.png", "best_server.png"] {
        assert_eq!(&std::fs::read(out.join(png)).unwrap()[1..4], b"PNG", "{png}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("coverage.json")).unwrap()).unwrap();
    assert_eq!(json["colour_range_db"], serde_json::json!([-100.0, -50.0]));
    assert!((json["config"]["noise"]["noise_power_dbm"].as_f64().unwrap() - noise_dbm).abs() < 1e-9);
    assert!(json["servers"].as_str().unwrap().contains("k T0 B F"));
    // The speck's three rims diffract (on by default), 1 km up: far below these powers.
    assert_eq!(json["physics"]["diffraction"], "on (first order, UTD, 3 wedges)");
    assert_eq!(json["physics"]["transmission"], "on (0.1 m slabs, default)");
    assert_eq!(json["physics"]["extrapolate"], false);
    assert_eq!(json["physics"]["max_depth"], 0);
    assert_eq!(json["physics"]["rays_per_transmitter"], 8_000_000);
    let maps = json["transmitter_maps"].as_array().unwrap();
    assert_eq!(maps.len(), 2);
    for m in maps {
        assert_eq!(m["map"]["reached_cells"], 1800);
        assert_eq!(m["best_server_cells"], 900, "{m}");
    }
}

#[test]
fn a_grid_that_misses_the_model_gets_one_warning_line() {
    // The canyon's ground is at z = 0 and its roofs at most 40 m up: a plane at 80 m, or a
    // grid 1 km away, cannot show it (what a Y-up model or a wrong grid gives).
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    for (args, needle) in [
        (vec!["--grid-height", "80"], "plane z = 80 m misses the model"),
        (vec!["--grid-min", "1000,1000", "--grid-max", "1010,1010"], "lies beside the model"),
    ] {
        let mut all =
            vec!["rf", CANYON, "--rays", "2000", "--no-receivers", "--no-diffraction", "--out", out];
        all.extend(args);
        let (ok, _, err) = propsim(&all);
        assert!(ok, "{err}");
        let lines: Vec<&str> = err.lines().collect();
        assert_eq!(lines.len(), 1, "{err}");
        assert!(lines[0].starts_with("warning: ") && lines[0].contains(needle), "{err}");
    }
    // The scene's own grid shows the model: no warning.
    let (ok, _, err) =
        propsim(&["rf", CANYON, "--rays", "2000", "--no-receivers", "--no-diffraction", "--out", out]);
    assert!(ok && err.is_empty(), "{err}");
}
