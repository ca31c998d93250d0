//! `propsim run`: the three views of the showcase scene side by side (small settings).

mod common;

use common::{assert_clean_error, propsim};

#[test]
fn run_writes_all_three_views_a_summary_sheet_and_a_manifest() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let (ok, stdout, err) = propsim(&["run", "--quick", "--out", out.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(stdout.contains("summary sheet"), "{stdout}");
    for f in [
        "render.png",
        "ir_S1_R1.wav",
        "ir_S1_R2.wav",
        "metrics.csv",
        "histogram.csv",
        "acoustic.json",
        "coverage.csv",
        "coverage.png",
        "coverage.json",
        "summary.png",
        "manifest.json",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["seed"], 1);
    assert_eq!(manifest["propsim_version"], env!("CARGO_PKG_VERSION"));
    assert!(manifest["timings_s"]["total"].as_f64().unwrap() > 0.0);
    assert_eq!(manifest["parameters"]["rf"]["transmitters"][0]["name"], "AP");
    let sheet = image::open(out.join("summary.png")).unwrap();
    assert_eq!((sheet.width(), sheet.height()), (1800, 1120));
}

#[test]
fn run_refuses_a_bad_scene_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    assert_clean_error(&["run", "/nonexistent/scene.toml", "--out", out.to_str().unwrap()], &["not found"]);
    assert!(!out.exists(), "nothing is written for a bad scene");
}
