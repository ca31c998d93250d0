//! `propsim run --quick` on every shipped scene (every `rooms/*/scene.toml` and every
//! built-in): it succeeds, skips exactly the parts that cannot run with one `note:` line each
//! saying why, and writes the summary and a manifest that lists every file it wrote.

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use common::{assert_clean_error, propsim};

const MANIFEST_DIR: &str = env!("CARGO_MANIFEST_DIR");

/// The parts a shipped scene cannot run, with a piece of the reason each note must give.
fn expected_skips(name: &str) -> Vec<(&'static str, &'static str)> {
    let no_tx = ("rf", "give one with --tx X,Y,Z");
    let no_air = ("acoustic", "encloses no air");
    match name {
        "bras_cr2" | "bras_cr4" | "auditorium" => vec![no_tx],
        // The prism scene (rooms/prism): a prism and a slit light in the open.
        "cornell_box_classic" | "prism" => vec![no_air, no_tx],
        "street_canyon" | "city_block" => vec![no_air],
        // A render test scene: 1.2 m across, too small for a source 0.5 m from every wall.
        "caustics" => vec![("acoustic", "found no place for a source"), no_tx],
        // Its floorboard has ITU-R P.2040 data for 50-100 GHz only.
        "l_room" => vec![("rf", "--extrapolate")],
        _ => Vec::new(),
    }
}

/// Runs `propsim run SCENE --quick --out DIR EXTRA...`, returning (success, stdout, stderr).
fn run(scene: &str, out: &Path, extra: &[&str]) -> (bool, String, String) {
    let mut args = vec!["run", scene, "--quick", "--out", out.to_str().expect("UTF-8 path")];
    args.extend_from_slice(extra);
    propsim(&args)
}

fn manifest(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("manifest.json")).expect("manifest.json written");
    serde_json::from_str(&text).expect("manifest.json is JSON")
}

/// The summary and manifest exist, every file of the manifest exists with its size, and
/// every file in `out` (but the manifest) is listed.
fn check_outputs(label: &str, out: &Path) -> serde_json::Value {
    assert!(out.join("summary.png").is_file(), "{label}: summary.png missing");
    assert!(out.join("summary.txt").is_file(), "{label}: summary.txt missing");
    let m = manifest(out);
    let mut listed = BTreeSet::new();
    for o in m["outputs"].as_array().expect("outputs") {
        let rel = o["path"].as_str().expect("path");
        let meta = std::fs::metadata(out.join(rel)).unwrap_or_else(|e| panic!("{label}: {rel}: {e}"));
        assert_eq!(Some(meta.len()), o["bytes"].as_u64(), "{label}: size of {rel}");
        listed.insert(rel.to_string());
    }
    for entry in std::fs::read_dir(out).expect("out dir") {
        let name = entry.expect("entry").file_name().to_string_lossy().to_string();
        assert!(name == "manifest.json" || listed.contains(&name), "{label}: {name} written but not listed");
    }
    m
}

/// Runs one shipped scene and checks its notes, summary and manifest.
fn check_scene(scene: &str, name: &str, dir: &Path) -> f64 {
    let out = dir.join(name.replace(':', "_"));
    let t = std::time::Instant::now();
    let (ok, stdout, err) = run(scene, &out, &[]);
    let secs = t.elapsed().as_secs_f64();
    assert!(ok, "{scene}: {err}");
    assert!(!err.contains("error"), "{scene}: {err}");
    assert!(stdout.contains("summary sheet"), "{scene}: {stdout}");
    let m = check_outputs(scene, &out);
    let summary = std::fs::read_to_string(out.join("summary.txt")).expect("summary.txt");
    let skips = expected_skips(name);
    for part in ["render", "acoustic", "rf"] {
        let prefix = format!("note: {part} part skipped: ");
        let notes: Vec<&str> = err.lines().filter(|l| l.starts_with(&prefix)).collect();
        match skips.iter().find(|(p, _)| *p == part) {
            Some((_, why)) => {
                assert_eq!(notes.len(), 1, "{scene}: one note for the {part} part: {err}");
                assert!(notes[0].contains(why), "{scene}: {part} note should say \"{why}\": {}", notes[0]);
                assert_eq!(m["parts"][part]["status"], "skipped", "{scene}: {part}");
                assert!(summary.contains(&format!("{part}: skipped: ")), "{scene}: {summary}");
            }
            None => {
                assert!(notes.is_empty(), "{scene}: the {part} part should run: {err}");
                assert_eq!(m["parts"][part]["status"], "ran", "{scene}: {part}: {err}");
                assert!(summary.contains(&format!("{part}: ran")), "{scene}: {summary}");
                assert!(m["timings_s"][part].as_f64().is_some(), "{scene}: {part} timing");
            }
        }
    }
    assert!(!err.contains("part failed"), "{scene}: {err}");
    // What each part that ran wrote is in the manifest.
    let listed: Vec<&str> =
        m["outputs"].as_array().expect("outputs").iter().filter_map(|o| o["path"].as_str()).collect();
    let has = |f: &str| listed.contains(&f);
    assert!(has("render.png") && has("summary.png") && has("summary.txt"), "{scene}: {listed:?}");
    if m["parts"]["acoustic"]["status"] == "ran" {
        assert!(has("metrics.csv") && has("acoustic.json"), "{scene}: {listed:?}");
        assert!(listed.iter().any(|f| f.starts_with("ir_") && f.ends_with(".wav")), "{scene}: {listed:?}");
        assert!(listed.iter().any(|f| f.starts_with("decay_") && f.ends_with(".png")), "{scene}: {listed:?}");
    }
    if m["parts"]["rf"]["status"] == "ran" {
        assert!(has("coverage.csv") && has("coverage.png") && has("coverage.json"), "{scene}: {listed:?}");
    }
    secs
}

