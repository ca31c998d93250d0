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

#[test]
fn spatial_outputs_are_identical_for_one_and_two_threads_and_w_is_the_mono_response() {
    // A cardioid source facing +y, third-order Ambisonics and the binaural head: ambix (16
    // channels) and brir (2) beside the mono IR, bit for bit the same for 1 and 2 threads;
    // the W channel is the mono response to float rounding.
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("t1"), dir.path().join("t2"));
    for (threads, out) in [("1", &a), ("2", &b)] {
        let (ok, _, err) = propsim(&[
            "--threads",
            threads,
            "acoustic",
            "builtin:shoebox",
            "--rays",
            "20000",
            "--directivity",
            "cardioid",
            "--orientation",
            "0,1,0",
            "--ambisonic-order",
            "3",
            "--binaural",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(ok, "{err}");
    }
    for f in ["histogram.csv", "ir_S1_R1.wav", "ambix_S1_R1.wav", "brir_S1_R1.wav"] {
        assert_eq!(read(&a.join(f)), read(&b.join(f)), "{f} differs between 1 and 2 threads");
    }
    let channels = |f: &str| {
        let mut r = hound::WavReader::open(a.join(f)).unwrap();
        let n = usize::from(r.spec().channels);
        assert_eq!((r.spec().sample_rate, r.spec().sample_format), (48_000, hound::SampleFormat::Float));
        let s: Vec<f32> = r.samples::<f32>().map(Result::unwrap).collect();
        (0..n).map(|c| s.iter().skip(c).step_by(n).copied().collect::<Vec<f32>>()).collect::<Vec<_>>()
    };
    let (ir, ambix, brir) =
        (channels("ir_S1_R1.wav"), channels("ambix_S1_R1.wav"), channels("brir_S1_R1.wav"));
    assert_eq!((ambix.len(), brir.len()), (16, 2));
    let peak = ir[0].iter().fold(0.0f32, |m, v| m.max(v.abs()));
    for (w, m) in ambix[0].iter().zip(&ir[0]) {
        assert!((w - m).abs() <= 1e-5 * peak, "W {w} vs mono {m}");
    }
    let (ok, _, err) = propsim(&["acoustic", "builtin:shoebox", "--ambisonic-order", "4"]);
    assert!(!ok && err.contains("4"), "{err}");
    assert_clean_error(
        &[
            "acoustic",
            "builtin:shoebox",
            "--directivity",
            "shotgun",
            "--out",
            dir.path().join("x").to_str().unwrap(),
        ],
        &["shotgun", "cardioid", "figure-of-eight"],
    );
}

#[test]
fn auralize_convolves_any_response_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
    let (ok, stdout, err) = propsim(&["auralize", "--make-dry", &p("dry.wav"), "--seconds", "3"]);
    assert!(ok && stdout.contains("dry.wav"), "{err}");
    let (ok, _, err) = propsim(&[
        "acoustic",
        "builtin:shoebox",
        "--rays",
        "5000",
        "--max-time-s",
        "0.3",
        "--ambisonic-order",
        "1",
        "--out",
        &p("o"),
    ]);
    assert!(ok, "{err}");
    for (ir, n) in [("o/ir_S1_R1.wav", 1), ("o/ambix_S1_R1.wav", 4)] {
        let (ok, stdout, err) = propsim(&["auralize", &p(ir), &p("dry.wav"), "-o", &p("wet.wav")]);
        assert!(ok, "{err}");
        assert!(stdout.contains("normalised by"), "{stdout}");
        let r = hound::WavReader::open(p("wet.wav")).unwrap();
        assert_eq!(usize::from(r.spec().channels), n);
        // 3 s of dry signal plus 0.3 s of response, less one sample.
        assert_eq!(r.duration() as usize, 3 * 48_000 + (0.3 * 48_000.0) as usize - 1);
    }
    assert_clean_error(
        &["auralize", &p("none.wav"), &p("dry.wav"), "-o", &p("x.wav")],
        &["none.wav", "not found"],
    );
    std::fs::write(p("junk.wav"), b"not a wav").unwrap();
    assert_clean_error(&["auralize", &p("o/ir_S1_R1.wav"), &p("junk.wav"), "-o", &p("x.wav")], &["junk.wav"]);
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 44_100,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(p("cd.wav"), spec).unwrap();
    for i in 0..100 {
        w.write_sample((i * 100) as i16).unwrap();
    }
    w.finalize().unwrap();
    assert_clean_error(
        &["auralize", &p("o/ir_S1_R1.wav"), &p("cd.wav"), "-o", &p("x.wav")],
        &["cd.wav", "44100"],
    );
}

#[test]
fn a_bad_sofa_file_is_a_one_line_error_naming_it_before_any_ray() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("junk.sofa");
    std::fs::write(&junk, b"not an HDF5 file").unwrap();
    let out = dir.path().join("o");
    assert_clean_error(
        &["acoustic", "builtin:shoebox", "--hrtf", junk.to_str().unwrap(), "--out", out.to_str().unwrap()],
        &["junk.sofa", "SOFA"],
    );
    assert!(!out.exists(), "nothing is written");
    let missing = dir.path().join("missing.sofa");
    assert_clean_error(
        &["acoustic", "builtin:shoebox", "--hrtf", missing.to_str().unwrap(), "--out", out.to_str().unwrap()],
        &["missing.sofa", "not found"],
    );
}
