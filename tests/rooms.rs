//! The example scenes in rooms/: they load, and the measured rooms match their published
//! geometry (BRAS: CR2 146.09 m^3 of air and 202.53 m^2; CR4 has 6 over-shared edges).

use std::path::Path;

use glam::Vec3;
use propsim::scene::{self, LoadOptions, World};

fn world(path: &str) -> World {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    World::build(scene::load(&p, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}")))
}

#[test]
fn bras_cr2_volume_area_and_positions() {
    let w = world("rooms/bras_cr2/scene.toml");
    let r = &w.report;
    assert!(r.is_closed() && r.is_consistently_oriented());
    // BRAS CR2: air volume 146.09 m^3 (shell minus 3 obstacles), surface 202.53 m^2.
    assert!((r.air_volume_m3.unwrap() - 146.094).abs() < 0.01, "{:?}", r.air_volume_m3);
    assert!((r.total_area_m2 - 202.527).abs() < 0.01);
    assert!(w.check_acoustic_points().is_ok());
    let a = w.scene.desc.acoustic.as_ref().unwrap();
    assert_eq!((a.sources.len(), a.receivers.len()), (2, 5));
    // The air measured in the room (BRAS documentation): 19.5 C, 41.7 % relative humidity.
    let (t, h) = (a.temperature_c.unwrap(), a.relative_humidity_percent.unwrap());
    assert!((t - 19.5).abs() < 1e-4 && (h - 41.7).abs() < 1e-4, "{t} C, {h} %");
    assert!(w.scene.surfaces.iter().all(|s| s.material.as_ref().is_some_and(|m| m.acoustic.is_some())));
}

/// Every object of the shipped CR2, its three radiator boxes included, is wound like the room
/// shell: just off each triangle, on the side its normal points to, lies the outside of the air
/// (BRAS's convention, `normals_point_out_of_air`), and just behind it the air. The built-in
/// scene embeds the same files.
#[test]
fn bras_cr2_is_wound_like_its_walls_everywhere() {
    for w in [
        world("rooms/bras_cr2/scene.toml"),
        World::build(scene::load(Path::new("builtin:bras_cr2"), &LoadOptions::default()).unwrap()),
    ] {
        let r = &w.report;
        assert_eq!(r.normals_point_out_of_air, Some(true), "the shell's normals");
        let mesh = &w.scene.mesh;
        let offset_m = 2e-3;
        let wrong: Vec<usize> = (0..mesh.triangle_count())
            .filter(|&t| {
                let [a, b, c] = mesh.corners(t);
                let n = (b - a).cross(c - a).normalize();
                let centre = (a + b + c) / 3.0;
                w.is_inside(centre + offset_m * n) != Some(false)
                    || w.is_inside(centre - offset_m * n) != Some(true)
            })
            .collect();
        assert!(
            wrong.is_empty(),
            "{} of {} triangles face into the air: {wrong:?}",
            wrong.len(),
            mesh.triangle_count()
        );
        // Wound alike, the plain divergence sum over all triangles is the air volume.
        let air = r.air_volume_m3.unwrap();
        assert!((r.divergence_volume_m3 - air).abs() < 1e-3, "{} vs {air} m^3", r.divergence_volume_m3);
    }
}

#[test]
fn bras_cr4_flags_its_internal_sheet() {
    let w = world("rooms/bras_cr4/scene.toml");
    let r = &w.report;
    assert_eq!(r.over_shared_edges, 6);
    assert_eq!(r.open_edges, 0);
    assert!(!r.is_closed());
    // BRAS CR4: 8656.63 m^3 of air (shell 8695.68 minus 41 obstacles).
    assert!((r.air_volume_m3.unwrap() - 8656.63).abs() < 0.1, "{:?}", r.air_volume_m3);
    assert!(w.check_acoustic_points().is_ok());
}

#[test]
fn authored_rooms_are_closed_with_their_points_inside() {
    for (path, volume) in [
        ("rooms/shoebox/scene.toml", 240.0),
        ("rooms/l_room/scene.toml", 144.0),
        ("rooms/cornell_box/scene.toml", 0.1563),
    ] {
        let w = world(path);
        let v = w.report.air_volume_m3.unwrap_or_else(|| panic!("{path} encloses no air"));
        assert!((v - volume).abs() < 1e-3 * volume, "{path}: {v} m^3");
        assert!(w.report.is_consistently_oriented(), "{path}");
        w.check_acoustic_points().unwrap_or_else(|e| panic!("{e}"));
    }
}

#[test]
fn inside_test_excludes_obstacles_and_the_outside() {
    let w = world("rooms/shoebox/scene.toml");
    assert_eq!(w.is_inside(Vec3::new(5.0, 4.0, 1.5)), Some(true));
    assert_eq!(w.is_inside(Vec3::new(11.0, 4.0, 1.5)), Some(false));
    assert_eq!(w.is_inside(Vec3::new(5.0, 4.0, -0.5)), Some(false));
    // CR2's obstacles (closed boxes inside the room) are not air.
    let cr2 = world("rooms/bras_cr2/scene.toml");
    let obstacle = cr2.report.components.iter().find(|c| c.closed && c.triangles < 100).expect("an obstacle");
    let centre = 0.5 * (obstacle.bounds.0 + obstacle.bounds.1);
    assert_eq!(cr2.is_inside(centre), Some(false));
}

#[test]
fn the_street_canyon_is_an_open_scene() {
    let w = world("rooms/street_canyon/scene.toml");
    assert_eq!(w.report.air_volume_m3, None);
    assert_eq!(w.is_inside(Vec3::new(0.0, 0.0, 10.0)), None);
    let (lo, hi) = w.scene.mesh.bounds().unwrap();
    assert!((hi.x - lo.x - 180.0).abs() < 1.0 && (hi.y - lo.y - 120.0).abs() < 1.0);
}
