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
    let (mut empty, mut reached) = (0, 0);
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
            assert!(r[5].parse::<u32>().unwrap() > 0);
            reached += 1;
        }
    }
    // Cells inside buildings are never reached; the streets are.
    assert!(empty > 1000 && reached > 1000, "{empty} {reached}");
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
    assert_clean_error(
        &["rf", "builtin:cornell_box", "--tx", "1,1,1"],
        &["cornell_white", "no radio properties"],
    );
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
    assert_eq!(json["surfaces"][0]["surfaces"][0]["thickness_m"], 0.1);
    assert_eq!(run("flag", &["--transmission"]).0, default);
    assert_eq!(run("thick", &["--wall-thickness-m", "0.1"]).0, default);
    assert_eq!(run("last", &["--no-transmission", "--transmission"]).0, default);
    let (opaque, json) = run("opaque", &["--no-transmission"]);
    assert_eq!(json["config"]["transmission"], false);
    let reached =
        |csv: &[u8]| String::from_utf8_lossy(csv).lines().skip(1).filter(|l| !l.contains(",,")).count();
    assert!(reached(&default) > reached(&opaque) + 100, "{} {}", reached(&default), reached(&opaque));
    let (thick, json) = run("thick2", &["--wall-thickness-m", "0.3"]);
    assert_ne!(thick, default);
    assert_eq!(json["surfaces"][0]["surfaces"][0]["thickness_m"], 0.3);
}

#[test]
fn street_canyon_map_agrees_with_the_exact_paths_at_the_receivers() {
    // The stochastic map's cell value against the exact image-method power sum at the two
    // line-of-sight receivers (direct, ground, facades; up to 3 reflections).
    use propsim::rf::{Overrides, RfConfig, simulate};
    use propsim::scene::{LoadOptions, World, load};
    let world = World::build(load(CANYON.as_ref(), &LoadOptions::default()).unwrap());
    // The image method finds the reflected paths only, so the map is made with opaque walls
    // (`--no-transmission`): under the defaults it would also hold the paths through the
    // buildings, which the exact sum leaves out.
    let o = Overrides { rays: Some(2_000_000), no_transmission: true, ..Overrides::default() };
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
        // (The receiver behind B01 has no specular path: its rows are none, its response 0.)
        assert_eq!(mine.is_empty(), name == "P_behind_B01", "{name}");
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
                r[11] == "LOS" || r[11].split(';').all(|h| h.starts_with("R:")) && hops <= 3,
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
