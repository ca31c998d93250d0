//! `--up-axis` and `--scale` (and the scene keys `up_axis` and `scale`): a Y-up or centimetre
//! copy of a room loads as the Z-up metre original, and bad values fail with one line.

mod common;

use std::path::Path;

use common::{BOX_OBJ, assert_clean_error, propsim};

/// `BOX_OBJ` with every vertex mapped by `f` (as another tool would have written it).
fn convert(f: impl Fn([f64; 3]) -> [f64; 3]) -> String {
    BOX_OBJ
        .lines()
        .map(|l| match l.strip_prefix("v ") {
            Some(rest) => {
                let p: Vec<f64> = rest.split_whitespace().map(|t| t.parse().unwrap()).collect();
                let [x, y, z] = f([p[0], p[1], p[2]]);
                format!("v {x} {y} {z}")
            }
            None => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `propsim info --json` of `obj` with extra flags, parsed.
fn info(obj: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["info", obj.to_str().unwrap(), "--json"];
    args.extend(extra);
    let (ok, out, err) = propsim(&args);
    assert!(ok, "{args:?}: {err}");
    serde_json::from_str(&out).unwrap()
}

fn vec3(v: &serde_json::Value) -> [f64; 3] {
    let a = v.as_array().unwrap();
    [a[0].as_f64().unwrap(), a[1].as_f64().unwrap(), a[2].as_f64().unwrap()]
}

/// The radio coverage grid of `scene` (a fixed transmitter, few rays), as written.
fn coverage(scene: &Path, out: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "rf",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--tx",
        "1,1,2",
        "--rays",
        "20000",
        "--cell-m",
        "0.5",
        "--grid-height",
        "1.2",
        "--seed",
        "3",
    ];
    args.extend(extra);
    let (ok, _, err) = propsim(&args);
    assert!(ok, "{args:?}: {err}");
    std::fs::read_to_string(out.join("coverage.csv")).unwrap()
}

#[test]
fn a_y_up_copy_loads_as_the_z_up_original() {
    let dir = tempfile::tempdir().unwrap();
    let z = dir.path().join("z.obj");
    let y = dir.path().join("y.obj");
    std::fs::write(&z, BOX_OBJ).unwrap();
    // Blender's export: (x, y, z) -> (x, z, -y).
    std::fs::write(&y, convert(|[x, y, z]| [x, z, -y])).unwrap();
    let a = info(&z, &[]);
    let b = info(&y, &["--up-axis", "y"]);
    for key in ["bounds_min_m", "bounds_max_m", "air_volume_m3", "total_area_m2", "closed"] {
        assert_eq!(a[key], b[key], "{key}");
    }
    // Without the flag the model lies on its side.
    assert_ne!(a["bounds_max_m"], info(&y, &[])["bounds_max_m"]);
    // The same coverage, cell for cell, from the flag and from the scene key.
    let toml = dir.path().join("y.toml");
    std::fs::write(&toml, "obj = \"y.obj\"\nup_axis = \"y\"\n").unwrap();
    let reference = coverage(&z, &dir.path().join("cz"), &[]);
    assert_eq!(reference, coverage(&y, &dir.path().join("cy"), &["--up-axis", "y"]));
    assert_eq!(reference, coverage(&toml, &dir.path().join("ct"), &[]));
}

#[test]
fn a_centimetre_model_scaled_by_a_hundredth_is_the_metre_model() {
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("m.obj");
    let cm = dir.path().join("cm.obj");
    std::fs::write(&m, BOX_OBJ).unwrap();
    std::fs::write(&cm, convert(|p| p.map(|c| c * 100.0))).unwrap();
    let a = info(&m, &[]);
    let b = info(&cm, &["--scale", "0.01"]);
    for key in ["bounds_min_m", "bounds_max_m"] {
        let (pa, pb) = (vec3(&a[key]), vec3(&b[key]));
        assert!(pa.iter().zip(&pb).all(|(a, b)| (a - b).abs() < 1e-5), "{key}: {pa:?} vs {pb:?}");
    }
    let (va, vb) = (a["air_volume_m3"].as_f64().unwrap(), b["air_volume_m3"].as_f64().unwrap());
    assert!((va - vb).abs() < 1e-4 * va, "volume {va} vs {vb}");
    // The scene key does the same; the flag overrides it.
    let toml = dir.path().join("cm.toml");
    std::fs::write(&toml, "obj = \"cm.obj\"\nscale = 0.01\n").unwrap();
    assert_eq!(b["bounds_max_m"], info(&toml, &[])["bounds_max_m"]);
    let big = info(&toml, &["--scale", "1"]);
    assert!(vec3(&big["bounds_max_m"])[0] > 399.0);
}

#[test]
fn bad_up_axes_and_scales_fail_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("m.obj");
    std::fs::write(&obj, BOX_OBJ).unwrap();
    let o = obj.to_str().unwrap();
    for bad in ["0", "-1", "nan", "inf", "abc"] {
        assert_clean_error(&["info", o, &format!("--scale={bad}")], &["--scale"]);
    }
    assert_clean_error(&["render", o, "--up-axis", "x"], &["--up-axis", "expected y or z"]);
    assert_clean_error(&["rf", o, "--scale", "0"], &["--scale", "greater than 0"]);
    assert_clean_error(&["acoustic", o, "--scale", "-2"], &["--scale"]);
    assert_clean_error(&["run", o, "--scale", "0"], &["--scale"]);
    assert_clean_error(&["info", o, "--scale", "1e38"], &["m.obj", "too large"]);
    assert_clean_error(&["info", o, "--scale", "1e-45"], &["m.obj", "zero area"]);
    for (key, needle) in [("scale = 0.0", "scale"), ("scale = -1", "scale"), ("up_axis = \"x\"", "up_axis")] {
        let toml = dir.path().join("bad.toml");
        std::fs::write(&toml, format!("obj = \"m.obj\"\n{key}\n")).unwrap();
        assert_clean_error(&["info", toml.to_str().unwrap()], &["bad.toml", needle]);
    }
}
