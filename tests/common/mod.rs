//! Helpers shared by the end-to-end tests: run the binary, check for a clean one-line error.
#![allow(dead_code)]

pub mod render;

use std::path::Path;
use std::process::Command;

/// Runs `propsim ARGS` in `dir` (or the current directory): (success, stdout, stderr).
pub fn propsim_in(dir: Option<&Path>, args: &[&str]) -> (bool, String, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_propsim"));
    if let Some(d) = dir {
        cmd.current_dir(d);
    }
    let out = cmd.args(args).output().expect("the binary runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// Runs `propsim ARGS`: (success, stdout, stderr).
pub fn propsim(args: &[&str]) -> (bool, String, String) {
    propsim_in(None, args)
}

/// Whether `line` is part of clap's usage help after its `error:` line (a tip, the usage,
/// the pointer to --help), which command-line mistakes keep in full.
fn clap_help_line(line: &str) -> bool {
    let t = line.trim_start();
    t.starts_with("tip:") || t.starts_with("Usage:") || t.starts_with("For more information, try")
}

/// Asserts a clean failure of a finished run: non-zero exit, no panic, and exactly one
/// non-warning line on stderr, an `error:` line containing every needle (a command-line
/// mistake may add clap's tip and usage lines). Returns that line.
pub fn check_one_line_error(args: &[&str], ok: bool, err: &str, needles: &[&str]) -> String {
    assert!(!ok, "{args:?} should fail");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with("warning:") && !clap_help_line(l))
        .collect();
    assert_eq!(lines.len(), 1, "{args:?}: one error line expected, got: {err}");
    assert!(lines[0].starts_with("error:"), "{err}");
    for n in needles {
        assert!(lines[0].contains(n), "{args:?}: error should mention \"{n}\": {}", lines[0]);
    }
    lines[0].to_string()
}

/// Runs `propsim ARGS` and asserts a clean one-line error mentioning every needle.
pub fn assert_clean_error(args: &[&str], needles: &[&str]) -> String {
    let (ok, _, err) = propsim(args);
    check_one_line_error(args, ok, &err, needles)
}

/// A closed 4 x 3 x 2.5 m room of built-in materials (concrete floor and ceiling,
/// plasterboard walls), normals out of the room.
pub const BOX_OBJ: &str = "\
o room
v 0 0 0
v 4 0 0
v 4 3 0
v 0 3 0
v 0 0 2.5
v 4 0 2.5
v 4 3 2.5
v 0 3 2.5
usemtl concrete
f 1 4 3 2
f 5 6 7 8
usemtl plasterboard
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
";

/// A `.npy` file read without the writer's crate (numpy's format 1.0-3.0): the dtype string
/// (`<f8`, `<c16`), the shape, and the raw little-endian data in C order.
pub fn read_npy(path: &Path) -> (String, Vec<usize>, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&bytes[..6], b"\x93NUMPY", "{}: not a .npy file", path.display());
    let (len, start) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        _ => (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12),
    };
    let header = std::str::from_utf8(&bytes[start..start + len]).unwrap();
    assert!(header.contains("'fortran_order': False"), "{header}");
    let field = |key: &str| {
        let at = header.find(key).unwrap_or_else(|| panic!("no {key} in {header}")) + key.len();
        header[at..].trim_start_matches([':', ' ']).to_string()
    };
    let descr = field("'descr'");
    let descr = descr.trim_start_matches('\'').split('\'').next().unwrap().to_string();
    let shape = field("'shape'");
    let shape: Vec<usize> = shape[1..shape.find(')').unwrap()]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    (descr, shape, bytes[start + len..].to_vec())
}

/// The float64 data of a `.npy` file of dtype `<f8`, with its shape.
pub fn read_npy_f64(path: &Path) -> (Vec<usize>, Vec<f64>) {
    let (descr, shape, data) = read_npy(path);
    assert_eq!(descr, "<f8", "{}", path.display());
    let values: Vec<f64> = data.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
    assert_eq!(values.len(), shape.iter().product::<usize>(), "{}", path.display());
    (shape, values)
}

/// The OBJ text of a closed box [0,x]x[0,y]x[0,z] whose every face is material "test_wall".
pub fn box_obj([x, y, z]: [f32; 3]) -> String {
    format!(
        "v 0 0 0\nv {x} 0 0\nv {x} {y} 0\nv 0 {y} 0\nv 0 0 {z}\nv {x} 0 {z}\nv {x} {y} {z}\nv 0 {y} {z}\n\
         usemtl test_wall\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
    )
}

/// A closed box room [0,x]x[0,y]x[0,z] whose every face is material "test_wall".
pub fn box_room(dir: &Path, size: [f32; 3], absorption: f32, scattering: f32) -> propsim::scene::World {
    let obj = box_obj(size);
    let obj_path = dir.join("room.obj");
    std::fs::write(&obj_path, obj).unwrap();
    let mats = dir.join("mats.toml");
    std::fs::write(
        &mats,
        format!("[materials.test_wall]\nabsorption = {absorption}\nscattering = {scattering}\n"),
    )
    .unwrap();
    let s = propsim::scene::load(
        &obj_path,
        &propsim::scene::LoadOptions { materials_files: vec![mats.clone()], ..Default::default() },
    )
    .unwrap();
    propsim::scene::World::build(s)
}
