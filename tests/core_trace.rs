//! The tracing core against brute force and closed-form answers.

use glam::{Vec2, Vec3};
use propsim::core::launcher::LAUNCH_BLOCK;
use propsim::core::rng::{stream, uniform};
use propsim::core::sampling::uniform_sphere;
use propsim::core::{Accel, BuildQuality, Hit, PrimitiveKind, Ray, Sphere, TriangleMesh};
use rayon::prelude::*;

fn random_soup(n: usize, seed: u64) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    let s = m.surface_id("a");
    let s2 = m.surface_id("b");
    let mut r = stream(seed, 0, 0);
    for i in 0..n {
        let c = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 20.0 - 10.0;
        let mut corner = || c + Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 2.0 - 1.0;
        let tri = [corner(), corner(), corner()];
        m.push_triangle(tri, if i % 2 == 0 { s } else { s2 });
    }
    m
}

fn random_rays(n: usize, seed: u64) -> Vec<Ray> {
    (0..n)
        .map(|k| {
            let mut r = stream(seed, 1, k as u64);
            let o = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 30.0 - 15.0;
            Ray::new(o, uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r))))
        })
        .collect()
}

/// Closest hits as the launcher asks for them: [`Accel::closest_hits_into`] on blocks of
/// [`LAUNCH_BLOCK`] rays, blocks in parallel.
fn launcher_hits(accel: &Accel, rays: &[Ray]) -> Vec<Option<Hit>> {
    let mut out = vec![None; rays.len()];
    out.par_chunks_mut(LAUNCH_BLOCK)
        .zip(rays.par_chunks(LAUNCH_BLOCK))
        .for_each(|(o, r)| accel.closest_hits_into(r, o));
    out
}

fn brute_force(mesh: &TriangleMesh, ray: &Ray) -> Option<(u32, f32)> {
    let mut best: Option<(u32, f32)> = None;
    for i in 0..mesh.triangle_count() {
        if let Some((t, _)) = mesh.triangle_rt(i).intersect(ray)
            && best.is_none_or(|(_, bt)| t < bt)
        {
            best = Some((i as u32, t));
        }
    }
    best
}

#[test]
fn bvh_matches_brute_force_on_1e5_random_rays_for_every_quality() {
    let mesh = random_soup(2000, 11);
    let rays = random_rays(100_000, 12);
    let expected: Vec<Option<(u32, f32)>> = rays.iter().map(|r| brute_force(&mesh, r)).collect();
    assert!(expected.iter().filter(|h| h.is_some()).count() > 10_000, "test rays should hit often");
    for quality in BuildQuality::ALL {
        let accel = Accel::build(&mesh, Vec::new(), quality);
        let got = launcher_hits(&accel, &rays);
        for (k, (e, g)) in expected.iter().zip(&got).enumerate() {
            match (e, g) {
                (None, None) => {}
                (Some((ti, tt)), Some(h)) => {
                    assert_eq!(h.kind, PrimitiveKind::Triangle);
                    // Identical hits: same triangle at the same distance (a tie between two
                    // triangles at the very same t may resolve either way).
                    assert!(
                        h.primitive == *ti || (h.t - tt).abs() <= 1e-6 * tt.max(1.0),
                        "ray {k} ({quality:?}): brute force {ti} at {tt}, BVH {} at {}",
                        h.primitive,
                        h.t
                    );
                    assert!((h.t - tt).abs() <= 1e-5 * tt.max(1.0));
                    assert_eq!(h.surface, mesh.surface_of_triangle[h.primitive as usize]);
                    let [a, b, c] = mesh.corners(h.primitive as usize);
                    let p = a * (1.0 - h.barycentric.x - h.barycentric.y)
                        + b * h.barycentric.x
                        + c * h.barycentric.y;
                    assert!((p - h.point).length() < 1e-3, "barycentrics reproduce the hit point");
                }
                _ => panic!(
                    "ray {k} ({quality:?}): brute force {e:?}, BVH {:?}",
                    g.map(|h| (h.primitive, h.t))
                ),
            }
            assert_eq!(accel.occluded(&rays[k]), e.is_some(), "occlusion of ray {k}");
        }
    }
}

