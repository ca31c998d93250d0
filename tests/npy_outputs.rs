//! Every CSV result has a `.npy` twin of the documented shape that holds the same numbers:
//! read here by an independent reader of numpy's format (and by numpy itself when there).

mod common;

use common::{propsim, read_npy, read_npy_f64};
use std::path::Path;

const CANYON: &str = "rooms/street_canyon/scene.toml";

/// The rows of a CSV file as maps from column name to text.
fn csv_rows(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let names: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    r.records()
        .map(|rec| names.iter().cloned().zip(rec.unwrap().iter().map(String::from)).collect())
        .collect()
}

/// `text` as a number, NaN when empty.
fn number(text: &str) -> f64 {
    if text.is_empty() { f64::NAN } else { text.parse().unwrap() }
}

/// Equal within the CSV's rounding, or both missing.
fn same(csv: f64, npy: f64, tolerance: f64) -> bool {
    (csv.is_nan() && npy.is_nan()) || (csv - npy).abs() <= tolerance
}

/// numpy's own shape for each file, when python3 with numpy is installed (else `None`).
fn numpy_shapes(files: &[&Path]) -> Option<Vec<String>> {
    let script = "import sys, numpy\nfor f in sys.argv[1:]: print(numpy.load(f).shape)";
    let out = std::process::Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(files)
        .output()
        .ok()
        .filter(|o| o.status.success())?;
    Some(String::from_utf8_lossy(&out.stdout).lines().map(|l| l.replace(' ', "")).collect())
}

