//! `propsim acoustic` end to end: outputs, determinism across thread counts, bad input.

mod common;

use std::path::Path;

use common::{assert_clean_error, propsim};

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn outputs_are_complete_and_identical_for_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("t1"), dir.path().join("t2"));
    for (threads, out) in [("1", &a), ("2", &b)] {
        let (ok, stdout, err) = propsim(&[
            "--threads",
            threads,
            "acoustic",
            "builtin:shoebox",
            "--rays",
            "20000",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(ok, "{err}");
        assert!(stdout.contains("Eyring"), "{stdout}");
    }
    for f in ["metrics.csv", "histogram.csv", "ir_S1_R1.wav"] {
        assert_eq!(read(&a.join(f)), read(&b.join(f)), "{f} differs between 1 and 2 threads");
    }
    for f in ["acoustic.json", "ir_S1_R1.png", "decay_S1_R1.png"] {
        assert!(a.join(f).exists(), "{f} missing");
    }
    let metrics = String::from_utf8(read(&a.join("metrics.csv"))).unwrap();
    // The first ten columns keep their names and places; later ones are appended.
    assert_eq!(
        metrics.lines().next().unwrap(),
        "source,receiver,band_hz,edt_s,t20_s,t30_s,c50_db,c80_db,d50,ts_ms,g_db,dynamic_range_db,\
         truncation_s,t20_r,t30_r,t20_xi_permille,t30_xi_permille,curvature_percent"
    );
    assert_eq!(metrics.lines().count(), 1 + 8);
    let wav = hound::WavReader::open(a.join("ir_S1_R1.wav")).unwrap();
    assert_eq!((wav.spec().sample_rate, wav.spec().bits_per_sample), (48_000, 32));
    assert_eq!(wav.spec().sample_format, hound::SampleFormat::Float);
}

#[test]
fn a_bare_obj_gets_a_source_and_a_receiver_placed_inside() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("room.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 6 0 0\nv 6 5 0\nv 0 5 0\nv 0 0 3\nv 6 0 3\nv 6 5 3\nv 0 5 3\nusemtl concrete_smooth\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let (ok, stdout, err) =
        propsim(&["acoustic", obj.to_str().unwrap(), "--rays", "5000", "--out", out.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(err.contains("placed S1 at") && err.contains("placed R1 at"), "{err}");
    assert!(stdout.contains("T30"));
    assert!(out.join("ir_S1_R1.wav").exists());
}

#[test]
fn bad_input_gets_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = out.to_str().unwrap();
    assert_clean_error(
        &["acoustic", "builtin:shoebox", "--source", "20,20,20", "--receiver", "5,4,1.5", "--out", o],
        &["builtin:shoebox", "source \"S1\"", "outside the room"],
    );
    let canyon = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/street_canyon/scene.toml");
    assert_clean_error(&["acoustic", canyon, "--out", o], &["street_canyon", "encloses no air"]);
    assert_clean_error(&["acoustic", "builtin:shoebox", "--rays", "0", "--out", o], &["0 rays"]);
    assert_clean_error(&["acoustic", "builtin:shoebox", "--ism-order", "40", "--out", o], &["--ism-order"]);
    assert_clean_error(
        &["acoustic", "builtin:shoebox", "--temperature-c", "300", "--out", o],
        &["temperature"],
    );
    assert_clean_error(&["acoustic", "builtin:shoebox", "--receiver-radius-m=-1", "--out", o], &["radius"]);
    assert_clean_error(&["acoustic", "builtin:shoebox", "--source", "1,2", "--out", o], &["X,Y,Z"]);
    // Surfaces known only from the MTL have no acoustic data.
    let obj = dir.path().join("mtl_only.obj");
    std::fs::write(dir.path().join("m.mtl"), "newmtl paint\nKd 0.5 0.5 0.5\n").unwrap();
    std::fs::write(
        &obj,
        "mtllib m.mtl\nv 0 0 0\nv 6 0 0\nv 6 5 0\nv 0 5 0\nv 0 0 3\nv 6 0 3\nv 6 5 3\nv 0 5 3\nusemtl paint\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .unwrap();
    assert_clean_error(
        &["acoustic", obj.to_str().unwrap(), "--out", o],
        &["mtl_only.obj", "without acoustic data", "paint"],
    );
}