#[test]
fn one_million_rays_from_inside_a_closed_subdivided_box_all_hit() {
    // 6 * 60 * 60 * 2 = 43,200 triangles with many shared edges and vertices, in a tree; then
    // 6 * 3 * 3 * 2 = 108 in a tree and 6 * 2 * 2 * 2 = 48 tested without one.
    for (cells, n) in [(60usize, 1_000_000u64), (3, 200_000), (2, 200_000)] {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(Vec3::new(-1.3, -0.7, -2.1), Vec3::new(2.9, 1.7, 0.9), cells, s);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let grid = cells as f32;
        let rays: Vec<Ray> = (0..n)
            .map(|k| {
                let mut r = stream(99, 2, k);
                let o = Vec3::new(-1.2, -0.6, -2.0)
                    + Vec3::new(uniform(&mut r) * 4.0, uniform(&mut r) * 2.2, uniform(&mut r) * 2.8);
                // Half the rays aim exactly at vertices and edges of the subdivision grid.
                let d = if k % 2 == 0 {
                    uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)))
                } else {
                    let i = (uniform(&mut r) * (grid + 1.0)).floor() / grid;
                    let j = (uniform(&mut r) * (grid + 1.0)).floor() / grid;
                    (Vec3::new(-1.3 + 4.2 * i, -0.7 + 2.4 * j, 0.9) - o).normalize()
                };
                Ray::new(o, d)
            })
            .collect();
        let hits = launcher_hits(&accel, &rays);
        let misses = hits.iter().filter(|h| h.is_none()).count();
        assert_eq!(misses, 0, "{misses} of {n} rays escaped the closed box of {cells}x{cells} cells a face");
    }
}

#[test]
fn secondary_rays_never_rehit_their_own_surface() {
    // A large room far from the origin, where float spacing is coarse: 768 triangles in a
    // tree, and 48 tested without one.
    for cells in [8, 2] {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(Vec3::new(1000.0, 2000.0, 0.0), Vec3::new(1050.0, 2040.0, 12.0), cells, s);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let centre = Vec3::new(1025.0, 2020.0, 6.0);
        let mut rehits = 0;
        for k in 0..100_000u64 {
            let mut r = stream(5, 3, k);
            let first = Ray::new(centre, uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r))));
            let hit = accel.closest_hit(&first).expect("inside a closed room");
            // Leave the surface into the room in a random direction of the inner hemisphere.
            let n_in = hit.facing_normal();
            let mut d = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            if d.dot(n_in) < 0.0 {
                d = -d;
            }
            let second = Ray::spawn(hit.point, hit.normal, d);
            let next = accel.closest_hit(&second).expect("still inside");
            // Re-hitting the same plane (the walls are planar) is a self-intersection.
            let same_plane =
                (next.point - hit.point).dot(hit.normal).abs() < 1e-3 && next.normal.dot(hit.normal) > 0.999;
            if next.primitive == hit.primitive || same_plane {
                eprintln!("ray {k}: left {:?} at {}, came back at t = {}", hit.primitive, hit.point, next.t);
                rehits += 1;
            }
            // A grazing shadow ray back to the room centre is never blocked by its own surface.
            assert!(!accel.occluded(&Ray::spawn_to(hit.point, hit.normal, centre)));
        }
        assert_eq!(rehits, 0, "{cells}x{cells} cells a face");
    }
}

#[test]
fn spheres_and_triangles_share_one_closest_hit_query() {
    let mut mesh = TriangleMesh::default();
    let s = mesh.surface_id("floor");
    mesh.push_quad(
        Vec3::new(-5.0, -5.0, 0.0),
        Vec3::new(5.0, -5.0, 0.0),
        Vec3::new(5.0, 5.0, 0.0),
        Vec3::new(-5.0, 5.0, 0.0),
        s,
    );
    let spheres: Vec<Sphere> =
        (0..40).map(|i| Sphere::new(Vec3::new(i as f32 * 0.2 - 4.0, 0.0, 1.0), 0.05, 1)).collect();
    let accel = Accel::build(&mesh, spheres, BuildQuality::default());
    let down = Ray::new(Vec3::new(-4.0, 0.0, 5.0), -Vec3::Z);
    let h = accel.closest_hit(&down).unwrap();
    assert_eq!(h.kind, PrimitiveKind::Sphere);
    assert!((h.t - 3.95).abs() < 1e-4);
    let beside = Ray::new(Vec3::new(-4.1, 0.0, 5.0), -Vec3::Z);
    let h = accel.closest_hit(&beside).unwrap();
    assert_eq!(h.kind, PrimitiveKind::Triangle);
    assert!((h.t - 5.0).abs() < 1e-5 && h.front_face);
    assert!(accel.occluded(&Ray::segment(Vec3::new(-4.0, 0.0, 5.0), -Vec3::Z, 4.0)));
    assert!(!accel.occluded(&Ray::segment(Vec3::new(-4.0, 0.0, 5.0), -Vec3::Z, 3.9)));
    // The sphere set's BVH path (more than 16 spheres) finds every crossing.
    let along = Ray::new(Vec3::new(-5.0, 0.0, 1.0), Vec3::X);
    let mut count = 0;
    accel.spheres.for_each_crossing(&along, |_, chord| {
        assert!((chord - 0.1).abs() < 1e-4);
        count += 1;
    });
    assert_eq!(count, 40);
}