#[test]
fn street_canyon_npy_twins_hold_the_csv_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let (ok, _, err) = propsim(&[
        "rf",
        CANYON,
        "--rays",
        "20000",
        "--cell-m",
        "4",
        "--cfr-bandwidth-mhz",
        "20",
        "--cfr-points",
        "16",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");

    // coverage.npy: (transmitters, ny, nx) linear path gain; the CSV is x fastest, in dB.
    let (shape, gain) = read_npy_f64(&out.join("coverage.npy"));
    let rows = csv_rows(&out.join("coverage.csv"));
    assert_eq!(shape[0], 1);
    assert_eq!(shape[1] * shape[2], rows.len());
    let first_y = number(&rows[0]["y_m"]);
    let nx = rows.iter().take_while(|r| number(&r["y_m"]) == first_y).count();
    assert_eq!(shape[2], nx, "x is the last axis");
    let mut reached = 0;
    for (row, &g) in rows.iter().zip(&gain) {
        let db = if g > 0.0 { 10.0 * g.log10() } else { f64::NAN };
        assert!(same(number(&row["path_gain_db"]), db, 0.0006), "{row:?} vs {db}");
        reached += usize::from(g > 0.0);
    }
    assert!(reached > rows.len() / 2, "{reached} of {} cells reached", rows.len());

    // paths.npy: one row per paths.csv row, its numeric columns, tx and rx by index.
    let (shape, v) = read_npy_f64(&out.join("paths.npy"));
    let rows = csv_rows(&out.join("paths.csv"));
    assert_eq!(shape, vec![rows.len(), 11]);
    assert!(rows.len() >= 3);
    let receivers: Vec<String> = rows.iter().map(|r| r["receiver"].clone()).collect();
    for (i, row) in rows.iter().enumerate() {
        let n = &v[11 * i..11 * i + 11];
        assert_eq!(n[0], 0.0);
        let rx_index = {
            let mut names = receivers.clone();
            names.dedup();
            names.iter().position(|r| *r == row["receiver"]).unwrap() as f64
        };
        assert_eq!(n[1], rx_index);
        assert_eq!(n[2], number(&row["path"]));
        // Delays and amplitudes are written exactly in the CSV.
        for (k, col) in [(3, "delay_s"), (4, "amplitude_re"), (5, "amplitude_im")] {
            assert_eq!(n[k], number(&row[col]), "{col} of row {i}");
        }
        for (k, col) in [
            (6, "gain_db"),
            (7, "aod_azimuth_deg"),
            (8, "aod_zenith_deg"),
            (9, "aoa_azimuth_deg"),
            (10, "aoa_zenith_deg"),
        ] {
            assert!(same(number(&row[col]), n[k], 1.0e-6), "{col} of row {i}: {} vs {}", row[col], n[k]);
        }
    }

    // cfr.npy: complex128 (transmitters, receivers, points), the CSV's re and im exactly.
    let (descr, shape, data) = read_npy(&out.join("cfr.npy"));
    assert_eq!(descr, "<c16");
    let receivers = receivers.iter().collect::<std::collections::BTreeSet<_>>().len();
    assert_eq!(shape, vec![1, receivers, 16]);
    let rows = csv_rows(&out.join("cfr.csv"));
    assert_eq!(rows.len(), receivers * 16);
    for (i, row) in rows.iter().enumerate() {
        let at = |k: usize| f64::from_le_bytes(data[16 * i + 8 * k..16 * i + 8 * k + 8].try_into().unwrap());
        assert_eq!((at(0), at(1)), (number(&row["re"]), number(&row["im"])), "row {i}");
    }

    if let Some(shapes) =
        numpy_shapes(&[&out.join("coverage.npy"), &out.join("paths.npy"), &out.join("cfr.npy")])
    {
        let want = [
            format!("({},{},{})", 1, gain.len() / nx, nx),
            format!("({},11)", v.len() / 11),
            format!("(1,{receivers},16)"),
        ];
        assert_eq!(shapes, want);
    }
}

/// Free space with two transmitters (a tiny triangle 1 km up), -20 dBm each at 3.5 GHz.
fn two_transmitters(dir: &Path) -> std::path::PathBuf {
    std::fs::write(
        dir.join("speck.obj"),
        "v 0 0 1000\nv 0.01 0 1000\nv 0 0.01 1000\nusemtl concrete\nf 1 2 3\n",
    )
    .unwrap();
    let scene = dir.join("two_tx.toml");
    let text = "obj = \"speck.obj\"\n\n[rf]\nfreq_ghz = 3.5\n\n\
        [[rf.transmitters]]\nname = \"TXA\"\nposition = [-25.0, 0.0, 21.5]\npower_dbm = -20.0\n\n\
        [[rf.transmitters]]\nname = \"TXB\"\nposition = [25.0, 0.0, 21.5]\npower_dbm = -20.0\n\n\
        [rf.grid]\nheight_m = 1.5\ncell_m = 2.0\nmin = [-60.0, -30.0]\nmax = [60.0, 30.0]\n";
    std::fs::write(&scene, text).unwrap();
    scene
}

#[test]
fn each_transmitter_has_its_own_map_in_coverage_npy() {
    let dir = tempfile::tempdir().unwrap();
    let scene = two_transmitters(dir.path());
    let out = dir.path().join("o");
    let (ok, _, err) =
        propsim(&["rf", scene.to_str().unwrap(), "--rays", "200000", "--out", out.to_str().unwrap()]);
    assert!(ok, "{err}");
    let (shape, gain) = read_npy_f64(&out.join("coverage.npy"));
    assert_eq!(shape, vec![2, 30, 60]);
    let rows = csv_rows(&out.join("coverage.csv"));
    let cells = 30 * 60;
    for (c, row) in rows.iter().enumerate() {
        let mut sum_mw = 0.0;
        for (t, name) in ["TXA", "TXB"].iter().enumerate() {
            let g = gain[t * cells + c];
            // -20 dBm times the path gain, in dBm.
            let dbm = if g > 0.0 { -20.0 + 10.0 * g.log10() } else { f64::NAN };
            assert!(same(number(&row[&format!("rx_power_dbm_{name}")]), dbm, 0.0006), "cell {c} {name}");
            sum_mw += 0.01 * g;
        }
        let total = if sum_mw > 0.0 { 10.0 * sum_mw.log10() } else { f64::NAN };
        assert!(same(number(&row["rx_power_dbm"]), total, 0.0006), "cell {c}");
    }
    // The nearer transmitter is the stronger on each side.
    let at = |t: usize, x: usize| gain[t * cells + 15 * 60 + x];
    assert!(at(0, 5) > at(1, 5) && at(1, 55) > at(0, 55));
}

#[test]
fn a_render_to_npy_holds_the_exr_values_as_height_width_channel() {
    let dir = tempfile::tempdir().unwrap();
    let (exr_path, npy_path) = (dir.path().join("a.exr"), dir.path().join("a.npy"));
    for path in [&exr_path, &npy_path] {
        let args = ["render", "builtin:cornell_box", "-o", path.to_str().unwrap()];
        let (ok, _, err) =
            propsim(&[&args[..], &["--width", "16", "--height", "12", "--spp", "4", "--seed", "3"]].concat());
        assert!(ok, "{err}");
    }
    let (descr, shape, data) = read_npy(&npy_path);
    assert_eq!((descr.as_str(), shape), ("<f4", vec![12, 16, 3]));
    let npy: Vec<f32> = data.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    let img = exr::prelude::read_first_rgba_layer_from_file(
        &exr_path,
        |r, _| vec![0.0f32; 3 * r.width() * r.height()],
        |v: &mut Vec<f32>, p, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = 3 * (p.y() * 16 + p.x());
            v[i..i + 3].copy_from_slice(&[r, g, b]);
        },
    )
    .unwrap();
    assert_eq!(npy, img.layer_data.channel_data.pixels);
    assert!(npy.iter().any(|&v| v > 0.0));
}

