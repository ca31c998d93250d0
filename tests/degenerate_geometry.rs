//! Degenerate meshes load and get their tree in time linear in their size and in bounded
//! stack (issue 21): one polygon face of 10^5 vertices, 10^5 copies of one triangle, and a
//! fan of 10^5 vertices written as separate triangles. Before the PLOC guard and the
//! iterative collapse, 3 x 10^4 of any of these took seconds to minutes and overflowed the
//! stack; a quadratic step would make these tests hang rather than fail on a timer.

mod common;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use propsim::core::{BuildQuality, MeshBvh, Ray};
use propsim::scene::obj::load_obj;

const N: usize = 100_000;

/// Writes `text` as `name` in `dir`, with `usemtl metal` so the CLI knows the material.
fn write_obj(dir: &Path, name: &str, body: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, format!("usemtl metal\n{body}")).unwrap();
    path
}

/// `n` vertices on the unit circle in the z = 0 plane, starting at angle 0.
fn circle(out: &mut String, n: usize) {
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        writeln!(out, "v {:.9} {:.9} 0", a.cos(), a.sin()).unwrap();
    }
}

/// One convex polygon face of `n` vertices.
fn polygon(n: usize) -> String {
    let mut s = String::new();
    circle(&mut s, n);
    s.push('f');
    for i in 1..=n {
        write!(s, " {i}").unwrap();
    }
    s.push('\n');
    s
}

/// `n` copies of one triangle.
fn identical(n: usize) -> String {
    let mut s = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for _ in 0..n {
        s.push_str("f 1 2 3\n");
    }
    s
}

/// A centre and `n - 1` rim vertices, joined by `n - 2` triangles sharing the centre.
fn fan(n: usize) -> String {
    let mut s = String::from("v 0 0 0.5\n");
    circle(&mut s, n - 1);
    for i in 2..n {
        writeln!(s, "f 1 {i} {}", i + 1).unwrap();
    }
    s
}

/// Loads `path` (`expected_triangles` after triangulation), builds its tree at every quality, and checks a ray straight down through
/// the mesh hits it and one beside it misses.
fn load_and_build(path: &Path, expected_triangles: usize) {
    let scene = load_obj(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    // Slivers whose area rounds to zero in f32 are dropped (and counted), nothing else.
    let kept = scene.mesh.triangle_count();
    assert_eq!(kept + scene.degenerate_dropped, expected_triangles, "{}", path.display());
    assert!(kept > expected_triangles * 99 / 100, "{}: {kept} triangles kept", path.display());
    for quality in BuildQuality::ALL {
        let bvh = MeshBvh::build(&scene.mesh, quality);
        let down = glam::Vec3::new(0.0, 0.0, -1.0);
        let hit = bvh.closest_hit(&Ray::new(glam::Vec3::new(0.1, 0.1, 2.0), down));
        assert!(hit.is_some(), "{}: {quality:?}: the ray through the mesh hits", path.display());
        let miss = bvh.closest_hit(&Ray::new(glam::Vec3::new(5.0, 5.0, 2.0), down));
        assert!(miss.is_none(), "{}: {quality:?}: the ray beside the mesh misses", path.display());
    }
}

#[test]
fn polygon_face_of_100k_vertices_loads_and_builds() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_obj(dir.path(), "polygon.obj", &polygon(N));
    load_and_build(&path, N - 2);
}

#[test]
fn identical_triangles_100k_load_and_build() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_obj(dir.path(), "identical.obj", &identical(N));
    load_and_build(&path, N);
}

#[test]
fn fan_of_100k_vertices_loads_and_builds() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_obj(dir.path(), "fan.obj", &fan(N));
    load_and_build(&path, N - 2);
}

#[test]
fn info_reports_a_100k_vertex_polygon() {
    let dir = tempfile::tempdir().unwrap();
    write_obj(dir.path(), "polygon.obj", &polygon(N));
    let (ok, out, err) = common::propsim_in(Some(dir.path()), &["info", "polygon.obj"]);
    assert!(ok, "propsim info fails: {err}");
    assert!(out.contains("triangles, 100000 vertices)"), "the report counts the vertices:\n{out}");
    assert!(!err.contains("panicked") && !err.contains("overflow"), "{err}");
}
