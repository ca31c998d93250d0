//! Scene loading and every bad-input case: a one-line error naming the file and the
//! problem, a non-zero exit, and no panic.

mod common;

use std::path::{Path, PathBuf};

use common::{BOX_OBJ, propsim};

use glam::Vec3;
use propsim::scene::{self, LoadOptions, World};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Asserts a clean failure: non-zero exit, one `error:` line naming `file` and containing
/// every one of `needles`, and no panic.
fn assert_clean_error(args: &[&str], file: &str, needles: &[&str]) {
    let line = common::assert_clean_error(args, needles);
    assert!(line.contains(file), "error should name {file}: {line}");
}

#[test]
fn loads_a_bare_obj_with_builtin_material_names_and_no_mtl() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "room.obj", BOX_OBJ);
    let s = scene::load(&obj, &LoadOptions::default()).unwrap();
    assert_eq!(s.mesh.triangle_count(), 12, "quads are triangulated");
    assert_eq!(s.mesh.surface_names, vec!["concrete", "plasterboard"]);
    assert!(s.surfaces.iter().all(|x| x.material.as_ref().is_some_and(|m| m.acoustic.is_some())));
    let world = World::build(s);
    assert!(world.report.is_closed());
    assert!((world.report.air_volume_m3.unwrap() - 30.0).abs() < 1e-9);
    assert!((world.report.area_by_surface_m2[0] - 24.0).abs() < 1e-9);
    assert_eq!(world.is_inside(Vec3::new(1.0, 1.0, 1.0)), Some(true));
    assert_eq!(world.is_inside(Vec3::new(5.0, 1.0, 1.0)), Some(false));
    assert_eq!(world.is_inside(Vec3::new(2.0, 1.5, 2.6)), Some(false));
}

#[test]
fn info_reports_volume_area_and_closedness() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "room.obj", BOX_OBJ);
    let (ok, out, err) = propsim(&["info", obj.to_str().unwrap(), "--point", "1,1,1", "--point", "9,9,9"]);
    assert!(ok, "{err}");
    assert!(out.contains("12 triangles"), "{out}");
    assert!(out.contains("30.000 m^3"), "{out}");
    assert!(out.contains("closed:     yes"), "{out}");
    assert!(out.contains("inside") && out.contains("OUTSIDE"), "{out}");
}

#[test]
fn missing_file() {
    assert_clean_error(&["info", "/nonexistent/room.obj"], "/nonexistent/room.obj", &["not found"]);
}

#[test]
fn malformed_obj_points_at_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "bad.obj", &BOX_OBJ.replace("v 4 3 0", "v 4 three 0"));
    assert_clean_error(&["info", obj.to_str().unwrap()], "bad.obj", &["line 4"]);
    let obj = write(dir.path(), "badface.obj", &BOX_OBJ.replace("f 5 6 7 8", "f 5 6 7 99"));
    assert_clean_error(&["info", obj.to_str().unwrap()], "badface.obj", &["line 12", "vertex"]);
}

#[test]
fn missing_mtl() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "room.obj", &format!("mtllib nowhere.mtl\n{BOX_OBJ}"));
    assert_clean_error(&["info", obj.to_str().unwrap()], "room.obj", &["nowhere.mtl", "cannot be opened"]);
}

#[test]
fn nan_and_infinite_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "nan.obj", &BOX_OBJ.replace("v 4 3 0", "v 4 NaN 0"));
    assert_clean_error(&["info", obj.to_str().unwrap()], "nan.obj", &["line 4", "non-finite"]);
    let obj = write(dir.path(), "inf.obj", &BOX_OBJ.replace("v 0 3 2.5", "v 0 inf 2.5"));
    assert_clean_error(&["info", obj.to_str().unwrap()], "inf.obj", &["line 9", "non-finite"]);
}

#[test]
fn degenerate_triangles_are_dropped_with_a_count() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "degen.obj", &format!("{BOX_OBJ}f 1 2 1\nf 1 2 2\nv 1 0 0\nf 1 2 9\n"));
    let (ok, out, err) = propsim(&["info", obj.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(err.contains("dropped 3 degenerate"), "{err}");
    assert!(out.contains("12 triangles"), "{out}");
}

#[test]
fn unknown_material_names_are_listed_with_nearest_known_names() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(
        dir.path(),
        "room.obj",
        &BOX_OBJ.replace("usemtl concrete", "usemtl concret").replace("usemtl plasterboard", "usemtl zzqx"),
    );
    assert_clean_error(
        &["info", obj.to_str().unwrap()],
        "room.obj",
        &["unknown material", "\"concret\"", "\"zzqx\"", "nearest known: concrete"],
    );
}