#[test]
fn acoustic_npy_twins_hold_the_histogram_and_the_metrics() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let (ok, _, err) =
        propsim(&["acoustic", "builtin:shoebox", "--rays", "5000", "--out", out.to_str().unwrap()]);
    assert!(ok, "{err}");
    // histogram.npy: (pairs, bands, bins) J/m^2; the CSV has a row per pair and bin.
    let (shape, h) = read_npy_f64(&out.join("histogram.npy"));
    let rows = csv_rows(&out.join("histogram.csv"));
    assert_eq!(shape[..2], [1, 8]);
    assert_eq!(shape[2], rows.len(), "one pair: as many bins as rows");
    let bands = ["63", "125", "250", "500", "1000", "2000", "4000", "8000"];
    let mut energy = 0.0;
    for (k, row) in rows.iter().enumerate() {
        for (b, f) in bands.iter().enumerate() {
            let (csv, npy) = (number(&row[&format!("energy_{f}hz_j_per_m2")]), h[b * shape[2] + k]);
            assert!((csv - npy).abs() <= 1e-6 * npy.abs() + 1e-300, "bin {k} band {f}: {csv} vs {npy}");
            energy += npy;
        }
    }
    assert!(energy > 0.0);
    // metrics.npy: (pairs, bands, 15), the CSV's columns after source, receiver and band_hz.
    let (shape, m) = read_npy_f64(&out.join("metrics.npy"));
    assert_eq!(shape, vec![1, 8, 15]);
    let rows = csv_rows(&out.join("metrics.csv"));
    let columns: [(&str, i32); 15] = [
        ("edt_s", 4),
        ("t20_s", 4),
        ("t30_s", 4),
        ("c50_db", 3),
        ("c80_db", 3),
        ("d50", 4),
        ("ts_ms", 2),
        ("g_db", 2),
        ("dynamic_range_db", 1),
        ("truncation_s", 3),
        ("t20_r", 5),
        ("t30_r", 5),
        ("t20_xi_permille", 2),
        ("t30_xi_permille", 2),
        ("curvature_percent", 1),
    ];
    assert_eq!(rows.len(), 8);
    let mut measured = 0;
    for (b, row) in rows.iter().enumerate() {
        for (c, (name, digits)) in columns.iter().enumerate() {
            let npy = m[b * 15 + c];
            let tolerance = 0.5 * 10f64.powi(-digits) + 1e-12 * npy.abs();
            assert!(same(number(&row[*name]), npy, tolerance), "band {b} {name}: {} vs {npy}", row[*name]);
            measured += usize::from(npy.is_finite());
        }
    }
    assert!(measured > 60, "{measured} of 120 metrics measured");
}