#[test]
fn run_works_on_every_shipped_scene() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut scenes: Vec<(String, String)> = std::fs::read_dir(Path::new(MANIFEST_DIR).join("rooms"))
        .expect("rooms/")
        .filter_map(|e| {
            let p = e.ok()?.path().join("scene.toml");
            let name = p.parent()?.file_name()?.to_string_lossy().to_string();
            p.is_file().then(|| (p.display().to_string(), name))
        })
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 8, "{scenes:?}");
    for s in propsim::scene::builtin::BUILTIN_SCENES {
        scenes.push((format!("builtin:{}", s.name), s.name.to_string()));
    }
    let mut times = Vec::new();
    for (scene, name) in &scenes {
        let out_name = if scene.starts_with("builtin:") { format!("builtin_{name}") } else { name.clone() };
        let secs = check_scene(scene, name, &dir.path().join(&out_name));
        times.push(format!("{scene} {secs:.1} s"));
    }
    eprintln!("propsim run --quick: {}", times.join(", "));
}

#[test]
fn the_flags_the_notes_suggest_make_the_parts_run() {
    let dir = tempfile::tempdir().expect("temp dir");
    // l_room's radio part needs --extrapolate; BRAS CR2 has no transmitter.
    let l_room = format!("{MANIFEST_DIR}/rooms/l_room/scene.toml");
    let out = dir.path().join("l_room");
    let (ok, _, err) = run(&l_room, &out, &["--extrapolate", "--only", "rf"]);
    assert!(ok, "{err}");
    assert!(!err.contains("note: rf part"), "{err}");
    let m = check_outputs("l_room", &out);
    assert_eq!(m["parts"]["rf"]["status"], "ran");
    assert_eq!(m["parts"]["render"]["status"], "not selected");
    assert_eq!(m["parts"]["acoustic"]["status"], "not selected");
    assert!(!out.join("render.png").exists(), "--only rf renders nothing");

    let out = dir.path().join("cr2");
    let (ok, _, err) = run("builtin:bras_cr2", &out, &["--only=rf,render", "--tx=0,0,1.5", "--extrapolate"]);
    assert!(ok, "{err}");
    let m = check_outputs("cr2", &out);
    assert_eq!(m["parts"]["rf"]["status"], "ran", "{err}");
    assert_eq!(m["parts"]["render"]["status"], "ran", "{err}");
    assert_eq!(m["parameters"]["tx"], serde_json::json!([0.0, 0.0, 1.5]));
    let coverage = std::fs::read_to_string(out.join("coverage.json")).expect("coverage.json");
    assert!(coverage.contains("\"tx\""), "the transmitter of --tx is named tx");
}

#[test]
fn run_with_nothing_that_can_run_fails_but_still_writes_its_summary() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("out");
    let (ok, _, err) = run("builtin:cornell_box_classic", &out, &["--only", "acoustic"]);
    assert!(!ok, "nothing ran: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 2, "{err}");
    assert!(
        lines[0].starts_with("note: acoustic part skipped: ") && lines[0].contains("encloses no air"),
        "{err}"
    );
    assert!(lines[1].starts_with("error: ") && lines[1].contains("no part could run"), "{err}");
    let m = check_outputs("cornell_box_classic", &out);
    assert_eq!(m["parts"]["acoustic"]["status"], "skipped");
}

#[test]
fn run_rejects_unknown_parts_and_bad_flags_on_one_line() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("out");
    let o = out.to_str().expect("UTF-8 path");
    assert_clean_error(
        &["run", "builtin:shoebox", "--only", "render,sound", "--out", o],
        &["sound", "render, acoustic or rf"],
    );
    assert_clean_error(&["run", "builtin:shoebox", "--tx", "1,2", "--out", o], &["--tx", "X,Y,Z"]);
    assert_clean_error(&["run", "builtin:shoebox", "--rays", "0", "--out", o], &["--rays"]);
    assert_clean_error(&["run", "builtin:shoebox", "--width", "0", "--out", o], &["width 0"]);
    assert!(!out.exists(), "nothing is written for bad flags");
}