#[test]
fn scene_file_with_unknown_key_or_wrong_type_gives_the_line() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", BOX_OBJ);
    let scene = write(
        dir.path(),
        "typo.toml",
        "obj = \"room.obj\"\n\n[camera]\neye = [1, 1, 1]\ntarget = [2, 2, 1]\nfov = 40\n",
    );
    assert_clean_error(&["info", scene.to_str().unwrap()], "typo.toml", &["line 6", "unknown field `fov`"]);
    let scene = write(dir.path(), "type.toml", "obj = \"room.obj\"\n[acoustic]\nrays = \"many\"\n");
    assert_clean_error(&["info", scene.to_str().unwrap()], "type.toml", &["line 3", "invalid type"]);
    let scene = write(dir.path(), "noobj.toml", "[acoustic]\nrays = 10\n");
    assert_clean_error(&["info", scene.to_str().unwrap()], "noobj.toml", &["obj ="]);
}

#[test]
fn materials_file_with_unknown_key_or_bad_values() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "room.obj", BOX_OBJ);
    let mats = write(
        dir.path(),
        "mats.toml",
        "[materials.concrete]\nabsorption = [0.02, 0.03, 0.03, 0.03, 0.04, 0.07]\nscatter = 0.1\n",
    );
    assert_clean_error(
        &["info", obj.to_str().unwrap(), "--materials", mats.to_str().unwrap()],
        "mats.toml",
        &["line 3", "unknown field `scatter`"],
    );
    let mats = write(
        dir.path(),
        "range.toml",
        "[materials.concrete]\nabsorption = [0.02, 0.03, 0.03, 0.03, 0.04, 1.07]\n",
    );
    assert_clean_error(
        &["info", obj.to_str().unwrap(), "--materials", mats.to_str().unwrap()],
        "range.toml",
        &["concrete", "outside [0, 1]"],
    );
    let mats = write(dir.path(), "type.toml", "[materials.concrete]\nabsorption = \"high\"\n");
    assert_clean_error(
        &["info", obj.to_str().unwrap(), "--materials", mats.to_str().unwrap()],
        "type.toml",
        &["line 2"],
    );
}

#[test]
fn materials_file_given_on_its_own_overrides_the_library() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "room.obj", &BOX_OBJ.replace("usemtl plasterboard", "usemtl my_wall"));
    let mats = write(
        dir.path(),
        "mats.toml",
        "[materials.concrete]\nabsorption = [0.02, 0.03, 0.03, 0.03, 0.04, 0.07]\nscattering = [0.1, 0.1, 0.1, 0.1, 0.1, 0.1]\nitu = \"concrete\"\n\n[materials.my_wall]\nabsorption = 0.5\n",
    );
    let opts = LoadOptions { materials_files: vec![mats], ..Default::default() };
    let s = scene::load(&obj, &opts).unwrap();
    let a = s.surfaces[0].material.as_ref().unwrap().acoustic.as_ref().unwrap();
    assert_eq!(a.absorption[1], 0.02);
    assert_eq!(s.surfaces[1].material.as_ref().unwrap().acoustic.as_ref().unwrap().absorption, [0.5; 8]);
}

#[test]
fn empty_scene() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "empty.obj", "# nothing here\nv 0 0 0\n");
    assert_clean_error(&["info", obj.to_str().unwrap()], "empty.obj", &["empty"]);
}

#[test]
fn source_outside_the_room_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", BOX_OBJ);
    let toml = "obj = \"room.obj\"\n[acoustic]\n[[acoustic.sources]]\nname = \"S1\"\nposition = [1, 1, 1]\n[[acoustic.sources]]\nname = \"S2\"\nposition = [6, 1, 1]\n";
    let scene_path = write(dir.path(), "scene.toml", toml);
    let world = World::build(scene::load(&scene_path, &LoadOptions::default()).unwrap());
    let err = world.check_acoustic_points().unwrap_err().to_string();
    assert!(
        err.contains("scene.toml") && err.contains("\"S2\"") && err.contains("outside the room"),
        "{err}"
    );
    assert!(!err.contains('\n'));
    // `info` reports it too.
    let (ok, out, _) = propsim(&["info", scene_path.to_str().unwrap()]);
    assert!(ok);
    assert!(out.lines().any(|l| l.contains("S2") && l.contains("OUTSIDE")), "{out}");
    assert!(out.lines().any(|l| l.contains("S1") && l.contains("inside")), "{out}");
}

#[test]
fn non_finite_positions_in_the_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", BOX_OBJ);
    let scene_path = write(
        dir.path(),
        "scene.toml",
        "obj = \"room.obj\"\n[[lights]]\nposition = [1, nan, 1]\nintensity = [1, 1, 1]\n",
    );
    assert_clean_error(&["info", scene_path.to_str().unwrap()], "scene.toml", &["non-finite"]);
}

#[test]
fn absurd_parameters_are_refused() {
    assert_clean_error(&["bench", "trace", "--triangles", "0"], "--triangles", &["between"]);
    assert_clean_error(&["--threads", "0", "bench", "trace"], "--threads", &["between"]);
    let dir = tempfile::tempdir().unwrap();
    let rays = write(dir.path(), "rays.bin", "12345");
    let obj = write(dir.path(), "room.obj", BOX_OBJ);
    assert_clean_error(
        &["bench", "trace", obj.to_str().unwrap(), "--rays", rays.to_str().unwrap()],
        "rays.bin",
        &["24 bytes per ray"],
    );
}
